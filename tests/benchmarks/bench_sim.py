"""The simulator: CPU spent simulating servos during a batch, sim-serve's promptness, calibration.

References measured in the same run:

- servo CPU: the stepping integrator the simulator used before (0.25 ms Euler steps, lazily
  when a servo is looked at), kept here as `SteppedServo`; same control table, same batch;
- sim-serve lateness: a minimal pseudo-terminal server that answers every request with one
  prebuilt packet at the same due time (no parsing, no servos);
- motion: the STS3215 datasheet (0.222 s per 60 degrees at 7.4 V).
"""

from __future__ import annotations

import math
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import serial

from pinarray.clock import VirtualClock
from pinarray.hardware.feetech.models import STS3215_C001
from pinarray.hardware.feetech.registers import (
    BROADCAST_ID,
    Instruction,
    Register,
    checksum,
    to_bytes,
)
from pinarray.hardware.feetech.sim_motion import MotionState
from pinarray.hardware.feetech.sim_servo import SimServo
from pinarray.hardware.feetech.transport import open_bus
from pinarray.plan import make_plan
from pinarray.player.families import bus_setup
from pinarray.player.playback import play_trial
from pinarray.protocol.load import load_protocol
from pinarray.schedule import compile_trial

LOCALISATION = Path(__file__).resolve().parents[2] / "protocols" / "localisation.yaml"
REPEATS = 5
TRIALS = 6


class SteppedMotion:
    """The old motion model: integrate 0.25 ms Euler steps up to whenever someone looks."""

    STEP_NS = 250_000
    MAX_SPEED = 3400.0  # the old top speed (about 10 % above the datasheet's)
    MAX_ACCEL = 254 * 100.0

    def __init__(self, start_ns: int, position: float):
        self.time_ns = start_ns
        self.position = position
        self.speed = 0.0
        self.goal = position
        self.top = self.MAX_SPEED
        self.accel = self.MAX_ACCEL
        self.active = False

    start_ns = property(lambda self: 0)

    @property
    def end_ns(self) -> int:
        moving = self.active and (self.speed != 0.0 or self.position != self.goal)
        return self.time_ns + 1 if moving else 0

    def state_at(self, now_ns: int) -> MotionState:
        self.advance_to(now_ns)
        return MotionState(self.position, self.speed, self.position)

    def horn_speed_at(self, now_ns: int) -> float:
        self.advance_to(now_ns)
        return self.speed

    def advance_to(self, now_ns: int) -> None:
        if now_ns <= self.time_ns:
            return
        if not self.active or (self.speed == 0.0 and self.position == self.goal):
            self.time_ns = now_ns
            return
        while self.time_ns < now_ns:
            dt_ns = min(self.STEP_NS, now_ns - self.time_ns)
            self._step(dt_ns / 1e9)
            self.time_ns += dt_ns
            if self.speed == 0.0 and self.position == self.goal:
                self.time_ns = now_ns
                break

    def _step(self, dt_s: float) -> None:
        distance = self.goal - self.position
        if abs(distance) < 0.5 and abs(self.speed) <= self.accel * dt_s:
            self.position, self.speed = self.goal, 0.0
            return
        braking = math.sqrt(2.0 * self.accel * abs(distance))
        wanted = math.copysign(min(self.top, braking), distance)
        change = max(-self.accel * dt_s, min(self.accel * dt_s, wanted - self.speed))
        self.speed += change
        moved = self.speed * dt_s
        if abs(moved) >= abs(distance) and math.copysign(1.0, moved) == math.copysign(
            1.0, distance
        ):
            self.position, self.speed = self.goal, 0.0
        else:
            self.position += moved


