"""A whole run from a script: the protocol's plan presented trial by trial, each answered by
the script's own answer source, the results written as ``pinarray batch`` and the UI write
them (a BIDS dataset, every trial on disk the moment it ends, resumable).

The sitting is the one the UI and ``batch`` drive (`pinarray.session.sitting`): the same
retry policy for a stimulus not delivered (presented again, the run stopped after three
failures of one trial), the same close on every way out (the run's manifest says how it
ended; pins to rest, torque off).
"""

from __future__ import annotations

from collections.abc import Callable
from os import PathLike
from pathlib import Path
from typing import TYPE_CHECKING

from pinarray.api import arguments
from pinarray.clock import Clock
from pinarray.errors import PinArrayError
from pinarray.journal.timebase import Answers
from pinarray.player.rig import choose_clock
from pinarray.protocol.model import Protocol
from pinarray.session.sitting import Answer, NotDelivered, Question, SessionRequest, Sitting
from pinarray.session.trials import SessionError

if TYPE_CHECKING:  # a run read back once it is over: `pinarray batch` reads none
    from pinarray.analysis.load import LoadedRun

__all__ = ["Answer", "AnswerSource", "NotDelivered", "Question", "run_session",
           "simulated_observer"]

AnswerSource = Callable[[Question], Answer]
"""Answers each trial once its stimulus has played: given the `Question`, an answer its
paradigm takes (`Protocol.design.answers`): a pin's number (or ``"none"``: nothing felt) for
localisation, a direction's name, ``"none"`` or ``"unsure"`` for apparent motion (None counts
as nothing felt); a pattern's name (or a count) for identification, ``"first"`` or
``"second"`` for two intervals, the number of the pin that came first for temporal order."""


def run_session(protocol: Protocol, answer: AnswerSource, *, subject: str, session: str = "1",
                results: str | PathLike[str] = "results", port: str | None = None,
                sim: str | None = None, seed: int | None = None, resume: bool = False,
                experimenter: str = "", clock: Clock | None = None) -> LoadedRun:
    """Run the protocol's whole plan for one subject, answered by ``answer``.

    Parameters
    ----------
    protocol : Protocol
        From `load_protocol`. A protocol with a scanner section (``sync:``) runs from
        ``pinarray batch`` or the UI, which wait for the scanner's triggers.
    answer : AnswerSource
        Called once per delivered trial with the `Question` (the planned trial, and for an
        adaptive design the value presented); see `AnswerSource` for what it returns.
        `simulated_observer` makes one that answers like the seed's subjects.
    subject, session : str
        BIDS labels: letters and digits only.
    results : str or path-like
        The results folder (a BIDS dataset; created if need be).
    port, sim : str or None
        Where the servos are, as for `open_array` (neither: the simulated array).
    seed : int or None
        The plan's seed (None: the protocol's, else a new one, recorded in the manifest); a
        resumed run keeps its own.
    resume : bool
        Continue the subject's unfinished run of this task and session: exactly its remaining
        trials, in plan order, on its own time base.
    experimenter : str
        Who ran it, for the manifest.
    clock : Clock or None
        As for `open_array` (None: virtual time on simulated servos, so a whole session runs
        in seconds; real time on real ones).

    Returns
    -------
    LoadedRun
        The run as read back from disk: its rows, its manifest's status and its paths.

    Raises
    ------
    NotDelivered
        A trial's stimulus failed three times; the run is left aborted and resumable.
    PinArrayError
        Bad labels, a run open in another process (`RunLocked`), nothing to resume, the bus
        failing (`BusError`), results that cannot be written (`ResultsError`).
    """
    call = "run_session"
    protocol = arguments.protocol(call, protocol)
    source = arguments.answer_source(call, answer)
    subject = arguments.label(call, "subject", subject)
    session = arguments.label(call, "session", session)
    results = arguments.path(call, "results", results)
    port = arguments.port(call, port)
    sim = arguments.sim_for(call, protocol, sim)
    seed = arguments.seed(call, seed)
    resume = arguments.flag(call, "resume", resume)
    experimenter = arguments.text(call, "experimenter", experimenter)
    clock = arguments.clock(call, clock)
    if port is not None and sim is not None:
        raise PinArrayError(f"{call}: give a port (real servos) or a sim URL, not both")
    if protocol.sync is not None:
        raise PinArrayError(f"{protocol.source}: a protocol with a sync: section waits for the "
                            "scanner's triggers: run it with `pinarray batch` or the UI")
    request = SessionRequest(protocol, subject, session, experimenter, port, sim, seed, resume,
                             Answers.SCRIPT)

    def clock_for(chosen_port: str | None) -> Clock:
        return clock if clock is not None else choose_clock(chosen_port, None, paced=True,
                                                            sim_url=sim)

    def checked(question: Question) -> Answer:
        return arguments.answer(call, source(question))  # True is never pin 1, 6.7 never 6

    try:
        with Sitting(Path(results), clock_for) as sitting:
            sitting.connect(request)
            beh = sitting.open_session().writer.paths.beh_tsv
            sitting.run_scripted(checked)
    except SessionError as error:  # an answer the paradigm does not take (the run is kept)
        raise PinArrayError(f"{call}: answer: {error}") from None
    from pinarray.analysis.load import load_run

    return load_run(beh)


def simulated_observer(protocol: Protocol, model: str = "default", *,
                       seed: int | None = None) -> AnswerSource:
    """An answer source that answers like a simulated subject (``pinarray batch --observer``).

    Parameters
    ----------
    protocol : Protocol
        The protocol it will answer; a fixed design's observer is calibrated on its pins.
    model : str
        ``"default"`` (the paradigm's average subject: for localisation 62.5 % correct at
        10 Hz, as the seed's; for apparent motion 77 % felt motion) or overrides of its
        paradigm's model such as ``"correct_10hz=0.7"``, ``"motion_felt=0.9"``,
        ``"identify_correct=0.7"``, ``"weber=0.25"``, ``"jnd_ms=30"`` (each paradigm's room
        says its own: `pinarray.analysis.seam.ParadigmAnalysis.observer`); an adaptive
        design's psychometric function, e.g. ``"threshold=120,slope=3,lapse=0.02"``.
    seed : int or None
        Seed of its random answers (None: a fixed design's observer draws a new subject; an
        adaptive one uses 0).

    Raises
    ------
    PinArrayError
        A model it cannot read, naming the key.
    """
    call = "simulated_observer"
    protocol = arguments.protocol(call, protocol)
    model = arguments.text(call, "model", model)
    seed = arguments.seed(call, seed)
    adaptive = protocol.design.adaptive
    if adaptive is not None:
        from pinarray.analysis.adaptive_subject import AdaptiveSubject, parse_psychometric

        subject = AdaptiveSubject(protocol, parse_psychometric(model, adaptive), seed or 0)

        def respond_adaptively(question: Question) -> Answer:
            trial = question.trial
            return subject.respond(trial.trial, trial.condition, trial.catch,
                                   question.adapted_value)

        return respond_adaptively
    from pinarray.analysis.seam import observer_of, trial_answers

    # Each answer from the seed and the trial's number: a resumed run answers as an unbroken one.
    answer = trial_answers(
        observer_of(protocol.design.paradigm.name)(protocol, model, seed), seed)
    return lambda question: answer(question.trial.trial, question.trial.condition)
