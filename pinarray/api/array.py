"""An open pin array for scripts: present a stimulus now or armed for a time, learn what was
delivered.

`open_array` connects the protocol's array (real servos on a port, or the simulated array) as
``pinarray play`` does: every servo pinged, all missing ones named at once, the pins to rest.
Leaving its ``with`` block is the safe stop on every way out (the end of the block, an error,
Ctrl-C): a stimulus still playing is cut short, then the pins go to rest and torque off. On
real servos the stimuli play in a player process of their own, which also rests the pins if
the script's process is killed outright.

Times are integer nanoseconds on the array's clock (`PinArray.now_ns`): on real servos that
is ``time.monotonic_ns()`` (CLOCK_MONOTONIC, the clock PsychoPy's flips are stamped on under
Linux); on the simulated array, virtual time unless the script gives a clock.
"""

from __future__ import annotations

import threading
from concurrent.futures import Future
from dataclasses import dataclass
from types import TracebackType

import numpy as np

from pinarray.api.protocols import describe_condition
from pinarray.clock import Clock, MonotonicClock, VirtualClock
from pinarray.errors import PinArrayError
from pinarray.hardware.delivery import DeliveryRecord
from pinarray.hardware.driver import SafeStopReport
from pinarray.hardware.motion import PinStroke
from pinarray.plan import PlannedTrial
from pinarray.player.playback import DEFAULT_LEAD_NS, Onset, OnsetAfter, OnsetAt, PlaybackReport
from pinarray.player.rig import Rig, choose_clock
from pinarray.protocol.drives import trial_drives
from pinarray.protocol.model import Condition, Protocol, is_simulated
from pinarray.schedule import TrialSchedule, compile_drives

__all__ = ["Armed", "Clock", "Delivery", "DeliveryRecord", "MonotonicClock", "PinArray",
           "PinStroke", "Presentable", "SafeStopReport", "VirtualClock", "open_array"]

Presentable = PlannedTrial | Condition
"""What `PinArray.present` plays: a trial of the protocol's plan, or one of its conditions."""


@dataclass(frozen=True)
class Delivery:
    """What one presentation delivered.

    Attributes
    ----------
    onset_ns : int
        The stimulus's time zero on the array's clock (`PinArray.now_ns`), in ns: the time
        it was armed for, or the lead after the call for one presented at once. Every goal
        change of the schedule is due at this plus its own time.
    duration_ns : int
        The stimulus's length as scheduled, in ns.
    onset_write_late_ns : int
        How late the write of the stimulus's first frame (at or after time zero) returned
        after its deadline, in ns: the host's side of the onset (0 for a stimulus without
        frames).
    record : DeliveryRecord
        What reached the servos: goal changes scheduled, confirmed as sent, healed (written
        again, then confirmed), missing; the latest any arrived; the protocol's tolerance; and
        the moving pins' measured strokes where the servos report their positions.
    """

    onset_ns: int
    duration_ns: int
    onset_write_late_ns: int
    record: DeliveryRecord

    @property
    def delivered(self) -> bool:
        """Delivered as scheduled and specified: every goal change reached its servo within
        the protocol's tolerance, and, where the servos report their positions, every moving
        pin was measured in every cycle and made its stroke."""
        return self.record.delivered

    @property
    def problem(self) -> str:
        """Empty when delivered; otherwise the first thing that went wrong, in plain words."""
        return self.record.problem

    @property
    def strokes(self) -> tuple[PinStroke, ...]:
        """Each moving pin's measured stroke (empty where the servos report no position:
        hobby PWM servos)."""
        return () if self.record.strokes is None else self.record.strokes.pins

    def stroke(self, pin: int) -> PinStroke:
        """The measured stroke of ``pin``.

        Raises
        ------
        PinArrayError
            When the pin did not move in this stimulus or its motion was not measured.
        """
        for stroke in self.strokes:
            if stroke.pin == pin:
                return stroke
        moved = ", ".join(str(s.pin) for s in self.strokes) or "none"
        raise PinArrayError(f"pin {pin}: no stroke measured in this stimulus (pins measured: "
                            f"{moved})")


