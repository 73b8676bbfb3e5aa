"""pinarray: drive a servo pin-array tactile stimulator and run experiments on it.

The names below are the library's public face, for a lab's own scripts and tests::

    import pinarray

    protocol = pinarray.load_protocol("protocols/localisation.yaml")
    with pinarray.open_array(protocol, sim="sim://") as array:
        delivery = array.present(pinarray.find_condition(protocol, pin=6, frequency_hz=10))

Each is imported on first use (PEP 562), so ``import pinarray`` loads nothing else and the
commands start as fast as they did. What ``__all__`` lists is a promise kept by semantic
versioning (CHANGELOG.md); everything else in the package may move. ``pinarray.testing`` is
the simulated array and assertions for a lab's own tests (a pytest plugin).
"""

import os as _os
import sys as _sys


def _interrupted_at_start(signum: int, frame: object) -> None:
    """Ctrl-C while the `pinarray` command is still loading: one line, status 130 (nothing
    has been done yet); `pinarray.cli.main` puts Python's own handler back as it starts."""
    _os.write(2, b"pinarray: interrupted\n")
    _os._exit(130)


def _command_starting() -> bool:
    """Whether this import is the `pinarray` command starting: its console script (the main
    script is a file named pinarray, and is argv[0]) or ``python -m pinarray`` (not another
    module of the package run with -m, such as the player's child process)."""
    main_file = getattr(_sys.modules.get("__main__"), "__file__", None) or ""
    if _os.path.basename(main_file) == "pinarray" and _sys.argv[:1] == [main_file]:
        return True
    words = getattr(_sys, "orig_argv", [])
    return _sys.argv[:1] == ["-m"] and any(
        word == "-mpinarray" or (word == "-m" and words[k + 1:k + 2] == ["pinarray"])
        for k, word in enumerate(words))


# First, before anything else loads: Ctrl-C during the rest of the command's imports is then one
# line, not a traceback. `_signal` (built in, loaded with the interpreter) rather than `signal`,
# which imports enum. A library's `import pinarray` changes no handler.
if _command_starting():
    import _signal

    if _signal.getsignal(_signal.SIGINT) is not _signal.SIG_IGN:  # ignored: left so (nohup)
        _signal.signal(_signal.SIGINT, _interrupted_at_start)

import importlib  # noqa: E402

from pinarray.version import __version__ as __version__  # noqa: E402

# typing.TYPE_CHECKING without importing typing: type checkers take this name as true.
TYPE_CHECKING = False

__all__ = [
    "Answer",
    "AnswerSource",
    "Armed",
    "BusError",
    "Clock",
    "Condition",
    "Cut",
    "DamagedResults",
    "Delivery",
    "DeliveryRecord",
    "Ending",
    "Frames",
    "IdentificationCondition",
    "IdentificationRecord",
    "LoadedRun",
    "LocalisationCondition",
    "LocalisationRecord",
    "ManifestState",
    "MonotonicClock",
    "MotionCondition",
    "MotionRecord",
    "NotDelivered",
    "NotStarted",
    "NothingToResume",
    "Paradigm",
    "Pattern",
    "PinArray",
    "PinArrayError",
    "PinStroke",
    "PlannedTrial",
    "PlaybackAborted",
    "Played",
    "PortInUse",
    "PortLost",
    "Presentable",
    "Protocol",
    "ProtocolError",
    "ProtocolErrors",
    "Question",
    "ResultsError",
    "RunLocked",
    "RunPaths",
    "SafeStopReport",
    "ServoPort",
    "TemporalOrderCondition",
    "TemporalOrderRecord",
    "Train",
    "TrialPlan",
    "TrialRecord",
    "TrialStatus",
    "TwoIntervalCondition",
    "TwoIntervalRecord",
    "TwoPointCondition",
    "TwoPointRecord",
    "VirtualClock",
    "Wave",
    "find_condition",
    "find_servo_ports",
    "load_protocol",
    "open_array",
    "plan_trials",
    "protocol_from_text",
    "read_results",
    "run_session",
    "simulated_observer",
]

