"""The seed's trains on a PCA9685 board: I2C bytes and bus time per frame beside the bus's
minimum, and when each frame's write reaches the board beside a bare write loop.

Both are measured where the board receives them: every message the simulated board hears is
stamped with the clock time of its STOP (`pinarray.hardware.pca9685.sim`), on this machine's
monotonic clock, while the player plays the trial in real time (`play_prepared`).

- **Bytes per frame**: what each frame's write carried (address byte included), its time on
  the bus at 100 and 400 kHz, and the read-backs that verify it in the slack. The minimum the
  bus allows for a new pulse width is one message of 4 bytes per changed channel (address,
  register pointer, OFF_L, OFF_H).
- **Write lateness at the board**: STOP of each frame's write minus (its scheduled write time
  plus its own bus time), in the player with its verifier, beside a minimal loop that sleeps
  until the same times and writes the same bytes to a fresh simulated board and does nothing
  else. Min/median/max over rounds of each run's median and worst frame; a write must end
  before its pulse's period begins (the slack column: the smallest margin left).
"""

from __future__ import annotations

import statistics
from pathlib import Path

from pinarray.clock import MonotonicClock
from pinarray.hardware.pca9685.i2c import I2cMessage
from pinarray.hardware.pca9685.sim import SimI2cLink
from pinarray.hardware.pca9685.timing import PwmTrial
from pinarray.plan import make_plan
from pinarray.player.families import open_array
from pinarray.player.playback import OnsetAfter, play_prepared, prepare_trial
from pinarray.protocol.load import parse_protocol
from pinarray.schedule import compile_trial
from tests.benchmarks._timing import SPREAD_HEADER

PROTOCOL = Path(__file__).parents[2] / "protocols" / "localisation_pwm.yaml"
URL = "sim://pca9685?osc_hz=25300000"
RUNS = 5
SECONDS = 2  # each train cut from the protocol's 10 s (20 frames a second at 10 Hz still)
MINIMUM_BYTES = 4  # address, pointer, OFF_L, OFF_H: one changed channel
LEAD_NS = 20_000_000


class _Heard:
    """Every message the link carries, beside the driver's own listener."""

    def __init__(self, link):
        self.messages: list[I2cMessage] = []
        self._driver = link.listener
        link.listener = self

    def __call__(self, message: I2cMessage) -> None:
        self.messages.append(message)
        if self._driver is not None:
            self._driver(message)


def _trials(protocol):
    plan = make_plan(protocol, 0)
    chosen = {}
    for planned in plan.trials:
        chosen.setdefault(planned.condition.frequency_hz, planned)
    return [chosen[f] for f in sorted(chosen)]


def _play(protocol, schedule):
    """Our player on a fresh simulated board; (trial, onset, frame writes, read bytes)."""
    clock = MonotonicClock()
    bus = open_array(protocol.device, None, URL, clock)
    try:
        bus.check_servos()
        bus.hold()
        trial = prepare_trial(bus, schedule.targets, schedule.pulses)
        heard = _Heard(bus.link)
        report = play_prepared(bus, trial, clock, onset=OnsetAfter(LEAD_NS),
                               tolerance_ns=protocol.device.delivery_tolerance_ns)
    finally:
        bus.close()
    onset, end = report.onset_ns, report.onset_ns + trial.end_ns
    during = [m for m in heard.messages if onset < m.stop_ns <= end]
    writes = []  # each frame's first write, in order: a rewrite that heals it comes after
    position = 0
    for frame in trial.frames:
        while position < len(during) and (during[position].read
                                          or bytes(during[position].data) != frame.packet):
            position += 1
        if position == len(during):
            break  # written after the trial's end: its slack shows below zero
        writes.append(during[position])
        position += 1
    read = sum(len(m.data) for m in during if m.read)
    return trial, onset, writes, read, report.delivery.missing


def _bare(trial: PwmTrial, address: int) -> list[int]:
    """The same bytes at the same times, nothing else: lateness (ns) of each write."""
    clock = MonotonicClock()
    link = SimI2cLink(URL, clock)
    onset = clock.now_ns() + LEAD_NS
    late = []
    for frame in trial.frames:
        due = onset + frame.time_ns
        clock.sleep_until_ns(due)
        message = link.write(address, frame.packet)
        late.append(message.stop_ns - link.message_ns(len(frame.packet)) - due)
    link.close()
    return late