class SteppedServo(SimServo):
    """Today's control table driven by the old stepping integrator (the reference)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._move = SteppedMotion(self._last_ns, self._move.state_at(self._last_ns).horn_steps)

    def _replan(self, now_ns: int) -> None:
        motion = self._move
        motion.advance_to(now_ns)  # up to now under the old settings
        motion.goal = float(self.target_steps)
        speed = self.get(Register.GOAL_SPEED) or SteppedMotion.MAX_SPEED
        motion.top = min(speed, SteppedMotion.MAX_SPEED)
        motion.accel = self.get(Register.ACCELERATION) * 100.0 or SteppedMotion.MAX_ACCEL
        motion.active = self.torque_enabled
        if not motion.active:
            motion.speed = 0.0


def _timed(method, spent: list[int]):
    def wrapper(*args):
        started = time.perf_counter_ns()
        try:
            return method(*args)
        finally:
            spent[0] += time.perf_counter_ns() - started
    return wrapper


def _batch(servo_class, trials) -> tuple[float, float]:
    """Play ``trials`` as `pinarray batch` does; returns (servo CPU s, whole batch s)."""
    protocol = load_protocol(LOCALISATION)
    setup = bus_setup(protocol.device)
    clock = VirtualClock()
    ids = ",".join(map(str, setup.servo_ids))
    bus = open_bus(f"sim://?ids={ids}", None, clock)
    spent = [0]
    sim = bus.sim
    for servo_id in list(sim.servos):
        servo = servo_class(servo_id, clock.now_ns())
        for name in ("read", "write"):
            setattr(servo, name, _timed(getattr(servo, name), spent))
        sim.servos[servo_id] = servo
    started = time.perf_counter()
    bus.connect(setup)
    bus.move_to_rest()
    for schedule in trials:
        play_trial(bus, schedule.targets, clock, release_at_end=False)
        clock.sleep_until_ns(clock.now_ns() + 3_000_000_000)  # inter-trial interval
    bus.rest_and_release()
    return spent[0] / 1e9, time.perf_counter() - started


def _spread(values: list[float], scale: float = 1.0) -> str:
    low, mid, high = min(values), statistics.median(values), max(values)
    return f"{low * scale:>8.1f} {mid * scale:>8.1f} {high * scale:>8.1f}"


def servo_cpu_during_a_batch() -> None:
    protocol = load_protocol(LOCALISATION)
    plan = make_plan(protocol, seed=1)
    trials = [compile_trial(protocol, t) for t in plan.trials[:TRIALS]]
    print(f"CPU simulating servos while playing {TRIALS} localisation trials (10 s each, "
          f"virtual time), {REPEATS} runs each; ms per batch, min / median / max")
    results: dict[str, tuple[list[float], list[float]]] = {"closed form": ([], []),
                                                          "stepping (old)": ([], [])}
    for _ in range(REPEATS):
        for label, servo_class in (("closed form", SimServo), ("stepping (old)", SteppedServo)):
            servo_s, batch_s = _batch(servo_class, trials)
            results[label][0].append(servo_s)
            results[label][1].append(batch_s)
    print(f"{'servo model':<16} {'servo CPU ms (min med max)':>27} {'batch ms (min med max)':>27}")
    for label, (servo, batch) in results.items():
        print(f"{label:<16} {_spread(servo, 1e3):>27} {_spread(batch, 1e3):>27}")
    new_servo, old_servo = (statistics.median(results[k][0]) for k in results)
    new_batch, old_batch = (statistics.median(results[k][1]) for k in results)
    print(f"servo CPU: old / new = {old_servo / new_servo:.1f}x (target >= 5x); "
          f"whole batch: {old_batch / new_batch:.2f}x")


REFERENCE_SERVER = r"""
import os, select, sys, time, tty
controller, device = os.openpty()
tty.setraw(controller); tty.setraw(device)
print(os.ttyname(device), flush=True)
answer, after_ns = bytes.fromhex(sys.argv[1]), int(sys.argv[2])
while True:
    data = os.read(controller, 4096)
    due_ns = time.monotonic_ns() + after_ns
    while (left := due_ns - time.monotonic_ns()) > 0:
        select.select([], [], [], left / 1e9)
    os.write(controller, answer)
