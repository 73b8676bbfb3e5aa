"""Writing one run: the manifest before trial 1, then each trial row, fsync'd, the moment it ends.

``beh.tsv`` is the record of what happened; ``events.tsv`` is derived from it one row per
trial (so it can always be rebuilt from ``beh.tsv`` after a crash). The pins' sampled motion
goes to the run's motion recording (`pinarray.journal.physio`) after the trial's rows, flushed
and fsync'd per trial; a resume keeps every trial that reads back whole. Every earlier row was on
disk before the trial after it began; a process killed while writing leaves at most one torn
last row, which a resume drops.

A run has one writer at a time: `RunWriter.start` and `RunWriter.resume` take the run's lock
(`pinarray.journal.lock`) before reading or writing anything, and `close` gives it back. A
second process is refused with a one-line `RunLocked` naming the first.

Past 400 lines on purpose: the order of the fsync'd writes (manifest, rows, events, volumes,
sidecars) is what keeps a killed run resumable, and it reads only as one piece.
"""

from __future__ import annotations

import contextlib
import json
import os
import stat
import sys
from collections.abc import Callable, Sequence
from dataclasses import replace
from datetime import datetime
from pathlib import Path
from types import TracebackType
from typing import TextIO

from pinarray.errors import ResultsError
from pinarray.journal.columns import NA, tsv_line
from pinarray.journal.dataset import DATASET_FILES, ensure_dataset, write_sidecars
from pinarray.journal.files import (
    fsync_folder,
    iso,
    own_copy,
    read_results_file,
    read_results_text,
    results_file,
    this_host,
    this_machine,
    wall_now,
    write_atomically,
)
from pinarray.journal.lock import RunLock, RunLocked, stale_message
from pinarray.journal.manifest import (
    PlanEntry,
    Provenance,
    RunManifest,
    RunStatus,
    TaskInfo,
    read_manifest,
    remaining_plan,
    updated,
    write_manifest,
)
from pinarray.journal.paths import RunPaths, has_files, runs_of
from pinarray.journal.physio import (
    MotionColumns,
    MotionRecording,
    MotionSample,
    claimed_samples,
    motion_recording_path,
    motion_sidecar,
)
from pinarray.journal.records import LEGACY_LAYOUT, TrialRecord, TrialStatus
from pinarray.journal.rows import (
    beh_header,
    check_finished_once,
    check_run,
    event_row,
    finished_trials,
    is_legacy_prefix,
    read_trials,
    split_torn_tail,
    todays_names,
    trial_row,
)
from pinarray.journal.seam import ParadigmRows, rows_of
from pinarray.journal.timebase import (
    FIRST_TRIAL_ONSET,
    REAL_TIME,
    Answers,
    Sitting,
    TimeScale,
    TimeZero,
    answered_otherwise,
    resumed_start_ns,
    zero_wall_time,
)
from pinarray.journal.volumes import (
    VOLUME_NAMES,
    ScannerRecord,
    VolumeRow,
    volume_cells,
    volume_log_path,
    volume_sidecar,
)
from pinarray.stop import deferred_signals
from pinarray.text_files import kind_of
from pinarray.version import __version__

Wall = Callable[[], datetime]


def unwritable(problem: OSError, where: Path, *, mid_run: bool = False) -> ResultsError:
    """A file that could not be written, in one line: which, and what the system said."""
    after = ("; every row written before is on disk, and the run resumes once the results "
             "can be written" if mid_run else "")
    return ResultsError(f"{problem.filename or where}: cannot write results there: "
                        f"{problem.strerror or problem}{after}")


def repair_tail(path: Path, columns: int) -> str:
    """Drop a torn last row of the TSV at ``path`` in place; return the dropped text."""
    if not results_file(path):
        return ""
    data = read_results_file(path)
    end, torn = split_torn_tail(data, columns)
    if torn:
        own_copy(path)  # cut here only, not in a backup linked to it
        with open(path, "r+b") as handle:
            handle.truncate(end)
            handle.flush()
            os.fsync(handle.fileno())
    return torn.decode("utf-8", errors="replace")