class Armed:
    """A stimulus armed to start at `onset_ns`: it plays in the background while the script
    goes on (draws a frame, flips a screen); `result` waits for what it delivered.

    Made by `PinArray.arm`.
    """

    def __init__(self, onset_ns: int) -> None:
        self._onset_ns = onset_ns
        self._future: Future[Delivery] = Future()

    @property
    def onset_ns(self) -> int:
        """The time zero it is armed for, on the array's clock, in ns."""
        return self._onset_ns

    @property
    def done(self) -> bool:
        """Whether it has ended (played, or failed: `result` then raises)."""
        return self._future.done()

    def result(self, timeout_s: float | None = None) -> Delivery:
        """Wait until the stimulus has played; what it delivered.

        Parameters
        ----------
        timeout_s : float or None
            Wait at most this long, in seconds of the host's time (None: until it ends).

        Raises
        ------
        PinArrayError
            What stopped it (the bus failed, the array closed first), or a wait that timed out.
        """
        try:
            return self._future.result(timeout_s)
        except TimeoutError:
            raise PinArrayError(f"the stimulus armed for {self.onset_ns} ns has not ended "
                                f"after {timeout_s} s") from None

    def _play(self, play: _Play) -> None:
        try:
            self._future.set_result(play())
        except BaseException as error:  # handed to whoever asks for the result
            self._future.set_exception(error)


class _Play:
    """One stimulus to play on a rig (what `Armed` runs in its thread)."""

    def __init__(self, array: PinArray, schedule: TrialSchedule, onset: Onset) -> None:
        self.array, self.schedule, self.onset = array, schedule, onset

    def __call__(self) -> Delivery:
        return self.array._play(self.schedule, self.onset)


class PinArray:
    """A connected pin array for one protocol: `open_array` makes one.

    One stimulus plays at a time; between stimuli the pins hold at rest.
    """

    lead_ns: int = DEFAULT_LEAD_NS
    """How far ahead of the array's clock a stimulus is armed at least, in ns; a stimulus
    presented at once starts this long after the call."""

    def __init__(self, rig: Rig) -> None:
        self._rig = rig
        self._armed: Armed | None = None
        self._safe_stop: SafeStopReport | None = None

    @property
    def protocol(self) -> Protocol:
        """The protocol the array was opened for."""
        return self._rig.protocol

    @property
    def url(self) -> str:
        """The serial device of real servos, or the ``sim://`` URL of the simulated array."""
        return self._rig.url

    @property
    def simulated(self) -> bool:
        """Whether the servos are simulated (nothing real moves)."""
        return is_simulated(self.url)

    @property
    def warnings(self) -> tuple[str, ...]:
        """What the connection found worth saying (a USB adapter's latency timer, real-time
        priority refused, a servo response measured on another rig), one line each."""
        return tuple(self._rig.warnings)

    def now_ns(self) -> int:
        """The array's clock, in ns: the time line onsets are given and reported on."""
        return self._rig.clock.now_ns()

    def present(self, stimulus: Presentable, *, at_ns: int | None = None) -> Delivery:
        """Play one stimulus and wait until it has played.

        Parameters
        ----------
        stimulus : PlannedTrial or Condition
            A trial of the protocol's plan (`plan_trials`) or a condition of its design
            (`find_condition`). A trial of an adaptive design plays its condition as the
            protocol writes it: the values its procedures choose are `run_session`'s.
        at_ns : int or None
            The stimulus's time zero on the array's clock, in ns, at least `lead_ns` ahead;
            None: `lead_ns` after the call.

        Returns
        -------
        Delivery
            Its onset, its delivery record and the strokes measured. A stimulus not delivered
            as scheduled is returned (``delivered`` False, with the reason), not raised.

        Raises
        ------
        PinArrayError
            A stimulus the protocol does not hold, an onset too soon, another stimulus still
            armed, a closed array, or the bus failing mid-stimulus (the message says at which
            frame it stopped and how the pins were left: they were put to rest first).
        """
        schedule = self._schedule(stimulus)
        onset = self._onset(at_ns)
        self._check_idle()
        return self._play(schedule, onset)

    def arm(self, stimulus: Presentable, *, at_ns: int) -> Armed:
        """Arm one stimulus to start at ``at_ns`` and return at once; it plays in the
        background (on real servos, in the player process).

        Parameters
        ----------
        stimulus : PlannedTrial or Condition
            As for `present`.
        at_ns : int
            The stimulus's time zero on the array's clock, in ns, at least `lead_ns` ahead
            (a screen flip's time, on real servos ``time.monotonic_ns()``'s time line).

        Returns
        -------
        Armed
            Its `Armed.result` is the `Delivery`, once it has played.
        """
        schedule = self._schedule(stimulus)
        onset = self._onset(at_ns)
        self._check_idle()
        armed = self._armed = Armed(at_ns)
        threading.Thread(target=armed._play, args=(_Play(self, schedule, onset),),
                         name=f"pinarray stimulus at {at_ns} ns", daemon=True).start()
        return armed

    def close(self) -> SafeStopReport:
        """Wait for a stimulus still armed, then pins to rest, torque off, port closed.

        Safe to call more than once; leaving the ``with`` block calls it (after an error it
        first cuts a playing stimulus short).

        Returns
        -------
        SafeStopReport
            Which servos were confirmed at rest and released, and which did not answer.
        """
        if self._safe_stop is None:
            armed = self._armed
            if armed is not None:
                armed._future.exception()  # its outcome stays with whoever holds it
            self._safe_stop = self._rig.close()
        return self._safe_stop

    def __enter__(self) -> PinArray:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 traceback: TracebackType | None) -> None:
        if kind is not None:
            self._rig.stop.request(f"the script stopped: {kind.__name__}")
        self.close()

    # -- below the face -------------------------------------------------------------------

    def _schedule(self, stimulus: Presentable) -> TrialSchedule:
        """The stimulus compiled, once it is known to be one the protocol holds (and so was
        checked when the protocol was read)."""
        protocol = self.protocol
        match stimulus:
            case PlannedTrial(catch=True):
                raise PinArrayError(f"{protocol.source}: trial {stimulus.trial} is a catch trial "
                                    "of an adaptive design: run_session presents those")
            case PlannedTrial(condition=condition):
                pass
            case _ if isinstance(stimulus, Condition):
                condition = stimulus
            case _:
                raise PinArrayError(f"expected a planned trial or a condition of the protocol, "
                                    f"found {type(stimulus).__name__}")
        if condition not in protocol.design.conditions:
            raise PinArrayError(f"{protocol.source}: {describe_condition(condition)} is not a "
                                "condition of the protocol's design: write it into the protocol "
                                "(find_condition names what it holds)")
        return compile_drives(trial_drives(protocol, condition), protocol.device)

    def _onset(self, at_ns: int | None) -> Onset:
        if at_ns is None:
            return OnsetAfter(self.lead_ns)
        now_ns = self.now_ns()
        if at_ns - now_ns < self.lead_ns:
            raise PinArrayError(f"a stimulus armed for {at_ns} ns is {(at_ns - now_ns) / 1e6:.1f} "
                                f"ms ahead of the array's clock ({now_ns} ns): arm it at least "
                                f"{self.lead_ns / 1e6:g} ms ahead")
        return OnsetAt(at_ns)

    def _check_idle(self) -> None:
        if self._safe_stop is not None:
            raise PinArrayError(f"{self.url}: the array is closed")
        armed = self._armed
        if armed is not None and not armed.done:
            raise PinArrayError(f"a stimulus is armed for {armed.onset_ns} ns: wait for its "
                                "result first (one stimulus plays at a time)")

    def _play(self, schedule: TrialSchedule, onset: Onset) -> Delivery:
        presentation = self._rig.present(schedule, onset=onset)
        # The delivery below carries what a script needs; the rig need not keep every
        # stimulus's frames and samples for as long as the script runs.
        report = self._rig.reports.pop()
        return Delivery(presentation.onset_ns, schedule.end_ns, _onset_write_late_ns(report),
                        presentation.delivery)


