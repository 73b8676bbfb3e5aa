"""The stimulator a session drives: a connected array (real or simulated) and its clock.

The array is whatever `pinarray.player.families.open_array` opens for the protocol's device,
seen only through the `ArrayDriver` seam.

One place decides hardware vs simulation, real vs virtual time, and where the deadline loop
runs: on a serial device (real servos, or simulated ones behind a pseudo-terminal) it runs in
a player process of its own at real-time priority (`pinarray.player.process`); on the
in-process simulator, in virtual or scaled time, it runs here. Markers (LSL) are announced by
whoever plays: the rig opens its marker stream once, in the player process or here. However a
`Rig` is left (normal close, exception, a stop request), pins go to rest and torque goes off
where the bus still answers.

One owner per port: a rig on a device holds it (`pinarray.hardware.port_lock`) from before
it opens it until it is closed, and its player process keeps it held while it may still
drive the servos; any other opener is refused, naming the holder.

Past 400 lines on purpose: one connected array and every use of it that must take its port in
turn (a stimulus now, at a time or on a cue; a test pin; the timing check; telemetry; the
stop and the close).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from typing import TYPE_CHECKING, overload

from pinarray.clock import Clock, MonotonicClock, PacedClock, ScaledClock, VirtualClock
from pinarray.errors import Interrupted, PinArrayError
from pinarray.hardware.delivery import PreparedTrial, Presentation
from pinarray.hardware.driver import ArrayDriver, SafeStopReport, Telemetry
from pinarray.hardware.port_lock import PortLock, hold_port
from pinarray.player.families import board_refusals, open_array
from pinarray.player.forks import FORKED_COPY, blank_descriptors, let_go_in_forks
from pinarray.player.markers import Announcer, Announcers, TrialMarkers
from pinarray.player.playback import (
    SOON,
    Onset,
    OnsetAfter,
    OnsetAt,
    OnsetPassed,
    PlaybackReport,
    Suspended,
    play_prepared,
    prepare_trial,
)
from pinarray.player.simulators import SimulatedArrays
from pinarray.player.timing import (
    CHECK_SLICE_NS,
    DEFAULT_PERIOD_NS,
    CheckSkipped,
    PortFigures,
    Verdict,
    WakeUps,
    duration_for,
    judge,
)
from pinarray.protocol import NS_PER_S, Protocol
from pinarray.protocol.model import is_simulated
from pinarray.protocol.response import MeasuredResponse
from pinarray.schedule import TrialSchedule
from pinarray.stop import StoppableClock, Stopped, StopRequest

if TYPE_CHECKING:
    from pinarray.player.process import PlayerProcess, StartCue

# How often a stimulus waiting for its cue on the in-process simulator looks at the stop, in s.
CUE_WATCH_S = 0.02


def choose_clock(port: str | None, time_scale: float | None, *, paced: bool = False,
                 sim_url: str | None = None) -> Clock:
    """Real servos run in real time; simulated ones in virtual time (scale 0/None) or scaled.

    ``sim_url``: simulated boards kept in a state file (``sim://pca9685?state=FILE``) are
    shared with the player process as real ones are, so they run in real time too.

    ``paced``: a scaled simulation for a scripted run, in simulated time that only moves
    while something waits (`PacedClock`), so the host's own delays cannot make a stimulus
    late; without it (the UI, where a person answers), scaled wall-clock time.
    """
    if port or (sim_url is not None and _is_shared_board_url(sim_url)):
        if time_scale not in (None, 1.0):
            what = "real servos play" if port else "a board kept in a state file plays"
            raise PinArrayError(f"{what} in real time: --speed must be 1")
        return MonotonicClock()
    if not time_scale:
        return VirtualClock()
    return PacedClock(time_scale) if paced else ScaledClock(time_scale)


def _is_shared_board_url(url: str) -> bool:
    # Imported only for a simulated array: real servos' start-up does not load the simulator.
    from pinarray.hardware.pca9685.sim import is_shared_board_url

    return is_shared_board_url(url)


class Rig:
    """A connected pin array for one protocol's device.

    Parameters
    ----------
    protocol : Protocol
        Its device section gives servo ids, rest positions, limits, speed, baud rate and the
        delivery tolerance.
    port : str or None
        A serial device of real servos; None for the simulator.
    sim_url : str or None
        A ``sim://`` URL (faults etc.) when ``port`` is None.
    clock : Clock
        The bus's clock; `Rig.clock` wraps it so that waits end on a stop request.
    stop : StopRequest, optional
        Set by the composition root (signals, the UI's quit); playback and the session's
        waits end at their next look at it.
    isolate : bool or None
        Play in a player process of its own (None: whenever the port is a device).
    realtime : bool
        Ask for real-time priority in the player process.
    wire_log : str or None
        A file for every message on the wire as a logic analyser decodes it (PWM boards).
    simulators : SimulatedArrays, optional
        Simulated arrays kept from earlier connections in this program: the simulated servos
        are the ones the last connection to the same URL left (None: factory-new ones).
    markers : Announcers, optional
        A marker stream (LSL), opened once where trials play (the player process, or here)
        and kept until the rig closes; each `present` given markers announces them at its
        onset and end. Stimuli then play on the wall clock (`keep_wall_time`).
    holder : str
        Who holds the port, in words another opener is told ("pinarray play", "an array of
        protocol 'x'"); empty: the protocol's array.
    """

    def __init__(self, protocol: Protocol, port: str | None, sim_url: str | None, clock: Clock,
                 stop: StopRequest | None = None, *, isolate: bool | None = None,
                 realtime: bool = True, wire_log: str | None = None,
                 simulators: SimulatedArrays | None = None, markers: Announcers | None = None,
                 holder: str = ""):
        self.protocol = protocol
        self.stop = stop or StopRequest()
        self.bus_clock = clock
        self.clock = StoppableClock(clock, self.stop)
        # The protocol's own tolerance everywhere: on the in-process simulator a stimulus
        # plays in the simulator's own time (see `_present`), where the host's delays cost
        # nothing, at any --speed.
        self.tolerance_ns = protocol.device.delivery_tolerance_ns
        self.stroke_tolerance = protocol.device.stroke_tolerance
        refusals = board_refusals(protocol)  # before any port is opened: nothing touched
        if refusals:
            others = len(refusals) - 1
            more = (f" (and {others} more {'stimulus' if others == 1 else 'stimuli'}: "
                    "`pinarray validate` lists them)" if others else "")
            raise PinArrayError(f"{protocol.source}: {refusals[0]}{more}")
        # Held before it is opened (nothing is sent to a port another array drives), until
        # the rig and its player process have let it go.
        self._port_lock: PortLock | None = None
        if port is not None:
            self._port_lock = hold_port(port, holder or f"an array of protocol {protocol.name!r}")
        try:
            self.bus: ArrayDriver = open_array(protocol.device, port, sim_url, clock, wire_log,
                                               simulators)
        except BaseException:
            self._let_port_go()
            raise
        self.setup = self.bus.setup
        self.url = self.bus.port_name
        try:
            self.bus.check_servos()  # reads only: nothing moves, no torque yet
        except BaseException:
            self.bus.close()
            self._let_port_go()
            raise
        self.warnings = list(self.bus.warnings)
        bandwidth = protocol.device.bandwidth
        if isinstance(bandwidth, MeasuredResponse) and (
                is_simulated(bandwidth.port) != is_simulated(self.url)):
            def where(port: str) -> str:
                return f"the simulator ({port})" if is_simulated(port) else port

            self.warnings.append(
                f"feasibility follows the {bandwidth.describe()}, measured on "
                f"{where(bandwidth.port)}, not on {where(self.url)}: measure these servos "
                "(`pinarray servos response`)")
        self.reports: list[PlaybackReport] = []
        # What kept a trial's markers from going out, one entry per trial that had a problem.
        self.marker_problems: list[str] = []
        self.markers = markers
        self._announcer: Announcer | None = None  # the stream, when trials play here
        # One user of the port at a time: the UI may test a pin while a timing check runs.
        self._port = threading.RLock()
        self._released = False
        # The last safe stop's report while the servos are known to be at rest and released
        # since (nothing sent after it): a stop after a stop need not make another.
        self._safe: SafeStopReport | None = None
        # The stimulus playing now: its time zero on the rig's clock (None: none is playing).
        self._playing_from_ns: int | None = None
        # The time zero of the last stimulus played (or begun), kept after it ended: whether
        # a stimulus cut at some moment had begun by then.
        self.last_from_ns: int | None = None
        self._forked_away = False  # True in a forked copy of the process that opened it
        self._wall_time = markers is not None  # see `keep_wall_time`
        self._fd = self.bus.descriptor
        self._isolate = self._fd is not None if isolate is None else isolate
        self._realtime = realtime
        self.player: PlayerProcess | None = None
        let_go_in_forks(self)
        try:
            if self._isolate:
                # The player process guards the servos before torque comes on: if this process
                # is killed at any moment from here, it rests the pins and releases torque.
                self._start_player()
                if self.player is not None and self.player.realtime_problem:
                    self.warnings.append(self.player.realtime_problem)
            elif markers is not None:
                self._announcer = markers.open(clock)
            self.bus.hold()
            self.bus.move_to_rest()
        except BaseException:
            self.close()  # torque may be on: nobody else holds this rig to release it
            raise

    @property
    def forked_away(self) -> bool:
        """Whether this is a forked copy of the process that opened the rig (which alone
        drives it)."""
        return self._forked_away

    @property
    def isolated(self) -> bool:
        """Whether trials play in a player process of their own."""
        return self.player is not None

    def _start_player(self) -> None:
        from pinarray.player.process import PlayerProcess

        if self._fd is None:
            raise PinArrayError(f"{self.url}: a player process needs a serial device")
        lock_fd = self._port_lock.fd if self._port_lock is not None else -1
        try:
            self.player = PlayerProcess(self.bus, self._fd, self.stop, realtime=self._realtime,
                                        markers=self.markers,
                                        keep_fds=(lock_fd,) if lock_fd >= 0 else ())
        except OSError as error:  # what it made is closed again (EMFILE: no file left to open)
            raise PinArrayError(f"{self.url}: the player process could not be started: "
                                f"{error.strerror or error}") from None

    def present(self, schedule: TrialSchedule, markers: TrialMarkers | None = None, *,
                onset: Onset = SOON) -> Presentation:
        """Play one trial; the pins then hold at rest.

        Returns its onset (clock ns) and `DeliveryRecord`; a stimulus not delivered as
        scheduled is returned, not raised (the session marks the trial invalid). ``markers``
        are announced on the rig's marker stream, if it has one; one that could not be sent
        is added to `marker_problems`, never raised. ``onset``: the trial's time zero, a lead
        after the call or a time on the rig's clock (a stimulus a script armed).
        """
        return self.play(self.prepare(schedule), markers, onset=onset)

    def prepare(self, schedule: TrialSchedule) -> PreparedTrial:
        """The trial's frames encoded for this array (a stimulus prepared once can be played
        many times: the frames do not depend on what was played before)."""
        return prepare_trial(self.bus, schedule.targets, schedule.pulses)

    def play(self, trial: PreparedTrial, markers: TrialMarkers | None = None, *,
             onset: Onset | StartCue = SOON) -> Presentation:
        """`present` for a prepared trial; ``onset`` a `StartCue`: held ready and started the
        moment the cue is given (its time zero is then, as measured). A stop request ends it
        with `Stopped`, whose ``safe_stop`` tells how the pins were left (None: nothing had
        moved)."""
        with self._port:
            return self._present(trial, markers, onset)

    def ready(self) -> None:
        """Ready to play: the player process running, torque on (after a fault or a stop
        released it, the driver turns it back on: `ArrayDriver.reconnect`, on bus servos a
        few exchanges of the whole bus, the handshake only where they fall short). `present`
        does this first; `PinArray.arm` before it returns, its onset checked."""
        if self._forked_away:  # its player would seem dead, and a new one find no port
            raise PinArrayError(FORKED_COPY)
        with self._port:
            if self.player is not None:
                self.player.settle()  # a stimulus an interruption cut: its answer taken
            if self.player is not None and not self.player.alive:
                # Started again before torque can come back on, so that it guards it. (A
                # Ctrl-C between the two leaves the dead one in place, isolated still: its
                # close is done once, however often it is asked for.)
                self.player.close()
                self._start_player()
            if self._released:
                self.bus.reconnect()
                self._released = False
                self._safe = None

    def _present(self, trial: PreparedTrial, markers: TrialMarkers | None,
                 onset: Onset | StartCue) -> Presentation:
        self.last_from_ns = None
        self.ready()
        self._safe = None
        match onset:
            case OnsetAt(onset_ns=onset_ns):
                self._playing_from_ns = onset_ns
            case OnsetAfter(lead_ns=lead_ns):
                self._playing_from_ns = self.clock.now_ns() + lead_ns
        self.last_from_ns = self._playing_from_ns
        try:
            if self.player is not None:
                report = self.player.play(trial, onset=onset, tolerance_ns=self.tolerance_ns,
                                          markers=markers, stroke_tolerance=self.stroke_tolerance)
            else:
                if not isinstance(onset, OnsetAt | OnsetAfter):
                    self._wait_for(onset)
                    onset = OnsetAfter(0)  # at once: the time zero is when the cue came
                with self._own_time():
                    report = play_prepared(self.bus, trial, self.clock, onset=onset,
                                           tolerance_ns=self.tolerance_ns, release_at_end=False,
                                           markers=markers, announcer=self._announcer,
                                           stroke_tolerance=self.stroke_tolerance)
        except OnsetPassed:
            raise  # refused before anything was sent: the pins hold at rest as they were
        except BaseException as error:
            # However it ended (a fault, a stop, Ctrl-C), the player made the pins safe on
            # its way out: the next stimulus turns torque on again through the handshake.
            self._released = True
            if isinstance(error, Interrupted | Suspended) and isinstance(error.safe_stop,
                                                                          SafeStopReport):
                self._safe = error.safe_stop
            raise
        finally:
            self._playing_from_ns = None
        self.reports.append(report)
        if report.marker_problem:
            self.marker_problems.append(report.marker_problem)
        return Presentation(report.onset_ns, report.delivery, report.trace)

    def _wait_for(self, cue: StartCue) -> None:
        """Until ``cue`` is given; a stop (or the cue withdrawn) ends the wait with `Stopped`."""
        while not cue.wait(CUE_WATCH_S):
            self.stop.raise_if_requested()
        if cue.withdrawn:
            raise Stopped(self.stop.reason or "withdrawn before it started")
        self.stop.raise_if_requested()

    def rest_and_release(self) -> SafeStopReport:
        """Every pin to rest and torque off (never raises), unless the last stimulus's stop
        did exactly that and nothing was sent since; the next stimulus turns torque on again."""
        with self._port:
            if self._safe is None:
                self._safe = self.bus.rest_and_release()
                self._released = True
            return self._safe

    @property
    def playing_from_ns(self) -> int | None:
        """The time zero on the rig's clock of the stimulus playing now; None while none is
        (a presentation still waiting for the array, or between stimuli). Safe from any
        thread: a screen shows a stimulus's progress from it, never from when it was asked
        for."""
        return self._playing_from_ns

    def keep_wall_time(self) -> None:
        """Play every stimulus on the wall clock (never in the simulator's own time): another
        machine stamps this one's events on it (LSL markers, a scanner's triggers)."""
        self._wall_time = True

    @property
    def plays_in_own_time(self) -> bool:
        """Whether each stimulus plays in the simulator's own time (see `_own_time`)."""
        return isinstance(self.bus_clock, ScaledClock) and not self._wall_time

    def _own_time(self) -> AbstractContextManager[None]:
        """A rehearsal on the in-process simulator at wall-clock pace (the UI's) plays each
        stimulus in the simulator's own time: the UI's redraws and the other programs of a
        busy lab PC share this interpreter and CPU, and must not make a rehearsal's stimulus
        late where real servos (in a player process of their own) would get it in time."""
        if self.plays_in_own_time:
            assert isinstance(self.bus_clock, ScaledClock)
            return self.bus_clock.own_time()
        return nullcontext()

    def test_pin(self, pin: int, cycles: int = 3, frequency_hz: int = 2) -> Presentation:
        """Wiggle one pin (its calibrated widths, the seed's pulse shape) to check the hardware."""
        from fractions import Fraction

        from pinarray.protocol import PinDrive, Train
        from pinarray.schedule import compile_drives

        calibration = self.protocol.device.calibration(pin)
        widths = sorted(w for w, _ in calibration.positions_by_width_ns)
        train = Train(Fraction(frequency_hz), cycles * NS_PER_S // frequency_hz,
                      up_width_ns=widths[-1], down_width_ns=widths[0])
        return self.present(compile_drives([PinDrive(pin, train)], self.protocol.device))

    @overload
    def check_timing(self, duration_ns: int | None = None,
                     period_ns: int = DEFAULT_PERIOD_NS) -> Verdict: ...

    @overload
    def check_timing(self, duration_ns: int | None, period_ns: int = DEFAULT_PERIOD_NS, *,
                     progress: Callable[[int, int], bool]) -> Verdict | CheckSkipped: ...

    def check_timing(self, duration_ns: int | None = None, period_ns: int = DEFAULT_PERIOD_NS,
                     progress: Callable[[int, int], bool] | None = None
                     ) -> Verdict | CheckSkipped:
        """Measure this machine's wake-ups in a player process and judge the protocol's timing.

        ``duration_ns`` None: as long as the protocol's trials need for a verdict that holds
        from one try to the next (`pinarray.player.timing.duration_for`). On the in-process
        simulator a player process is started just for the measurement: the question is
        whether this machine could play real servos in time. ``progress(measured_ns,
        duration_ns)`` is told after every `CHECK_SLICE_NS` measured; when it returns False the
        check ends there, `CheckSkipped`.
        """
        with self._port:
            return self._check_timing(duration_ns, period_ns, progress)

    def _check_timing(self, duration_ns: int | None, period_ns: int,
                      progress: Callable[[int, int], bool] | None) -> Verdict | CheckSkipped:
        from pinarray.player.process import PlayerProcess

        busiest, frames, window_ns = self._frames()
        if duration_ns is None:
            duration_ns = duration_for(frames, period_ns)
        player = self.player or PlayerProcess(None, None, self.stop, realtime=self._realtime)
        lateness_ns: list[int] = []
        try:
            measured_ns = 0
            while measured_ns < duration_ns:
                slice_ns = min(CHECK_SLICE_NS, duration_ns - measured_ns)
                lateness_ns += player.measure_wake_ups(slice_ns, period_ns)
                measured_ns += slice_ns
                if progress is not None and not progress(measured_ns, duration_ns):
                    if measured_ns < duration_ns:
                        return CheckSkipped(measured_ns, duration_ns)
            wake_ups = WakeUps.of(lateness_ns)
            problem = player.realtime_problem
        finally:
            if player is not self.player:
                player.close()
        port = PortFigures(self.url, busiest, self.bus.heal_time_ns(busiest),
                           self.bus.latency_timer_ms, frames)
        return judge(wake_ups, problem, port, self.tolerance_ns, window_ns)

    def _frames(self) -> tuple[int, int, int | None]:
        """The most goal changes one frame of this protocol's trials sends, the most frames
        one trial writes, and the least time the hardware allows a frame's write (None: no
        limit but the tolerance), as the trials are prepared for this array."""
        from pinarray.plan import make_plan
        from pinarray.schedule import compile_trial

        seen, busiest, frames = set(), 1, 1
        windows: list[int] = []
        for planned in make_plan(self.protocol, 0).trials:
            if planned.condition in seen:
                continue
            seen.add(planned.condition)
            schedule = compile_trial(self.protocol, planned)
            trial = prepare_trial(self.bus, schedule.targets, schedule.pulses)
            sizes = [len(frame.goals) for frame in trial.frames]
            busiest = max([busiest, *sizes])
            frames = max(frames, len(sizes))
            window = trial.write_window_ns()
            if window is not None:
                windows.append(window)
        return busiest, frames, min(windows, default=None)

    def telemetry(self) -> tuple[Telemetry, ...]:
        with self._port:
            return self.bus.read_telemetry(self.setup.servo_ids)

    def close(self) -> SafeStopReport:
        """Player process ended, pins to rest, torque off, port closed.

        Waits for a stimulus in progress: request a stop first to cut it short.
        """
        with self._port:
            return self._close()

    def _close(self) -> SafeStopReport:
        if self._forked_away:
            return SafeStopReport((), (), ())  # the array is the original process's to close
        try:
            player, self.player = self.player, None
            try:
                if player is not None:
                    player.close()
            finally:
                # However the player's end went (a second Ctrl-C as it left), pins go to rest,
                # unless the last stop left them so and nothing was sent since: no player. One
                # that ended rested the pins on its way out, and its goals to rest switch
                # torque on; whether its torque off was heard, killed part way (too slow for
                # its budget) or not (a lossy bus: its report is not ours), only ours says.
                safe = (self._safe if self._safe is not None and player is None
                        else self.bus.rest_and_release())
        finally:
            try:
                self.bus.close()
                # Its number is free now, for the script's own files: a copy forked later
                # must not blank whatever holds it then (`_forked`).
                self._fd = None
                announcer, self._announcer = self._announcer, None
                if announcer is not None:
                    announcer.close()
            finally:
                self._let_port_go()
        return safe

    def _let_port_go(self) -> None:
        lock, self._port_lock = self._port_lock, None
        if lock is not None:
            lock.release()

    def _forked(self) -> None:
        """In a forked copy of the process that opened the rig: let go of the port (the
        player's channel and the port's lock let go of themselves), and never close what the
        original drives."""
        self._forked_away = True
        blank_descriptors(self._fd if self._fd is not None else -1)

    def __enter__(self) -> Rig:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
