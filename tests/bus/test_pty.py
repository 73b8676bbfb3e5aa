"""End to end: simulated servos on a pseudo-terminal, driven like real hardware via pyserial."""

import os
import signal
import subprocess
import sys

import serial

from pinarray.bus.faults import SimConfig
from pinarray.bus.serve import PtyServer
from pinarray.bus.transport import open_bus
from pinarray.clock import MonotonicClock
from pinarray.player import play_trial

from .lab import assert_safe, device_setup, pulse_train


def test_a_raw_pyserial_ping_gets_a_status_packet_back():
    server = PtyServer(SimConfig(ids=(1,))).start()
    try:
        with serial.Serial(server.path, 1_000_000, timeout=2) as port:
            port.write(bytes([0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB]))
            assert port.read(6) == bytes([0xFF, 0xFF, 0x01, 0x02, 0x00, 0xFC])
    finally:
        server.stop()


def test_play_over_the_pseudo_terminal_ends_with_pins_at_rest():
    server = PtyServer(SimConfig(ids=tuple(range(1, 5)))).start()
    try:
        clock = MonotonicClock()
        bus = open_bus(server.path, device_setup(range(1, 5)), clock)
        report = play_trial(bus, pulse_train([1, 2, 3, 4], 10, 3), clock)
        bus.close()
    finally:
        server.stop()
    assert report.frames_sent == 6
    assert report.safe_stop.complete
    bus.sim = server.sim  # the servos live in the server
    assert_safe(bus)


def test_sim_serve_prints_its_path_serves_a_scan_and_stops_on_sigterm():
    process = subprocess.Popen(
        [sys.executable, "-m", "pinarray", "sim-serve", "--ids", "1-3"],
        stdout=subprocess.PIPE, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        first_line = process.stdout.readline()
        path = first_line.split(" on ")[1].split()[0]
        scan = subprocess.run(
            [sys.executable, "-m", "pinarray", "scan", "--port", path, "--ids", "1-4"],
            capture_output=True, text=True, timeout=60,
        )
        assert "3 servo(s) answered" in scan.stdout, scan.stdout + scan.stderr
        process.send_signal(signal.SIGTERM)
        assert process.wait(timeout=10) == 0
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(timeout=10)
