"""`pinarray pwm scan`: which PCA9685 boards answer on an I2C bus (hobby PWM servos)."""

from __future__ import annotations

import argparse

from pinarray.cli.output import say

SCAN_EPILOG = """\
Reads MODE1 and PRE_SCALE at every address a PCA9685 can take (0x40-0x7f, set by its A0-A5
jumpers), leaving the all-call address 0x70 alone (every board answers it). A board is listed
with its state: asleep (its power-up state: no pulses) or running, and the rate its prescale
gives at the nominal 25 MHz (boards are off by up to several percent: measure it, README).
Nothing is written. Needs --port PATH (the I2C bus, e.g. /dev/i2c-1) or --sim [URL] to
rehearse (then its first line says SIMULATED).
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    pwm = subparsers.add_parser("pwm", help="hobby PWM servos on a PCA9685 board: scan the bus")
    sub = pwm.add_subparsers(dest="pwm_command", metavar="COMMAND", required=True)
    p = sub.add_parser("scan", help="list the PCA9685 boards that answer on an I2C bus",
                       epilog=SCAN_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    group = p.add_mutually_exclusive_group()
    group.add_argument("--port", metavar="PATH", help="the I2C bus of real boards (/dev/i2c-N)")
    group.add_argument("--sim", nargs="?", const="sim://pca9685", metavar="URL",
                       help="a simulated board, optionally a sim://pca9685 URL "
                            "(e.g. 'sim://pca9685?address=0x40,0x41')")
    p.set_defaults(func=_cmd_scan)


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
    return 0 if found else 3
