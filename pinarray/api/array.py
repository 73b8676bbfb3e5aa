"""An open pin array for scripts: present a stimulus now, armed for a time or armed to start
on a cue (a screen flip as it happens), stop it at any moment, learn what was delivered.

`open_array` connects the protocol's array (real servos on a port, or the simulated array) as
``pinarray play`` does: the port held against every other opener, every servo pinged, all
missing ones named at once, the pins to rest. On real servos the stimuli play in a player
process of their own, which also rests the pins if the script's process is killed outright.

A stop stops: `PinArray.stop`, `Armed.cancel`, `PinArray.close` and leaving the ``with``
block (at its end or by an error) cut a stimulus still armed or playing, put every pin to
rest and switch torque off; its `Delivery` says it was cut, and when. An array still open
when the script ends is closed as the interpreter exits, the same way; one the script lets go
of without closing it is closed as it is collected (its port free again). On real servos a
script suspended (Ctrl-Z) while a stimulus plays gets it cut the same way (`Cut`, by "the
script's suspension"): nobody could stop it while the script is suspended. A forked copy of
the script (``multiprocessing`` workers) holds nothing of the array: only the script drives
it, and its end rests the pins whatever the copies do.

Times are integer nanoseconds on the array's clock (`PinArray.now_ns`): on real servos that
is ``time.monotonic_ns()`` (CLOCK_MONOTONIC, the clock PsychoPy's flips are stamped on under
Linux); on the simulated array, virtual time unless the script gives a clock. Notices (the
connection's warnings, healed writes, retries, each stimulus's verdict) go to the `logging`
logger ``"pinarray"``.

Past 400 lines on purpose: the array's states (idle, a stimulus armed or playing, closed) and
the one lock every change of them takes, with the face's docstrings that the reference is
built from; the stimulus armed (`armed`) and what it delivered (`delivery`) live beside it.
"""

from __future__ import annotations

import atexit
import os
import queue
import threading
import weakref
from types import TracebackType

from pinarray.api import arguments
from pinarray.api.armed import Armed
from pinarray.api.delivery import (
    Cut,
    Delivery,
    NotStarted,
    log,
    onset_write_late_ns,
    tell,
    unplayed,
)
from pinarray.api.protocols import default_protocol
from pinarray.api.stimuli import Built, Frames, Pattern, Train, Wave, code_stimulus, described
from pinarray.clock import Clock, MonotonicClock, VirtualClock
from pinarray.errors import PinArrayError
from pinarray.hardware.delivery import DeliveryRecord, PreparedTrial
from pinarray.hardware.driver import SafeStopReport
from pinarray.hardware.motion import PinStroke
from pinarray.plan import PlannedTrial
from pinarray.player.playback import (
    DEFAULT_LEAD_NS,
    Onset,
    OnsetAfter,
    OnsetAt,
    OnsetPassed,
    PlaybackAborted,
    Suspended,
)
from pinarray.player.process import StartCue
from pinarray.player.rehearsal import Rehearsal
from pinarray.player.rig import Rig, choose_clock
from pinarray.protocol.drives import trial_drives
from pinarray.protocol.in_code import drives_on
from pinarray.protocol.model import Condition, PinDrive, Protocol, is_simulated
from pinarray.schedule import compile_drives
from pinarray.stop import Stopped, signal_name

__all__ = ["Clock", "DeliveryRecord", "MonotonicClock", "PinArray", "PinStroke",
           "Presentable", "SafeStopReport", "VirtualClock", "open_array"]

Presentable = PlannedTrial | Condition | Pattern | Frames | Wave
"""What `PinArray.present` plays: a trial of the protocol's plan, one of its conditions, or a
stimulus built in code (`Pattern`, `Frames`, `Wave`)."""

# What an array plays: a condition of its protocol, or a stimulus built in code.
Stimulus = Condition | Built

# Arrays still open, closed as the interpreter exits (a stimulus armed at the script's end).
_open_arrays: weakref.WeakSet[PinArray] = weakref.WeakSet()
# What cut a stimulus when the script was suspended while it played (real servos).
SUSPENSION = "the script's suspension (Ctrl-Z)"