def _onset_write_late_ns(report: PlaybackReport) -> int:
    """How late the write of the first frame at or after time zero returned, in ns."""
    at_or_after = np.flatnonzero(report.scheduled_ns >= 0)
    if not len(at_or_after):
        return 0
    first = int(at_or_after[0])
    return int(report.sent_ns[first] - report.scheduled_ns[first])


def open_array(protocol: Protocol, *, port: str | None = None, sim: str | None = None,
               clock: Clock | None = None) -> PinArray:
    """Connect the protocol's pin array: real servos on ``port``, or simulated ones.

    Every servo of the protocol's device is pinged first (all missing ones named in one
    error), then the pins go to rest holding torque. Use it as a context manager: leaving the
    block rests the pins and switches torque off however the block ends.

    Parameters
    ----------
    protocol : Protocol
        From `load_protocol`: its device section says which servos, their calibration and
        the delivery tolerance.
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
    BusError
        Servos missing or failing, naming their ids and registers.
    PinArrayError
        Both a port and a sim URL, a URL that cannot be opened, or a clock real servos
        cannot play on.
    """
    from pinarray.hardware.pca9685.sim import is_shared_board_url

    if port is not None and sim is not None:
        raise PinArrayError("open_array: give a port (real servos) or a sim URL, not both")
    if clock is None:
        clock = choose_clock(port, None, paced=True, sim_url=sim)
    elif (port is not None or is_shared_board_url(sim)) and not isinstance(clock, MonotonicClock):
        raise PinArrayError(f"{port or sim}: real servos play in real time: give no clock, or a "
                            "MonotonicClock")
    return PinArray(Rig(protocol, port, sim, clock))