def _upgrade_columns(path: Path, added: int) -> None:
    """Give an earlier pinarray's ``beh.tsv`` today's column names, its rows ``added`` n/a
    cells for the columns appended since (its whole rows; a torn tail is already dropped)."""
    rows = read_results_text(path).split("\n", 1)[1]
    pad = "\t".join([NA] * added)
    if added:
        rows = "".join(f"{row}\t{pad}\n" for row in rows.split("\n") if row)
    write_atomically(path, tsv_line(LEGACY_LAYOUT) + rows)


def _rebuild_events(path: Path, records: Sequence[TrialRecord], rows: ParadigmRows) -> None:
    """Make ``events.tsv`` hold one row per trial row on file, rewriting it if it does not.

    Its rows are a function of beh.tsv's, which is fsync'd first: a crash between the two
    leaves events one row short (or a torn row), and a row deleted by hand from beh.tsv (a
    trial logged ok twice) leaves one too many. Either way it is rebuilt from the trial rows.
    """
    text = tsv_line(rows.event_layout) + "".join(tsv_line(event_row(r, rows)) for r in records)
    try:
        same = results_file(path) and read_results_text(path) == text
    except ResultsError:  # not text, or not a table's size: rebuilt all the same
        same = False
    if not same:
        write_atomically(path, text)


class _AppendOnlyTsv:
    """A TSV opened for appending whose every row is on disk when `append` returns."""

    def __init__(self, path: Path, header: Sequence[str]):
        created = not path.exists()
        self._file = _open_to_append(path)
        if self._file.tell() == 0:
            self.append(header)
        if created:
            fsync_folder(path.parent)

    def append(self, cells: Sequence[str]) -> None:
        self.extend([cells])

    def extend(self, rows: Sequence[Sequence[str]]) -> None:
        """Append ``rows``, then flush and fsync once."""
        self._file.write("".join(tsv_line(cells) for cells in rows))
        self._file.flush()
        os.fsync(self._file.fileno())

    def close(self) -> None:
        self._file.close()


def _open_to_append(path: Path) -> TextIO:
    """``path`` opened for appending text, never waiting: a FIFO put in a results file's
    place would block a plain open until something reads it. A file with other names (hard
    links: a ``cp -al`` backup) gets a copy of its own first, so rows go to this one only."""
    own_copy(path)
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NONBLOCK | os.O_NOCTTY,
                 0o666)
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise ResultsError(f"{path}: expected a results file, found {kind_of(mode)}")
    os.set_blocking(fd, True)
    return os.fdopen(fd, "a", encoding="utf-8", newline="")


def run_files(paths: RunPaths) -> tuple[Path, ...]:
    """Every file a resume of the run at ``paths`` may read or write, but its lock."""
    motion = motion_recording_path(paths)
    volumes = volume_log_path(paths)
    return (paths.manifest, paths.legacy_manifest, paths.beh_tsv, paths.events_tsv,
            paths.beh_json, paths.events_json, motion,
            motion.with_name(motion.name.removesuffix(".tsv.gz") + ".json"),
            volumes, volumes.with_suffix(".json"),
            *(paths.root / name for name in DATASET_FILES))


def _command() -> str:
    return " ".join(["pinarray", *sys.argv[1:]])[:300]


def _claim_next_run(root: Path, subject: str, session: str, task: str) -> tuple[RunPaths, RunLock]:
    """The first run number after every existing run, locked (never reuses a number)."""
    written = [p.run for p in runs_of(root, subject, session, task) if has_files(p)]
    run = max(written, default=0) + 1
    while True:
        paths = RunPaths(root, subject, session, task, run)
        try:
            lock = RunLock.acquire(paths.lock, paths.label, _command())
        except RunLocked:
            run += 1  # another process is starting this number right now
            continue
        if not has_files(paths):
            return paths, lock
        lock.release()  # it finished this number while we looked: take the next
        run += 1


def refuse_other_answers(label: str, manifest: RunManifest, answers: Answers) -> None:
    """Refused (`ResultsError`, in one line saying how to resume it) when the run ``label``
    was answered by another known kind than ``answers``: a subject's run resumed by a simulated
    observer would hold a person's answers and a model's."""
    started = answered_otherwise(manifest.sittings, answers)
    if started is not None:
        raise ResultsError(
            f"{label}: expected the answers its sittings had ({started.describe()}), "
            f"found {answers.describe()}; resume it {started.how_to_resume()}")