class PinArray:
    """A connected pin array for one protocol: `open_array` makes one.

    One stimulus plays at a time; between stimuli the pins hold at rest (or, after a stop,
    rest released: the next stimulus turns torque on again).
    """

    lead_ns: int = DEFAULT_LEAD_NS
    """How far ahead of the array's clock a stimulus is armed for a time at least, in ns; a
    stimulus presented at once starts this long after the call."""

    def __init__(self, rig: Rig, asked: str | None = None) -> None:
        self._rig = rig
        self._asked = asked or rig.url  # the port or sim:// URL as the script gave it
        self._lock = threading.RLock()  # one change of state at a time: arm, stop, close
        self._current: Armed | None = None
        self._safe_stop: SafeStopReport | None = None  # set once closed
        self._trials: dict[Stimulus, PreparedTrial] = {}
        self._built: dict[Built, tuple[PinDrive, ...]] = {}  # read against this array's device
        self._preparing = threading.Lock()
        # Code-built stimuli played first on the simulated array, as `pinarray validate` plays
        # a protocol's (opened on first use, one play per distinct shape on the bus).
        self._rehearsal: Rehearsal | None = None
        self._rehearsing = threading.Lock()
        # Armed stimuli play in one thread of their own, started once: starting a thread per
        # stimulus would hand it the interpreter for up to a switch interval (5 ms) while the
        # script's frame loop waited in `arm`.
        self._armed: queue.SimpleQueue[Armed | None] = queue.SimpleQueue()
        self._player: threading.Thread | None = None
        _open_arrays.add(self)
        # Let go of without close(): closed as it is collected (at the interpreter's exit,
        # `_close_left_open` closes those still open, cutting what plays).
        self._finalizer = weakref.finalize(self, _let_go, rig, self._asked)
        self._finalizer.atexit = False
        for warning in rig.warnings:
            log.warning("%s: %s", self._asked, warning)

    @property
    def protocol(self) -> Protocol:
        """The protocol the array was opened for."""
        return self._rig.protocol

    @property
    def url(self) -> str:
        """The serial device of real servos, or the ``sim://`` URL of the simulated array, as
        `open_array` was given it (``"sim://"`` when it was given neither)."""
        return self._asked

    @property
    def simulated(self) -> bool:
        """Whether the servos are simulated (nothing real moves)."""
        return is_simulated(self.url)

    @property
    def is_open(self) -> bool:
        """Whether the array is open (not closed yet)."""
        return self._safe_stop is None

    @property
    def warnings(self) -> tuple[str, ...]:
        """What the connection found worth saying (a USB adapter's latency timer, real-time
        priority refused, a servo response measured on another rig), one line each."""
        return tuple(self._rig.warnings)

    def now_ns(self) -> int:
        """The array's clock, in ns: the time line onsets are given and reported on."""
        return self._rig.clock.now_ns()

    def __repr__(self) -> str:
        current = self._current
        if not self.is_open:
            state = "closed"
        elif current is not None and not current.done:
            state = f"open, {current._described()} armed or playing"
        else:
            state = "open, idle"
        return f"<PinArray {self.url} for protocol {self.protocol.name!r}: {state}>"

    def prepare(self, stimulus: Presentable) -> None:
        """Compile and encode a stimulus ahead, so that presenting or arming it later costs
        the script nothing but the call (each stimulus is prepared once, on first use).

        Parameters
        ----------
        stimulus : PlannedTrial, Condition, Pattern, Frames or Wave
            As for `present`: checked in full here (a stimulus built in code, against this
            array's device).
        """
        self._trial(self._stimulus("prepare", stimulus))

    def present(self, stimulus: Presentable, *, at_ns: int | None = None) -> Delivery:
        """Play one stimulus and wait until it has played.

        Parameters
        ----------
        stimulus : PlannedTrial, Condition, Pattern, Frames or Wave
            A trial of the protocol's plan (`plan_trials`) or a condition of its design
            (`find_condition`). A trial of an adaptive design plays its condition as the
            protocol writes it: the values its procedures choose are `run_session`'s.
            Or a stimulus built in code: its pins numbered on this array's grid, and checked
            as a protocol's stimulus is (each pin's calibrated stroke and the servos' speed,
            no pin driven twice at once, the servo bus, a trial's pulses) before anything
            moves.
        at_ns : int or None
            The stimulus's time zero on the array's clock, in integer ns, at least `lead_ns`
            and at most a minute ahead; None: `lead_ns` after the call.

        Returns
        -------
        Delivery
            Its onset, what was presented (`Delivery.stimulus`), its delivery record and
            the strokes measured. A stimulus not delivered
            as scheduled (late, short, cut by `stop` from another thread) is returned
            (``delivered`` False, with the reason), not raised.

        Raises
        ------
        PlaybackAborted
            The bus failing mid-stimulus (the message says at which frame it stopped and how
            the pins were left: they were put to rest first).
        PinArrayError
            A condition the protocol does not hold, a stimulus built in code that this
            array cannot play as specified (saying why, the argument at fault named), an
            onset too soon or too far, another stimulus still armed, a closed array.
        """
        condition = self._stimulus("present", stimulus)
        with self._lock:
            self._check_idle("present")
            onset: Onset = (OnsetAfter(self.lead_ns) if at_ns is None else
                            OnsetAt(arguments.onset_ns("present", at_ns, self.now_ns(),
                                                       self.lead_ns)))
            armed = self._current = Armed(self, condition, onset)
        self._run(armed)
        return armed.result()

    def arm(self, stimulus: Presentable, *, at_ns: int | None = None) -> Armed:
        """Arm one stimulus and return at once; it plays in the background (on real servos,
        in the player process), at ``at_ns`` or when `Armed.start` is called.

        Parameters
        ----------
        stimulus : PlannedTrial, Condition, Pattern, Frames or Wave
            As for `present`.
        at_ns : int or None
            The stimulus's time zero on the array's clock, in integer ns, at least `lead_ns`
            and at most a minute ahead (on real servos ``time.monotonic_ns()``'s time line).
            None: armed to start on `Armed.start` (a screen flip as it happens).

        Returns
        -------
        Armed
            Its `Armed.result` is the `Delivery`, once it has ended. One that cannot start in
            time (the host stalled past its onset) ends as not delivered, nothing moved.

        Raises
        ------
        PinArrayError
            As for `present`, before anything is armed.
        """
        condition = self._stimulus("arm", stimulus)
        with self._lock:
            self._check_idle("arm")
            onset: Onset | StartCue = (StartCue() if at_ns is None else
                                       OnsetAt(arguments.onset_ns("arm", at_ns, self.now_ns(),
                                                                  self.lead_ns)))
            # Torque on again after a stop (one exchange of a few ms: the servos' own state
            # read back), here rather than in the lead time or after a flip's cue: the
            # stimulus starts when it is due. After a fault, the whole handshake: its error
            # is raised here, before anything is armed.
            self._rig.ready()
            armed = self._current = Armed(self, condition, onset)
            if self._player is None:
                # The thread holds the array weakly: an array let go of is still collected.
                self._player = threading.Thread(
                    target=_play_armed, args=(weakref.ref(self), self._armed), daemon=True,
                    name=f"pinarray: stimuli armed on {self.url}")
                self._player.start()
        self._armed.put(armed)
        return armed

    def stop(self) -> SafeStopReport:
        """Cut the stimulus armed or playing now (if any), then every pin to rest and torque
        off; returns once they are. The array stays open: the next stimulus turns torque on
        again. Safe from any thread.

        Returns
        -------
        SafeStopReport
            Which servos were confirmed at rest and released, and which did not answer.
        """
        with self._lock:
            self._check_open("stop")
            self._cut_current("stop()")
            return self._rig.rest_and_release()

    def close(self) -> SafeStopReport:
        """Cut a stimulus still armed or playing, then pins to rest, torque off, port closed
        (and let go: another opener may have it).

        Safe to call more than once; leaving the ``with`` block calls it, as does the
        interpreter's exit for an array still open.

        Returns
        -------
        SafeStopReport
            Which servos were confirmed at rest and released, and which did not answer.
        """
        return self._close("close()")

    def __enter__(self) -> PinArray:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self._close("leaving the with block" + (f" on {kind.__name__}" if kind else ""))

    # -- below the face -------------------------------------------------------------------

    def _close(self, by: str) -> SafeStopReport:
        with self._lock:
            if self._safe_stop is None:
                try:
                    self._cut_current(by)
                finally:
                    self._finalizer.detach()
                    self._safe_stop = self._rig.close()
                    _open_arrays.discard(self)
                    self._close_rehearsal()
                    self._armed.put(None)  # the thread playing armed stimuli ends
                log.info("%s: closed by %s: %s", self.url, by, self._safe_stop.describe())
            return self._safe_stop

    def _stimulus(self, call: str, stimulus: object) -> Stimulus:
        """What ``stimulus`` plays, once it is known to be safe to: a condition the protocol
        holds (checked when the protocol was read), or a stimulus built in code read against
        this array's device (`pinarray.protocol.in_code`)."""
        protocol = self.protocol
        match stimulus:
            case Pattern() | Frames() | Wave():
                if stimulus not in self._built:
                    what = f"{call}: {type(stimulus).__name__}"
                    drives = drives_on(protocol.device, what, code_stimulus(stimulus))
                    self._rehearse(what, drives)
                    self._built[stimulus] = drives
                return stimulus
            case Train():
                raise PinArrayError(f"{call}: stimulus: a Train plays on pins: present "
                                    "pinarray.Pattern(pins=[...], train=...) or a "
                                    "pinarray.Wave")
            case PlannedTrial(catch=True):
                raise PinArrayError(f"{protocol.source}: trial {stimulus.trial} is a catch trial "
                                    "of an adaptive design: run_session presents those")
            case PlannedTrial(condition=condition):
                pass
            case _ if isinstance(stimulus, Condition):
                condition = stimulus
            case _:
                arguments.refuse(call, "stimulus", "a planned trial or a condition of the "
                                 "protocol (pinarray.find_condition), or a stimulus built in "
                                 "code (pinarray.Pattern, Frames, Wave)", stimulus)
        if condition not in protocol.design.conditions:
            raise PinArrayError(f"{protocol.source}: {described(condition)} is not a "
                                "condition of the protocol's design: write it into the protocol "
                                "(find_condition names what it holds)")
        return condition

    def _rehearse(self, what: str, drives: tuple[PinDrive, ...]) -> None:
        """Refuse ``drives`` that the simulated array does not deliver (`pinarray.player.
        rehearsal`: what the analytic checks of `drives_on` cannot see, the servos'
        acceleration and lag, a stroke the verifier cannot sample), before anything moves."""
        with self._rehearsing:
            self._check_open(what.partition(":")[0])
            if self._rehearsal is None:
                self._rehearsal = Rehearsal()
            problem = self._rehearsal(drives, self.protocol.device)
        if problem is not None:
            raise PinArrayError(f"{what}: {problem}")

    def _close_rehearsal(self) -> None:
        with self._rehearsing:
            if self._rehearsal is not None:
                self._rehearsal.close()
                self._rehearsal = None

    def _trial(self, stimulus: Stimulus) -> PreparedTrial:
        trial = self._trials.get(stimulus)
        if trial is None:
            with self._preparing:
                trial = self._trials.get(stimulus)
                if trial is None:
                    protocol = self.protocol
                    drives = (trial_drives(protocol, stimulus) if isinstance(stimulus, Condition)
                              else self._built[stimulus])
                    schedule = compile_drives(drives, protocol.device)
                    trial = self._trials[stimulus] = self._rig.prepare(schedule)
        return trial

    def _check_open(self, call: str) -> None:
        if self._safe_stop is not None:
            raise PinArrayError(f"{call}: {self.url}: the array is closed")

    def _check_idle(self, call: str) -> None:
        self._check_open(call)
        current = self._current
        if current is not None and not current.done:
            raise PinArrayError(f"{call}: the stimulus {current._described()} has not ended: "
                                "wait for its result or cancel it first (one stimulus "
                                "plays at a time)")

    def _run(self, armed: Armed) -> None:
        """Play ``armed`` in this thread and hand its outcome to whoever waits for it."""
        armed._runner = threading.get_ident()
        try:
            armed._future.set_result(self._play(armed))
        except BaseException as error:  # handed to whoever asks for the result
            armed._future.set_exception(error)

    def _play(self, armed: Armed) -> Delivery:
        condition = armed._stimulus
        what = described(condition)
        trial = self._trial(condition)
        rig = self._rig
        planned_ns = armed.onset_ns if armed.onset_ns is not None else self.now_ns()
        try:
            if armed._cut is not None:
                raise Stopped(f"cut short by {armed._cut.by}")
            presentation = rig.play(trial, onset=armed._onset)
        except Stopped as stopped:
            return self._cut_short(armed, trial, planned_ns, what,
                                   armed._cut or Cut(self.now_ns(), _stopped_by(stopped)))
        except Suspended as suspended:  # real servos: the player process cut it
            return self._cut_short(armed, trial, planned_ns, what,
                                   armed._cut or Cut(suspended.noticed_ns, SUSPENSION))
        except OnsetPassed as passed:
            why = (f"its onset had passed {passed.late_ns / 1e6:.1f} ms before playback could "
                   "begin (the host was busy): nothing moved")
            log.warning("%s: %s: %s", self.url, what, why)
            return unplayed(planned_ns, trial.end_ns, len(trial.changes), rig.tolerance_ns,
                            NotStarted(why), why, what)
        except PlaybackAborted as aborted:
            log.error("%s: %s: %s", self.url, what, aborted)
            if type(aborted) is PlaybackAborted:
                raise
            raise PlaybackAborted(str(aborted), aborted.safe_stop) from None  # the public class
        # The delivery carries what a script needs; the rig need not keep every stimulus's
        # frames and samples for as long as the script runs.
        report = rig.reports.pop()
        delivery = Delivery(presentation.onset_ns, trial.end_ns, onset_write_late_ns(report),
                            presentation.delivery, stimulus=what)
        tell(self.url, what, delivery, report)
        return delivery

    def _cut_short(self, armed: Armed, trial: PreparedTrial, planned_ns: int, what: str,
                   cut: Cut) -> Delivery:
        """The delivery of the stimulus ``what``, ``cut``: `Cut` if it had begun by then, else
        `NotStarted` (nothing moved)."""
        rig = self._rig
        if armed._began(cut.at_ns, rig.last_from_ns):
            delivery = unplayed(planned_ns, trial.end_ns, len(trial.changes), rig.tolerance_ns,
                                cut, f"cut short by {cut.by}", what)
        else:
            delivery = unplayed(planned_ns, trial.end_ns, len(trial.changes), rig.tolerance_ns,
                                NotStarted(f"cancelled by {cut.by} before it started"),
                                f"cancelled by {cut.by} before it started: nothing moved", what)
        log.warning("%s: %s: %s", self.url, what, delivery.problem)
        return delivery

    def _cut_current(self, by: str) -> None:
        """Cut the stimulus armed or playing (holding the lock): it ends, pins to rest and
        torque off, before this returns (unless it plays in this very thread)."""
        armed = self._current
        if armed is None or armed.done:
            return
        armed._cut = Cut(self.now_ns(), by)
        if isinstance(armed._onset, StartCue):
            armed._onset.withdraw()
        rig = self._rig
        rig.stop.request(f"cut short by {by}")
        try:
            if armed._runner != threading.get_ident():
                armed._future.exception()  # until it has ended; its outcome stays with it
        finally:
            rig.stop.clear()

    def _cancel(self, armed: Armed) -> None:
        with self._lock:
            if self._current is armed and not armed.done:
                self._cut_current("cancel()")
                self._rig.rest_and_release()


