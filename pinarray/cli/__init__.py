"""The `pinarray` command: a composition root that turns user mistakes into one-line errors.

Each subcommand group is a module of this package with ``register(subparsers)``; argparse is
imported as the parser is built and each handler imports what it needs when it runs, so
``pinarray validate`` never pays for numpy, Textual or matplotlib. A command line that starts
with a command's name registers only the module of that command: ``pinarray validate`` does not
import the bus, the journal or the other commands' modules to build their options.
"""

from __future__ import annotations

import os
import sys

# Nothing else at module level (os and sys are loaded with the interpreter): the console script imports this module before `main` runs, and
# Ctrl-C during an import is a traceback; inside `main` it is one line (argparse alone takes
# some 17 ms to import, typing 6 ms). mypy reads any TYPE_CHECKING as true.
TYPE_CHECKING = False
if TYPE_CHECKING:
    import argparse
    from collections.abc import Sequence

    from pinarray.stop import Stopped

# The module of this package that registers each command, in the order `pinarray --help` lists
# them (tests/test_startup.py holds this table to what the modules register).
COMMANDS = {
    "grid": ("grid",),
    "protocols": ("validate", "compile", "preview", "plan"),
    "bus": ("play", "timing", "scan", "sim-serve"),
    "servos": ("servos",),
    "pwm": ("pwm",),
    "batch": ("batch",),
    "analysis": ("analyse", "power"),
    "softness": ("softness",),
    "tui": ("tui",),
}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The `pinarray` parser: every command, or only those of the module that registers ``command``."""
    import argparse
    from importlib import import_module

    from pinarray.version import __version__

    parser = argparse.ArgumentParser(
        prog="pinarray",
        description="Drive a servo pin-array tactile stimulator and run experiments on it.",
    )
    parser.add_argument("--version", action="version", version=f"pinarray {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    modules = [module for module, words in COMMANDS.items() if command in words] or list(COMMANDS)
    for module in modules:
        import_module(f"pinarray.cli.{module}").register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command ``argv`` names (the process's arguments by default): its exit status.

    Ctrl-C at any moment of it ends in one line and status 130, the parser's building and the
    reading of the arguments included (they import each command's options). As the process's
    command (no ``argv``), from the start of its imports (`pinarray._interrupted_at_start`) to
    its exit: once the command's work is done its status stands, and a Ctrl-C then (the
    interpreter ending) is said in one line (`_say_late_interrupts`).
    """
    import _signal

    import pinarray

    if _signal.getsignal(_signal.SIGINT) is pinarray._interrupted_at_start:
        _signal.signal(_signal.SIGINT, _signal.default_int_handler)  # KeyboardInterrupt again
    _escape_what_the_streams_cannot_encode()
    try:
        status = _main(sys.argv[1:] if argv is None else list(argv))
    except KeyboardInterrupt:
        return _interrupted()
    if argv is None:
        _say_late_interrupts()
    return status


def _escape_what_the_streams_cannot_encode() -> None:
    """What standard output cannot encode is printed as Python escapes (as standard error
    always does), not a traceback: a file name in bytes the locale cannot read (a protocol in
    a folder named in Latin-1 on a UTF-8 system holds a lone surrogate), or a character beyond
    the terminal's encoding (the degree sign of ``servos scan`` in an ASCII locale). Python's
    own choice for a UTF-8 locale is to fail ("strict"); under C.UTF-8 it is to pass a name's
    bytes through ("surrogateescape"), which still fails on any other character: `validate`
    said ok on one machine and crashed on the next."""
    import codecs
    import io

    codecs.register_error(_BYTES_OR_ESCAPES, _bytes_or_escapes)
    for stream in (sys.stdout, sys.stderr):
        if isinstance(stream, io.TextIOWrapper) and stream.errors in ("strict",
                                                                       "surrogateescape"):
            stream.reconfigure(errors="backslashreplace" if stream.errors == "strict"
                               else _BYTES_OR_ESCAPES)


_BYTES_OR_ESCAPES = "pinarray.bytes-or-escapes"


