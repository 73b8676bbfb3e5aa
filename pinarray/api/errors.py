"""The one exception family a script catches: every `PinArrayError` says what, where and what
was found (a protocol's problems at ``file:line:col``, a servo by its id and register)."""

from pinarray.errors import BusError, PinArrayError, ProtocolError, ProtocolErrors, ResultsError

__all__ = ["BusError", "PinArrayError", "ProtocolError", "ProtocolErrors", "ResultsError"]