"""


def _sync_read_request(ids) -> bytes:
    body = bytes([BROADCAST_ID, len(ids) + 4, Instruction.SYNC_READ, 56, 2, *ids])
    return b"\xff\xff" + body + bytes([checksum(body)])


def _lateness_ms(path: str, request: bytes, answer_bytes: int, expected_ns: int,
                 exchanges: int, before=None) -> np.ndarray:
    late = []
    with serial.Serial(path, 1_000_000, timeout=1) as port:
        if before is not None:
            before(port)
        for _ in range(exchanges):
            sent_ns = time.monotonic_ns()
            port.write(request)
            got = port.read(answer_bytes)
            late.append((time.monotonic_ns() - sent_ns - expected_ns) / 1e6)
            assert len(got) == answer_bytes, "an answer went missing"
            time.sleep(0.002)
    return np.array(late)


def _start(command: list[str]) -> tuple[subprocess.Popen, str]:
    process = subprocess.Popen(command, stdout=subprocess.PIPE, text=True,
                               env={**os.environ, "PYTHONUNBUFFERED": "1"})
    line = process.stdout.readline()
    return process, (line.split(" on ")[1].split()[0] if " on " in line else line.strip())


def sim_serve_promptness(exchanges: int = 400) -> None:
    ids = list(range(1, 17))
    request = _sync_read_request(ids)
    delay_ns = 500_000  # factory return delay
    answer_bytes = 16 * 8
    expected_ns = (len(request) + answer_bytes) * 10_000 + 16 * delay_ns

    def all_move(port):
        goals = b"".join(bytes([i]) + to_bytes(1024 if i % 2 else 3072, 2) for i in ids)
        body = bytes([BROADCAST_ID, len(goals) + 4, Instruction.SYNC_WRITE, 42, 2]) + goals
        port.write(b"\xff\xff" + body + bytes([checksum(body)]))

    print(f"\nsim-serve answering a 16-servo sync read (own process, 1 Mbit/s, 500 us return "
          f"delays): lateness after the {expected_ns / 1e6:.2f} ms the wire and delays need, "
          f"{exchanges} exchanges each")
    measured = {}
    for label, before in (("sim-serve, 16 servos idle", None),
                          ("sim-serve, 16 servos moving", all_move)):
        server, path = _start([sys.executable, "-m", "pinarray", "sim-serve", "--ids", "1-16"])
        try:
            measured[label] = _lateness_ms(path, request, answer_bytes, expected_ns, exchanges,
                                           before)
        finally:
            server.terminate()
            server.wait(timeout=10)
    answer = bytes(answer_bytes).hex()
    reference, path = _start([sys.executable, "-c", REFERENCE_SERVER, answer, str(expected_ns)])
    try:
        ref = _lateness_ms(path, request, answer_bytes, expected_ns, exchanges)
    finally:
        reference.terminate()
        reference.wait(timeout=10)
    measured["minimal reply loop (reference)"] = ref
    print(f"{'server':<32} {'p50 ms':>8} {'p99 ms':>8} {'max ms':>8} {'p99 / ref':>10}")
    ref_p99 = max(float(np.percentile(ref, 99)), 1e-3)
    for label, late in measured.items():
        p50, p99, worst = np.percentile(late, [50, 99, 100])
        print(f"{label:<32} {p50:>8.3f} {p99:>8.3f} {worst:>8.3f} {p99 / ref_p99:>10.2f}")
    print("(target: within 1 ms of the wire and return delays; the machine's own wake-up "
          "latency is in every row)")


def motion_against_the_datasheet() -> None:
    print("\nfull-speed turns from rest (goal speed 0, acceleration 0, no backlash) against "
          "the STS3215 datasheet, 0.222 s per 60 deg at 7.4 V")
    print(f"{'turn':>6} {'datasheet s':>12} {'simulated s':>12} {'ratio':>6}")
    for degrees in (30, 60, 90, 180):
        servo = SimServo(1, 0, position_steps=0, backlash_steps=0)
        goal = round(degrees * 4096 / 360)
        servo.write(Register.GOAL_POSITION.address, to_bytes(goal, 2), 0)
        end_ns = next(t for t in range(0, 2_000_000_000, 100_000)
                      if servo.position_at_ns(t) == goal)
        datasheet = degrees / 60 * 0.222
        print(f"{degrees:>5}° {datasheet:>12.3f} {end_ns / 1e9:>12.3f} "
              f"{end_ns / 1e9 / datasheet:>6.3f}")
    print(f"(simulated = datasheet + the motor's spin-up, {STS3215_C001.spin_up_s * 1e3:.0f} ms "
          "estimated)")


def run() -> None:
    servo_cpu_during_a_batch()
    sim_serve_promptness()
    motion_against_the_datasheet()