def _bytes_or_escapes(error: UnicodeError) -> tuple[str | bytes, int]:
    """A name's own bytes where Python kept them as surrogates, else Python escapes."""
    import codecs

    try:
        return codecs.lookup_error("surrogateescape")(error)
    except UnicodeError:
        return codecs.backslashreplace_errors(error)


LATE_INTERRUPT = b"pinarray: interrupted as the command ended; its result stands\n"


def _say_late_interrupts() -> None:
    """The command's work is done: a Ctrl-C from now on (its last output flushed, threads
    joined, the interpreter ending) must neither turn its status into 130 nor kill it by the
    signal with nothing said (Python puts the default action back as it ends). Until the exit
    handlers run the first one is said in one line; from then on it is ignored. The status
    stands. Through `_signal`, as at the start: `pinarray.stop` (threads, the clock) is more
    than ``validate`` loads."""
    import _signal
    import atexit

    said: list[int] = []

    def late(signum: int, frame: object) -> None:
        if not said:
            said.append(signum)
            os.write(2, LATE_INTERRUPT)

    _signal.signal(_signal.SIGINT, late)
    # Registered last, so run first of the exit handlers: Python would reset `late` to the
    # default action (death by the signal) as it ends; an ignored signal it leaves ignored.
    atexit.register(_signal.signal, _signal.SIGINT, _signal.SIG_IGN)


def _main(argv: list[str]) -> int:
    from pinarray.errors import PinArrayError

    # Only the first word can name the command: the parser's own options (-h, --version) come
    # before it and end the run, so they get every command.
    parser = build_parser(argv[0] if argv else None)
    try:
        args = parser.parse_args(argv)
    except PinArrayError as error:  # an option's type= that said so in our words: still one line
        print(f"pinarray: {error}", file=sys.stderr)
        return 2
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        return _run(args)
    finally:
        _warn_of_ignored_plug_ins()


def _interrupted() -> int:
    from pinarray.cli.output import say

    say("pinarray: interrupted", error=True)
    return 130


def _run(args: argparse.Namespace) -> int:
    """The command ``args`` name, its errors said in one line each; its exit status."""
    from pinarray.cli.output import StandardOutputFailed, discard, guarded_stdout
    from pinarray.errors import PinArrayError

    try:
        with guarded_stdout():
            return int(args.func(args) or 0)
    except _stopped() as stopped:
        # `say`: the terminal may be gone with the signal (SIGHUP as an SSH session closes).
        from pinarray.cli.output import say

        say(f"pinarray: {stopped}", error=True)
        return stopped.exit_status
    except PinArrayError as error:
        for line in str(error).splitlines() or [type(error).__name__]:
            print(f"pinarray: {line}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return _interrupted()
    except BrokenPipeError:
        # The reader went away (``pinarray play ... | head``): end as if by SIGPIPE, quietly.
        import signal

        discard(sys.stdout)
        return 128 + signal.SIGPIPE
    except StandardOutputFailed as failed:
        # ``> /dev/full``, a full disk: one line and status 2, as any output that cannot be
        # written; the command's own files (a batch's results) stand as written.
        discard(sys.stdout)
        from pinarray.cli.output import say

        (cause,) = failed.args
        say(f"pinarray: standard output: {cause.strerror or cause}", error=True)  # to the same
        return 2  # full disk, perhaps (``> log 2>&1``): then said to nobody, the status stands


def _warn_of_ignored_plug_ins() -> None:
    """One line for each installed paradigm plug-in left out, where the command read them
    (listing the paradigms there are, or loading one not pinarray's own)."""
    from pinarray import registry

    for plug_in in registry.ignored():
        print(f"pinarray: warning: {plug_in.warning()}", file=sys.stderr)


def _stopped() -> type[Stopped]:
    """`Stopped`, imported only once a command has raised (an ``except`` clause is evaluated
    then): `pinarray.stop` brings signal handling and threads that ``validate`` does not need."""
    from pinarray.stop import Stopped

    return Stopped


if __name__ == "__main__":
    raise SystemExit(main())
