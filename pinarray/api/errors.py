"""The one exception family a script catches: every `PinArrayError` says what, where and what
was found (a protocol's problems at ``file:line:col``, a servo by its id and register, a port
by its holder). Every exception a public call raises is one of these (or Python's own
`KeyboardInterrupt`)."""

from pinarray.errors import BusError, PinArrayError, ProtocolError, ProtocolErrors, ResultsError
from pinarray.hardware.port_lock import PortInUse
from pinarray.player.playback import PlaybackAborted

__all__ = ["BusError", "PinArrayError", "PlaybackAborted", "PortInUse", "ProtocolError",
           "ProtocolErrors", "ResultsError"]