def open_array(protocol: Protocol | None = None, *, port: str | None = None,
               sim: str | None = None, clock: Clock | None = None) -> PinArray:
    """Connect the protocol's pin array: real servos on ``port``, or simulated ones.

    The port is held for this array until it is closed: any other opener, in this script or
    another process, is refused, naming the holder. Every servo of the protocol's device is
    pinged first (all missing ones named in one error), then the pins go to rest holding
    torque. Use it as a context manager: leaving the block cuts a stimulus still playing,
    rests the pins and switches torque off however the block ends.

    Parameters
    ----------
    protocol : Protocol or None
        From `load_protocol` or `protocol_from_text`: its device section says which servos,
        their calibration (the limits no command leaves) and the delivery tolerance; the
        pins of a stimulus built in code are numbered on its grid and checked against its
        servos. None: simulated bus servos with pinarray's default device (the 4x4 grid,
        STS3215 servos, the seed's calibration), for stimuli built in code; real servos
        always need the protocol that calibrates them.
    port : str or None
        A serial device of real bus servos (``/dev/ttyUSB0``), or the I2C bus of a PWM board
        (``/dev/i2c-1``).
    sim : str or None
        A ``sim://`` URL of simulated servos, faults included (``sim://?drop=0.01&seed=3``,
        ``sim://?speed=1500``, ``sim://?vanish_after=400``; ``sim://pca9685?...`` for a PWM
        board). With neither ``port`` nor ``sim``: the simulated array, as ``pinarray play``.
    clock : Clock or None
        The clock stimuli play on (None: real time on real servos, virtual time on simulated
        ones, where a 10 s stimulus plays in a fraction of a second). Real servos take only
        real time (`MonotonicClock`).

    Returns
    -------
    PinArray
        Connected, pins at rest.

    Raises
    ------
    PortInUse
        Another array holds the port (in this script or another process), named.
    BusError
        Servos missing or failing, naming their ids and registers; a port that cannot be
        opened.
    PinArrayError
        A wrong argument (named), both a port and a sim URL, a URL that cannot be read, a
        clock real servos cannot play on, or a port without a protocol.
    """
    from pinarray.hardware.pca9685.sim import is_shared_board_url

    call = "open_array"
    if protocol is None:
        if port is not None:
            raise PinArrayError(f"{call}: {port}: real servos need the protocol that calibrates "
                                "them (its device section: servo ids, rest, limits): give one "
                                "(pinarray.load_protocol or pinarray.protocol_from_text)")
        protocol = default_protocol()
    protocol = arguments.protocol(call, protocol)
    port = arguments.port(call, port)
    sim = arguments.sim_for(call, protocol, sim)
    clock = arguments.clock(call, clock)
    if port is not None and sim is not None:
        raise PinArrayError(f"{call}: give a port (real servos) or a sim URL, not both")
    if clock is None:
        clock = choose_clock(port, None, paced=True, sim_url=sim)
    elif (port is not None or is_shared_board_url(sim)) and not isinstance(clock, MonotonicClock):
        raise PinArrayError(f"{call}: {port or sim}: real servos play in real time: give no "
                            "clock, or a MonotonicClock")
    try:
        rig = Rig(protocol, port, sim, clock,
                  holder=f"an array of protocol {protocol.name!r} (pinarray.open_array)")
    except OSError as error:  # EMFILE (the script's files at their limit) and the like
        raise PinArrayError(f"{call}: {port or sim or 'sim://'}: cannot be opened: "
                            f"{error.strerror or error}") from None
    return PinArray(rig, port or sim or "sim://")