class RunWriter:
    """Writes one run; holds its lock until `close` (or `finish`).

    Make one with `RunWriter.start` (a new run) or `RunWriter.resume` (an unfinished one);
    use it as a context manager so a crash inside the block marks the manifest ``crashed``.

    Attributes
    ----------
    resumed : bool
        Whether this sitting continues an earlier one (its rows are marked ``resumed``).
    repaired : str
        Text of a torn last row dropped on resume, for the log ("" if none).
    stale_lock : str
        A lock left by a process that died, taken over, in words ("" if none).
    """

    def __init__(self, paths: RunPaths, manifest: RunManifest, records: list[TrialRecord],
                 lock: RunLock, *, resumed: bool, repaired: str = "", wall: Wall = wall_now,
                 claimed: int | None = 0):
        self.paths = paths
        self.manifest = manifest
        self.records = records
        self.resumed = resumed
        self.repaired = repaired
        # A new run may take a number whose lock a killed process left before writing anything:
        # nothing of that run is resumed, so there is nothing to report.
        self.stale_lock = stale_message(lock.stale, paths.label) if lock.stale and resumed else ""
        self._lock = lock
        self._wall = wall
        self._finished = set(finished_trials(records))
        self.rows = rows_of(manifest.task_info.paradigm)  # the run's paradigm's rows
        self._beh = _AppendOnlyTsv(paths.beh_tsv, self.rows.layout)
        self._events = _AppendOnlyTsv(paths.events_tsv, self.rows.event_layout)
        self._volumes: _AppendOnlyTsv | None = None
        self._motion: MotionRecording | None = None
        # The samples the rows on disk claim of the motion recording (None: some row does not
        # say: written before the count was kept), checked against the file on resume.
        self._claimed = claimed
        self._pending_volumes: Callable[[], Sequence[VolumeRow]] = tuple

    @classmethod
    def start(
        cls,
        root: Path | str,
        subject: str,
        session: str | int,
        task: str,
        plan: Sequence[PlanEntry],
        provenance: Provenance,
        task_info: TaskInfo,
        clock: TimeScale = REAL_TIME,
        *,
        wall: Wall = wall_now,
        scanner: ScannerRecord | None = None,
        answers: Answers = Answers.UNKNOWN,
    ) -> RunWriter:
        """Start the next free run: root files, manifest (status running), sidecars.

        Parameters
        ----------
        root, subject, session, task
            The results folder and the run's BIDS labels.
        plan
            Every trial of the run, in presentation order.
        provenance, task_info
            What the manifest and the sidecars record.
        clock
            This sitting's clock (real time unless simulated).
        wall
            The wall clock (tests pass their own).
        scanner
            For a run timed from scanner volumes: the trigger and its log, for the manifest.
        answers
            Who or what answers the sitting's trials.
        """
        root = Path(root)
        lock = None
        try:
            probe = RunPaths(root, subject, str(session), task, 1)  # checks the labels first
            ensure_dataset(root, probe.subject)
            paths, lock = _claim_next_run(root, probe.subject, probe.session, probe.task)
            now = wall()
            sitting = Sitting(1, iso(now), clock, None, os.getpid(), this_host(), __version__,
                              answers=answers)
            if scanner is not None:  # its log is named after the run just claimed
                log = volume_log_path(paths).relative_to(root).as_posix()
                scanner = replace(scanner, volume_log=log)
            manifest = RunManifest(
                subject=paths.subject, session=paths.session, task=paths.task, run=paths.run,
                plan=tuple(plan), provenance=provenance, task_info=task_info,
                started_at=iso(now), updated_at=iso(now), sittings=(sitting,),
                machine=this_machine(), scanner=scanner,
            )
            write_manifest(paths.manifest, manifest)
            write_sidecars(paths, manifest)
            return cls(paths, manifest, [], lock, resumed=False, wall=wall)
        except OSError as problem:
            if lock is not None:
                lock.release()
            raise unwritable(problem, root) from None
        except BaseException:
            if lock is not None:
                lock.release()
            raise

    @classmethod
    def resume(cls, paths: RunPaths, clock: TimeScale = REAL_TIME, *,
               wall: Wall = wall_now, answers: Answers = Answers.UNKNOWN) -> RunWriter:
        """Reopen an unfinished run: lock it, drop a torn row, rebuild events, start a sitting
        whose trials ``answers`` answers.

        Refused (`RunLocked`) while another process writes it; refused (`ResultsError`) when
        its rows finish a trial twice, which only a second writer or a hand edit leaves, and
        when its sittings were answered otherwise (a subject's run resumed by a simulated
        observer would hold a person's answers and a model's).
        """
        try:
            lock = RunLock.acquire(paths.lock, paths.label, _command())
        except OSError as problem:
            raise unwritable(problem, paths.lock) from None
        try:
            return cls._resume_locked(paths, lock, clock, wall, answers)
        except OSError as problem:
            lock.release()
            raise unwritable(problem, paths.root) from None
        except BaseException:
            lock.release()
            raise

    @classmethod
    def _resume_locked(cls, paths: RunPaths, lock: RunLock, clock: TimeScale,
                       wall: Wall, answers: Answers) -> RunWriter:
        source = paths.manifest_on_disk()
        if source is None:
            raise ResultsError(f"{paths.manifest}: no run manifest here")
        manifest = read_manifest(source)
        if not manifest.status.unfinished:
            raise ResultsError(f"{source}: the run is {manifest.status}; only a running, "
                               "crashed or aborted run can be resumed")
        refuse_other_answers(paths.label, manifest, answers)
        # Everything is looked at before anything is written: a resume refused leaves every
        # file of the run as it found it.
        for path in run_files(paths):
            results_file(path, "run manifest" if path.name.endswith("_manifest.json")
                         else "results")
        header = beh_header(paths.beh_tsv)
        names = todays_names(header)
        rows = rows_of(manifest.task_info.paradigm)
        if header and names != rows.layout and not (rows.layout == LEGACY_LAYOUT
                                                    and is_legacy_prefix(names)):
            raise ResultsError(
                f"{paths.beh_tsv}:1: this run was written by an earlier pinarray with the columns "
                f"{', '.join(header)}; finish it with that version, or start a new run"
            )
        records = (read_trials(paths.beh_tsv, manifest.task_info.paradigm)
                   if paths.beh_tsv.exists() else [])
        check_run(paths.beh_tsv, records, manifest)
        check_finished_once(paths.beh_tsv, records, ", then resume")
        # Every sample the rows claim must be in the recording, before anything is changed.
        claimed = claimed_samples(motion_recording_path(paths), records)
        # The dataset's own files are read (and refused) before the run's are changed; it
        # writes only what they lack (another version's name, a new participant's row).
        ensure_dataset(paths.root, paths.subject)
        repaired = repair_tail(paths.beh_tsv, len(header) or len(rows.layout))
        if header and tuple(header) != rows.layout:
            _upgrade_columns(paths.beh_tsv, len(rows.layout) - len(header))
        _rebuild_events(paths.events_tsv, records, rows)
        now = wall()
        zero_at = (datetime.fromisoformat(manifest.time_zero.at)
                   if manifest.time_zero is not None else None)
        start_ns = resumed_start_ns(max((r.end_ns for r in records), default=None), zero_at,
                                    now, clock)
        sitting = Sitting(len(manifest.sittings) + 1, iso(now), clock, start_ns, os.getpid(),
                          this_host(), __version__, answers=answers)
        manifest = updated(manifest, status=RunStatus.RUNNING, abort_reason="",
                           sittings=(*manifest.sittings, sitting))
        write_manifest(paths.manifest, manifest)
        if source != paths.manifest:
            source.unlink()  # an older run's manifest, now moved to sourcedata/
        write_sidecars(paths, manifest)
        return cls(paths, manifest, records, lock, resumed=True, repaired=repaired, wall=wall,
                   claimed=claimed)

    # -- the run's time base -----------------------------------------------------------------

    @property
    def sitting(self) -> Sitting:
        """This process's sitting (the manifest's last)."""
        return self.manifest.sittings[-1]

    @property
    def sitting_start_ns(self) -> int | None:
        """This sitting's start on the run's time base (ns), or None until the run's zero is fixed."""
        return self.sitting.start_ns

    def set_time_zero(self, sitting_start_ns: int, zero_ago_ns: int,
                      event: str = FIRST_TRIAL_ONSET) -> None:
        """Fix the run's time zero (once): record it and where this sitting started against it.

        Parameters
        ----------
        sitting_start_ns : int
            This sitting's start on the run's time base (ns; <= 0 when the zero came after it).
        zero_ago_ns : int
            How long ago, on this sitting's clock, the zero was (ns), to date it on the wall clock.
        event : str
            What the zero is, in words.
        """
        if self.sitting_start_ns is not None:
            raise ResultsError(f"{self.paths.label}: the run's time zero is already fixed")
        at = zero_wall_time(self._wall(), zero_ago_ns, self.sitting.clock)
        sittings = (*self.manifest.sittings[:-1], replace(self.sitting, start_ns=sitting_start_ns))
        self.manifest = updated(self.manifest, sittings=sittings,
                                time_zero=TimeZero(event, iso(at, "microseconds")))
        try:
            write_manifest(self.paths.manifest, self.manifest)
            write_sidecars(self.paths, self.manifest)  # they say what the zero is, and when
        except OSError as problem:
            raise unwritable(problem, self.paths.manifest, mid_run=True) from None

    def note_timing_check(self, said: str) -> None:
        """Record what the pre-flight's timing check said before this sitting (in words)."""
        sittings = (*self.manifest.sittings[:-1], replace(self.sitting, timing_check=said))
        self.manifest = updated(self.manifest, sittings=sittings)
        try:
            write_manifest(self.paths.manifest, self.manifest)
        except OSError as problem:
            raise unwritable(problem, self.paths.manifest, mid_run=True) from None

    # -- scanner volumes ---------------------------------------------------------------------

    def log_volumes(self, pending: Callable[[], Sequence[VolumeRow]]) -> None:
        """Keep the run's volume log (`pinarray.journal.volumes`): now, after each trial row,
        and when the run closes, the rows ``pending()`` returns are appended and fsync'd.

        The run's manifest must name the log (``scanner``, given to `start`).
        """
        record = self.manifest.scanner
        if record is None:
            raise ResultsError(f"{self.paths.label}: a volume log needs the run's scanner "
                               "settings in its manifest")
        path = volume_log_path(self.paths)
        write_atomically(path.with_suffix(".json"),
                         json.dumps(volume_sidecar(record), indent=2, ensure_ascii=False) + "\n")
        self._volumes = _AppendOnlyTsv(path, VOLUME_NAMES)
        self._pending_volumes = pending
        self._flush_volumes()  # the dummies and time zero are on disk before the first trial

    def _flush_volumes(self) -> None:
        if self._volumes is not None:
            rows = self._pending_volumes()
            if rows:
                self._volumes.extend([volume_cells(row) for row in rows])

    # -- rows --------------------------------------------------------------------------------

    @property
    def plan(self) -> tuple[PlanEntry, ...]:
        return self.manifest.plan

    def remaining(self) -> list[PlanEntry]:
        """Plan entries still to run, in plan order."""
        return remaining_plan(self.manifest.needed, self.records)

    def write_trial(self, record: TrialRecord,
                    motion: Sequence[MotionSample] | MotionColumns = ()) -> TrialRecord:
        """Append ``record`` to beh.tsv and events.tsv, each fsync'd, and return it as written;
        then ``motion``, the trial's samples, to the run's motion recording, fsync'd.

        On a resumed run the row is marked ``resumed``. A second ``ok`` row for a trial is
        refused: a trial counts once.
        """
        if not self._lock.held:
            raise ResultsError(f"{self.paths.label}: the run is closed; it has no writer now")
        if not isinstance(record, self.rows.record_type):
            raise ResultsError(f"{self.paths.label}: a {self.rows.name} run's rows are "
                               f"{self.rows.record_type.__name__}s, not "
                               f"{type(record).__name__}s")
        if record.status is TrialStatus.OK and record.key in self._finished:
            raise ResultsError(f"{self.paths.beh_tsv}: trial {record.trial} is already logged ok; "
                               "a trial counts once")
        if self.resumed and not record.resumed:
            record = replace(record, resumed=True)
        # The samples first: a row says how many of them are on disk, and is written only once
        # they are (a full disk or a deleted recording leaves no row: the trial is played again).
        record = replace(record, motion_samples=len(motion))
        if len(motion):
            self._write_motion(MotionColumns.of(motion))
        try:
            with deferred_signals():  # a Ctrl-C must not fall between the two files
                self._beh.append(trial_row(record, self.rows))
                self._events.append(event_row(record, self.rows))
                self.records.append(record)
                if record.status is TrialStatus.OK:
                    self._finished.add(record.key)
                if self._claimed is not None:
                    self._claimed += len(motion)
        except OSError as problem:
            raise unwritable(problem, self.paths.beh_tsv, mid_run=True) from None
        self._flush_volumes()
        return record

    def _write_motion(self, samples: MotionColumns) -> None:
        """A trial's samples onto the run's motion recording; its sidecar with the first.

        The recording is opened keeping the samples the rows claim (those of a presentation
        whose row never came are dropped); one deleted or replaced since it was opened is
        refused, as its earlier samples went with it."""
        path = motion_recording_path(self.paths)
        if self._motion is not None and not self._motion.in_place:
            raise ResultsError(
                f"{path}: the run's motion recording was deleted or replaced while the run "
                "wrote it, and the samples of its earlier trials with it; this trial's row is "
                "not written (the run is left resumable: put the recording back to resume it, "
                "or start a new run)")
        try:
            if self._motion is None:
                sidecar = path.with_name(path.name.removesuffix(".tsv.gz") + ".json")
                if not sidecar.exists():
                    described = motion_sidecar(samples.samples(), self.manifest.task_info.name)
                    write_atomically(sidecar, json.dumps(described, indent=2) + "\n")
                self._motion = MotionRecording(path, keep=self._claimed)
                fsync_folder(path.parent)
            self._motion.append(samples)
        except OSError as problem:
            # A stream cut mid-block cannot be continued: the next write opens it again from
            # the samples the rows claim.
            motion, self._motion = self._motion, None
            if motion is not None:
                with contextlib.suppress(OSError):
                    motion.close()
            raise unwritable(problem, path, mid_run=True) from None

    def not_needed_after(self, trial: int) -> None:
        """The run's adaptive procedures have all finished at ``trial``: the later planned
        trials are not needed (the manifest says so before the run is finished)."""
        self.manifest = updated(self.manifest, needed_until=trial)
        try:
            write_manifest(self.paths.manifest, self.manifest)
        except OSError as problem:
            raise unwritable(problem, self.paths.manifest, mid_run=True) from None

    def finish(self, status: RunStatus = RunStatus.COMPLETED, reason: str = "") -> None:
        """Set the manifest's final status (completed / aborted / crashed), close, unlock."""
        self.manifest = updated(self.manifest, status=RunStatus(status), abort_reason=reason)
        try:
            write_manifest(self.paths.manifest, self.manifest)
        except OSError as problem:
            raise unwritable(problem, self.paths.manifest, mid_run=True) from None
        finally:
            self.close()

    def close(self) -> None:
        """Close the files and give up the run's lock (whatever closing the files says)."""
        try:
            self._flush_volumes()
        finally:
            try:
                volumes, self._volumes = self._volumes, None
                motion, self._motion = self._motion, None
                if motion is not None:
                    with contextlib.suppress(OSError):
                        motion.close()  # the stream's end: a whole gzip file
                for tsv in (self._beh, self._events, *([volumes] if volumes else [])):
                    # Every row was fsync'd as it was written; closing can only fail on one
                    # whose write already failed and was reported.
                    with contextlib.suppress(OSError):
                        tsv.close()
            finally:
                self._lock.release()

    def __enter__(self) -> RunWriter:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 traceback: TracebackType | None) -> None:
        if kind is None or self.manifest.status is not RunStatus.RUNNING:
            # Nothing went wrong, or the caller already recorded how the run ended.
            self.close()
        else:
            status, reason = ((RunStatus.ABORTED, "interrupted (Ctrl-C)")
                              if issubclass(kind, KeyboardInterrupt)
                              else (RunStatus.CRASHED, f"{kind.__name__}: {error}"))
            # If the manifest cannot be written either (the disk that failed the block), it
            # keeps saying running, which resume treats as unfinished: the block's own error
            # is the one to report.
            with contextlib.suppress(ResultsError):
                self.finish(status, reason)
