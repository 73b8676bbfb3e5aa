"""A Lab Streaming Layer marker outlet, so EEG and physiology recordings line up with the stimuli.

One string channel of type ``Markers`` at an irregular rate (what LabRecorder records beside
an EEG amplifier's stream), named ``pinarray`` unless asked otherwise. Each marker carries
the time it stands for, converted from the session's clock to LSL's: on Linux both are
CLOCK_MONOTONIC (liblsl's clock is ``std::chrono::steady_clock``), so the conversion is the
identity; any other clock gets its offset measured when the outlet opens.

The outlet lives where trials play: `MarkerStream` is what the rig is given, a picklable
recipe the player process (or the rig, when trials play in this process) opens once there, so
each onset marker goes out from the player right after the onset frame's write.

pylsl (and the liblsl inside its wheels) is imported only here and only when an outlet is
asked for: ``pip install 'pinarray[lsl]'``. Which network LSL announces the stream on is
liblsl's configuration: the default scope reaches the lab's network; a file named by the
``LSLAPICFG`` environment variable can keep it on this machine (docs/experimenters/scanner-eeg.md).
"""

from __future__ import annotations

from dataclasses import dataclass

from pinarray.clock import Clock
from pinarray.errors import PinArrayError
from pinarray.units import NS_PER_S
from pinarray.version import __version__

STREAM_TYPE = "Markers"
DEFAULT_STREAM_NAME = "pinarray"
# Offsets smaller than this between the session's clock and LSL's are the same clock read
# twice (measured here: about 1 us apart), and are taken as exactly zero.
SAME_CLOCK_S = 0.0005
_OFFSET_PROBES = 7


class LslError(PinArrayError):
    """An LSL outlet cannot be opened (pylsl missing, or liblsl refused)."""


def _pylsl():
    try:
        import pylsl
    except ImportError as problem:
        raise LslError(f"--lsl needs pylsl: pip install 'pinarray[lsl]' ({problem})") from None
    except (OSError, RuntimeError) as problem:  # pylsl found no liblsl it could load
        raise LslError(f"--lsl: pylsl cannot load its library: {problem}") from None
    return pylsl


def source_id() -> str:
    """The stream's source id: the same from every process of this machine, so an inlet
    picks the stream up again when a new player process opens it."""
    import socket  # here: every batch reads this module's default name to build its options

    return f"pinarray-markers@{socket.gethostname()}"


@dataclass(frozen=True)
class MarkerStream:
    """A marker stream to open where trials play (`pinarray.player.markers.Announcers`).

    Parameters
    ----------
    name : str
        The stream's name (what LabRecorder lists).
    """

    name: str

    @property
    def source_id(self) -> str:
        return source_id()

    def check(self) -> None:
        """Raise `LslError` now if pylsl cannot be loaded here (before anything connects)."""
        _pylsl()

    def open(self, clock: Clock) -> MarkerOutlet:
        return MarkerOutlet(self.name, clock)


class MarkerOutlet:
    """An LSL outlet of string markers stamped on LSL's clock.

    Parameters
    ----------
    name : str
        The stream's name (what LabRecorder lists).
    clock : Clock
        The session's clock: `push` takes times on it (`use_clock` changes it).
    """

    def __init__(self, name: str, clock: Clock):
        pylsl = _pylsl()
        self._pylsl = pylsl
        self.name = name
        self.source_id = source_id()
        info = pylsl.StreamInfo(name, STREAM_TYPE, 1, pylsl.IRREGULAR_RATE, "string",
                                self.source_id)
        description = info.desc()
        description.append_child_value("manufacturer", "pinarray")
        description.append_child_value("version", __version__)
        description.append_child_value(
            "format", 'JSON: {"event": "onset"|"offset", "trial", "block", "practice", "task", '
                      '"pin" or "row" and "direction", "frequency_hz"}')
        try:
            self._outlet = pylsl.StreamOutlet(info)
        except RuntimeError as problem:
            raise LslError(f"--lsl: cannot open the marker outlet {name!r}: {problem}") from None
        self.pushed = 0
        self.use_clock(clock)

    def use_clock(self, clock: Clock) -> None:
        """Take times on ``clock`` from now on (the next run's), its offset to LSL measured."""
        self.clock = clock
        self.offset_s = self._measure_offset()

    def _measure_offset(self) -> float:
        """LSL's clock minus the session's (s), from the tightest of a few bracketed reads."""
        local_clock = self._pylsl.local_clock
        best = None
        for _ in range(_OFFSET_PROBES):
            before_ns = self.clock.now_ns()
            lsl_s = local_clock()
            after_ns = self.clock.now_ns()
            if best is None or after_ns - before_ns < best[0]:
                best = (after_ns - before_ns, lsl_s - (before_ns + after_ns) / 2 / NS_PER_S)
        assert best is not None
        return 0.0 if abs(best[1]) < SAME_CLOCK_S else best[1]

    def lsl_time(self, clock_ns: int) -> float:
        """A time on the session's clock (ns) on LSL's clock (s)."""
        return clock_ns / NS_PER_S + self.offset_s

    def push(self, marker: str, at_ns: int) -> None:
        """Send ``marker`` stamped with ``at_ns`` (session clock ns), through at once."""
        self._outlet.push_sample([marker], self.lsl_time(at_ns))
        self.pushed += 1

    def close(self) -> None:
        """Take the stream off the network (inlets see it end)."""
        outlet, self._outlet = self._outlet, None
        del outlet