def _lateness(trial, onset, writes, link_ns) -> list[int]:
    return [m.stop_ns - link_ns(len(m.data)) - (onset + f.time_ns)
            for m, f in zip(writes, trial.frames, strict=False)]


def _slack(trial, onset, writes) -> int:
    return min(onset + trial.window_end_ns(i) - m.stop_ns for i, m in enumerate(writes))


def _us(ns) -> str:
    return f"{ns / 1e3:>9.1f}"


def _three(values) -> str:
    return " ".join(_us(v) for v in (min(values), statistics.median(values), max(values)))


def bytes_per_frame(protocol) -> tuple:
    print("I2C per frame, the seed's trains (one pin each) on the simulated board; "
          "bytes with the address byte")
    print(f"{'train':>7} {'frames':>6} {'bytes/frame':>11} {'minimum':>7} {'ratio':>6} "
          f"{'us @400k':>8} {'min @400k':>9} {'us @100k':>8} {'read-back B/frame':>17}")
    slow = SimI2cLink(URL + "&bus_hz=100000", MonotonicClock())
    fast = SimI2cLink(URL, MonotonicClock())
    played = []
    for planned in _trials(protocol):
        schedule = compile_trial(protocol, planned)
        trial, onset, writes, read, _ = _play(protocol, schedule)
        played.append((trial, onset, writes, schedule))
        sizes = [1 + len(m.data) for m in writes]
        per_frame = statistics.median(sizes)
        changed = statistics.median(len(f.goals) for f in trial.frames)
        minimum = MINIMUM_BYTES * changed
        print(f"{float(planned.condition.frequency_hz):>5g}Hz {len(writes):>6} {per_frame:>11g} "
              f"{minimum:>7g} {per_frame / minimum:>5.2f}x "
              f"{fast.message_ns(int(per_frame) - 1) / 1e3:>8.1f} "
              f"{fast.message_ns(int(minimum) - 1) / 1e3:>9.1f} "
              f"{slow.message_ns(int(per_frame) - 1) / 1e3:>8.1f} "
              f"{read / max(1, len(writes)):>17.1f}")
    return played


def write_lateness(protocol, played) -> None:
    trial, _, _, schedule = played[-1]  # the fastest train: most frames
    address = protocol.device.servo.board.address
    ours_median, ours_worst, bare_median, bare_worst, slack = [], [], [], [], []
    missing = 0
    link_ns = SimI2cLink(URL, MonotonicClock()).message_ns
    for _ in range(RUNS):
        trial, onset, writes, _, lost = _play(protocol, schedule)
        missing += lost
        late = _lateness(trial, onset, writes, link_ns)
        ours_median.append(statistics.median(late))
        ours_worst.append(max(late))
        slack.append(_slack(trial, onset, writes))
        bare = _bare(trial, address)
        bare_median.append(statistics.median(bare))
        bare_worst.append(max(bare))
    print(f"\nWrite lateness at the board, {len(trial.frames)} frames a run, {RUNS} runs "
          f"(us: min/median/max over runs)")
    print(f"{'':<28} {SPREAD_HEADER}")
    print(f"{'median frame, player':<28} {_three(ours_median)}")
    print(f"{'median frame, bare loop':<28} {_three(bare_median)}")
    print(f"{'worst frame, player':<28} {_three(ours_worst)}")
    print(f"{'worst frame, bare loop':<28} {_three(bare_worst)}")
    print(f"{'slack before its period':<28} {_three(slack)}")
    ratio = statistics.median(ours_median) / max(1.0, statistics.median(bare_median))
    print(f"median lateness: player / bare loop = {ratio:.2f}x; a write is lost only when its "
          f"slack goes below 0 (period {float(trial.rate.period_ns) / 1e6:.2f} ms): "
          f"{missing} of {RUNS * len(trial.changes)} width changes lost (in this process, "
          "without the player process's real-time priority)")


def run() -> None:
    full = PROTOCOL.read_text()
    text = full.replace("duration_s: 10", f"duration_s: {SECONDS}")
    assert text != full, "the seed's train no longer lasts 10 s: update SECONDS' cut"
    protocol = parse_protocol(text, str(PROTOCOL))
    played = bytes_per_frame(protocol)
    write_lateness(protocol, played)


if __name__ == "__main__":
    run()