# The module of `pinarray.api` each public name lives in, imported when the name is first used.
_HOMES = {
    "pinarray.api.protocols": ("Condition", "PlannedTrial", "Protocol", "TrialPlan",
                               "find_condition", "load_protocol", "plan_trials",
                               "protocol_from_text"),
    "pinarray.api.paradigms": ("IdentificationCondition", "IdentificationRecord",
                               "LocalisationCondition", "LocalisationRecord", "MotionCondition",
                               "MotionRecord", "Paradigm", "TemporalOrderCondition",
                               "TemporalOrderRecord", "TwoIntervalCondition",
                               "TwoIntervalRecord", "TwoPointCondition", "TwoPointRecord"),
    "pinarray.api.array": ("Clock", "DeliveryRecord", "MonotonicClock", "PinArray", "PinStroke",
                           "Presentable", "SafeStopReport", "VirtualClock", "open_array"),
    "pinarray.api.stimuli": ("Frames", "Pattern", "Train", "Wave"),
    "pinarray.api.armed": ("Armed",),
    "pinarray.api.delivery": ("Cut", "Delivery", "Ending", "NotStarted", "Played"),
    "pinarray.api.ports": ("ServoPort", "find_servo_ports"),
    "pinarray.api.sessions": ("Answer", "AnswerSource", "NotDelivered", "Question",
                              "run_session", "simulated_observer"),
    "pinarray.api.results": ("LoadedRun", "ManifestState", "RunPaths", "TrialRecord",
                             "TrialStatus", "read_results"),
    "pinarray.api.errors": ("BusError", "DamagedResults", "NothingToResume", "PinArrayError",
                            "PlaybackAborted", "PortInUse", "PortLost", "ProtocolError",
                            "ProtocolErrors", "ResultsError", "RunLocked"),
}
_HOME_OF = {name: module for module, names in _HOMES.items() for name in names}


def __getattr__(name: str) -> object:
    module = _HOME_OF.get(name)
    if module is None:
        raise AttributeError(f"module 'pinarray' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # found directly from now on
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})


if TYPE_CHECKING:  # what type checkers and documentation tools see; never run
    from pinarray.api.armed import Armed
    from pinarray.api.array import (
        Clock,
        DeliveryRecord,
        MonotonicClock,
        PinArray,
        PinStroke,
        Presentable,
        SafeStopReport,
        VirtualClock,
        open_array,
    )
    from pinarray.api.delivery import Cut, Delivery, Ending, NotStarted, Played
    from pinarray.api.errors import (
        BusError,
        DamagedResults,
        NothingToResume,
        PinArrayError,
        PlaybackAborted,
        PortInUse,
        PortLost,
        ProtocolError,
        ProtocolErrors,
        ResultsError,
        RunLocked,
    )
    from pinarray.api.paradigms import (
        IdentificationCondition,
        IdentificationRecord,
        LocalisationCondition,
        LocalisationRecord,
        MotionCondition,
        MotionRecord,
        Paradigm,
        TemporalOrderCondition,
        TemporalOrderRecord,
        TwoIntervalCondition,
        TwoIntervalRecord,
        TwoPointCondition,
        TwoPointRecord,
    )
    from pinarray.api.ports import ServoPort, find_servo_ports
    from pinarray.api.protocols import (
        Condition,
        PlannedTrial,
        Protocol,
        TrialPlan,
        find_condition,
        load_protocol,
        plan_trials,
        protocol_from_text,
    )
    from pinarray.api.results import (
        LoadedRun,
        ManifestState,
        RunPaths,
        TrialRecord,
        TrialStatus,
        read_results,
    )
    from pinarray.api.sessions import (
        Answer,
        AnswerSource,
        NotDelivered,
        Question,
        run_session,
        simulated_observer,
    )
    from pinarray.api.stimuli import Frames, Pattern, Train, Wave
