"""`pinarray pwm ...`: hobby PWM servos on a PCA9685 board: which boards answer on an I2C bus
(`scan`), and each pin's rest and up pulse widths found by jogging (`calibrate`)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from pinarray.cli.bus import port_path
from pinarray.cli.calibrate import JogDialogue
from pinarray.cli.output import say

if TYPE_CHECKING:
    from pinarray.hardware.pca9685.jog import PwmJog, PwmJogReading

SCAN_EPILOG = """\
Reads MODE1 and PRE_SCALE at every address a PCA9685 can take (0x40-0x7f, set by its A0-A5
jumpers), leaving the all-call address 0x70 alone (every board answers it). A board is listed
with its state: asleep (its power-up state: no pulses) or running, and the rate its prescale
gives at the nominal 25 MHz (boards are off by up to several percent: measure it: docs/rig/pwm.md).
Nothing is written. Needs --port PATH (the I2C bus, e.g. /dev/i2c-1) or --sim [URL] to
rehearse (then its first line says SIMULATED).
"""


CALIBRATE_EPILOG = """\
Sends pulses of the pin's rest width on its channel alone (the others stay full off, their
servos limp) and asks, on lines:
  +  / -       one step (--step, default 10 us) wider / narrower
  +N / -N      N us           =N   go to N us           (empty line: what the board holds)
  ok           this is the width (first rest, then up)
  q            stop without writing anything
A new width is approached at 1000 us/s at most, one board period at a time, within 500..2500
us (widened to the pin's calibrated limits). Hobby servos report nothing: watch the pin. Then
the protocol file's device: pins: N: entry gets rest_us and positions (the narrowest pulse
width at rest, the widest up), limits_us too if the new widths leave them; comments, key order
and line ends stay, and the result is read back as a protocol before the file is replaced. On
any exit the pin goes to rest, is held there for its travel time, then every channel goes full
off (no pulses).
"""


def _board_choice(parser: argparse.ArgumentParser) -> None:
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--port", metavar="PATH", type=port_path,
                       help="the I2C bus of real boards (/dev/i2c-N)")
    group.add_argument("--sim", nargs="?", const="sim://pca9685", metavar="URL",
                       help="a simulated board, optionally a sim://pca9685 URL "
                            "(e.g. 'sim://pca9685?address=0x40,0x41')")


def register(subparsers: argparse._SubParsersAction) -> None:
    from pinarray.cli import common

    pwm = subparsers.add_parser("pwm", help="hobby PWM servos on a PCA9685 board: scan the bus, "
                                "calibrate a pin")
    sub = pwm.add_subparsers(dest="pwm_command", metavar="COMMAND", required=True)
    p = sub.add_parser("scan", help="list the PCA9685 boards that answer on an I2C bus",
                       epilog=SCAN_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    _board_choice(p)
    p.set_defaults(func=_cmd_scan)
    p = sub.add_parser("calibrate", help="jog one pin's pulse width to rest and up, then write "
                       "them into the protocol", epilog=CALIBRATE_EPILOG,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("protocol", metavar="PROTOCOL", help="protocol YAML file to update")
    p.add_argument("--pin", type=common.count(1, 4096), required=True, metavar="N",
                   help="the pin to calibrate")
    p.add_argument("--step", type=common.count(1, 500), default=10, metavar="US",
                   help="us of pulse width per + or - (default 10)")
    _board_choice(p)
    p.set_defaults(func=_cmd_calibrate)


def _cmd_scan(args: argparse.Namespace) -> int:
    from pinarray.clock import MonotonicClock
    from pinarray.errors import PinArrayError
    from pinarray.hardware.pca9685.bringup import scan
    from pinarray.hardware.pca9685.i2c import I2cLink

    clock = MonotonicClock()
    link: I2cLink
    if args.port:
        from pinarray.hardware.pca9685.smbus_link import SmbusLink

        link = SmbusLink(args.port, clock)
    elif args.sim is not None:
        from pinarray.hardware.pca9685.sim import SimI2cLink

        link = SimI2cLink(args.sim, clock)
        say(f"SIMULATED board(s) ({args.sim}): no real board is touched")
    else:
        raise PinArrayError("pwm scan: which bus? add --port PATH for a real one (e.g. "
                            "--port /dev/i2c-1), or --sim to rehearse on a simulated board")
    try:
        found = scan(link)
    finally:
        link.close()
    for board in found:
        say(board.describe())
    say(f"{len(found)} board(s) answer on {link.name}"
        + ("" if found else ": check power, SDA/SCL and pull-ups; `i2cdetect -y N` lists "
           "every device on bus N"))
    return 0 if found else 2  # as `servos scan` finding no servo: 3 is a stimulus not delivered


class _PwmJogger(JogDialogue):
    """A hobby servo's `pinarray.hardware.pca9685.jog.PwmJog`: it says what the board holds."""

    unit = "us"
    shown = "what the board holds"

    def __init__(self, jog: PwmJog, up_us: int):
        self.jog, self.up_us = jog, up_us
        self.held = False

    @property
    def goal(self) -> int:
        return self.jog.goal_us

    def start(self) -> str:
        self.held = self.jog.start().held
        low, high = self.jog.bounds
        return (f"{self.name}: pulses of {self.jog.goal_us} us, its calibrated rest (up "
                f"{self.up_us} us; the jog allows {low}..{high} us){self._not_held()}. Hobby "
                "servos report nothing: watch the pin.")

    def _not_held(self) -> str:
        return "" if self.held else " (the board does NOT hold it: check its power)"

    def _said(self, reading: PwmJogReading) -> str:
        self.held = reading.held
        return f"  {reading.goal_us} us{self._not_held()}"

    def refusal(self) -> str | None:
        if self.held:
            return None
        return (f"the board does not hold {self.jog.goal_us} us: check its power, then type "
                "the width again (the board is started again), or q")

    def release(self, rest: int) -> str:
        try:
            safe = self.jog.release(rest)
        finally:
            self.jog.array.close()
        where = f"at rest ({rest} us)" if safe.at_rest_ids else "NOT confirmed at rest"
        pulses = "no pulses" if safe.released_ids else "pulses NOT confirmed off"
        return f"{self.name}: {where}, then {pulses}"


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from pinarray.cli.bus import chosen_array
    from pinarray.cli.calibrate import calibrate_pin, protocol_to_calibrate
    from pinarray.clock import MonotonicClock
    from pinarray.errors import PinArrayError
    from pinarray.hardware.pca9685.jog import PwmJog
    from pinarray.player.families import open_board
    from pinarray.protocol import HobbyServos
    from pinarray.stop import StoppableClock, StopRequest, stop_on_signals

    protocol, data = protocol_to_calibrate(args)
    device = protocol.device
    if not isinstance(device.servo, HobbyServos):
        raise PinArrayError(f"{args.protocol}: its device is STS bus servos, not a PWM board: "
                            "use `pinarray servos calibrate`")
    url = chosen_array(args, "pwm calibrate", device)
    clock = MonotonicClock()
    with stop_on_signals(StopRequest()) as stop:
        array = open_board(device, args.port, None if args.port else url, clock)
        jog = PwmJog(array, args.pin, StoppableClock(clock, stop))
        up = device.calibration(args.pin).positions_by_width_ns[-1][1]
        return calibrate_pin(args, protocol, data, _PwmJogger(jog, up), stop)
