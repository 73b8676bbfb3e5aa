"""The one exception family people see: every message says what, where, and what was found."""

from __future__ import annotations


class PinArrayError(Exception):
    """A user-facing error; the CLI prints it on one line and exits with status 2."""


class ProtocolError(PinArrayError):
    """A problem in a protocol file, located at ``file:line:col``.

    Lines and columns are 1-based, as editors show them.
    """

    def __init__(self, message: str, file: str = "<protocol>", line: int = 0, col: int = 0):
        self.message = message
        self.file = file
        self.line = line
        self.col = col
        super().__init__(self.located())

    def located(self) -> str:
        """``file:line:col: message`` (``file: message`` when no line is known)."""
        if self.line:
            return f"{self.file}:{self.line}:{self.col}: {self.message}"
        return f"{self.file}: {self.message}"


class ProtocolErrors(PinArrayError):
    """Several protocol problems found in one pass, reported one per line."""

    def __init__(self, errors: list[ProtocolError]):
        self.errors = errors
        super().__init__("\n".join(e.located() for e in errors))


class Interrupted(PinArrayError):
    """The run was asked to stop (SIGTERM): not a fault of the stimulus, the bus or the input.

    ``safe_stop``: what the safe stop made on the way out achieved (the player's
    `SafeStopReport`, set by whoever made it; None when none was made, e.g. before a stimulus
    began), so that whoever asked need not make another.
    """

    safe_stop: object = None


class BusError(PinArrayError):
    """The servo bus failed; the message names the servo ids and the register."""


class ResultsError(PinArrayError):
    """Results cannot be written or read where asked."""