def _stopped_by(stopped: Stopped) -> str:
    """What cut a stimulus the script did not cut (by stop(), cancel() or close()): a signal
    sent to the player process itself."""
    if stopped.signal_number:
        return f"{signal_name(stopped.signal_number)} sent to the player process"
    return str(stopped) or "a stop"


def _play_armed(array_ref: weakref.ref[PinArray], armed_queue: queue.SimpleQueue[Armed | None]
                ) -> None:
    """The thread playing an array's armed stimuli, in turn, until it closes."""
    while (armed := armed_queue.get()) is not None:
        array = array_ref()  # alive: the stimulus armed holds it
        if array is None:
            return
        array._run(armed)
        del array, armed  # not held while waiting: the script may let go of the array


def _let_go(rig: Rig, url: str) -> None:
    """An array the script let go of without closing it, collected: closed now (pins to rest,
    torque off, its port free for the next opener)."""
    if rig.forked_away:
        return  # a forked copy's: the original closes it
    try:
        report = rig.close()
    except Exception:  # a finalizer has nobody to raise to
        log.exception("%s: closing an array let go of without close() failed", url)
        return
    log.info("%s: closed as the script let go of it without close(): %s", url,
             report.describe())


@atexit.register
def _close_left_open() -> None:
    """An array a script left open is closed as it ends: a stimulus still armed is cut."""
    for array in list(_open_arrays):
        try:
            array._close("the script's end")
        except Exception:  # one array's failure must not keep the others' torque on
            log.exception("%s: closing at the script's end failed", array.url)


# A forked copy of the script closes none of its arrays as it ends: they are the script's.
os.register_at_fork(after_in_child=_open_arrays.clear)
