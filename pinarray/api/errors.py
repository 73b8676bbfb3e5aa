"""The one exception family a script catches: every `PinArrayError` says what, where and what
was found (a protocol's problems at ``file:line:col``, a servo by its id and register, a port
by its holder). Every exception a public call raises is one of these (or Python's own
`KeyboardInterrupt`)."""

from pinarray.analysis.load import DamagedResults
from pinarray.errors import BusError, PinArrayError, ProtocolError, ProtocolErrors, ResultsError
from pinarray.hardware.driver import PortLost
from pinarray.hardware.port_lock import PortInUse
from pinarray.journal.lock import RunLocked
from pinarray.journal.runs import NothingToResume
from pinarray.player.playback import PlaybackAborted

__all__ = ["BusError", "DamagedResults", "NothingToResume", "PinArrayError", "PlaybackAborted",
           "PortInUse", "PortLost", "ProtocolError", "ProtocolErrors", "ResultsError",
           "RunLocked"]
