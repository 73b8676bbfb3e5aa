"""An adaptive run's procedures, as its rows on disk leave them.

The state of every procedure is rebuilt from the run's rows when a sitting starts: the rows
that count (status ok, not practice, not catch), in file order, each answer given again to its
procedure (`pinarray.procedures.ProcedureSet`). A killed run therefore resumes at exactly the
state it had; a trial that was not delivered, was aborted or redone has no ok row and moves
nothing, and is presented again at the same value.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from fractions import Fraction
from pathlib import Path

from pinarray.adaptive.questplus import QuestPlus as QuestPlusMachine
from pinarray.errors import PinArrayError
from pinarray.journal.records import AdaptiveCells, TrialRecord, TrialStatus
from pinarray.plan import PlannedTrial, TrialPlan
from pinarray.procedures import Presented, ProcedureSet, counts_as_correct
from pinarray.protocol.procedures import CATCH, PRACTICE, Adaptive


class Procedures(ProcedureSet):
    """The run's procedures, standing where its rows leave them.

    ``beh`` names the rows' file in errors; ``plan`` gives each row's condition, against which
    its ``correct`` cell is checked (a cell edited by hand is named on its own line, not where
    the procedures' values first part from the rows); ``prepared``: QUEST+ tables computed
    before the run was opened (`pinarray.procedures.prepare_quest_plus`).
    """

    def __init__(self, adaptive: Adaptive, seed: int, records: Sequence[TrialRecord],
                 beh: Path | str = "beh.tsv", plan: TrialPlan | None = None,
                 prepared: Mapping[str, QuestPlusMachine] | None = None):
        super().__init__(adaptive, seed, prepared)
        planned = {} if plan is None else {(t.trial, t.practice): t for t in plan.trials}
        for line, record in enumerate(records, start=2):
            cells = record.adaptive
            if (not record.counts or cells is None or cells.correct is None
                    or cells.procedure in (CATCH, PRACTICE)):
                continue
            where = f"{beh}:{line}: trial {record.trial}"
            trial = planned.get(record.key)
            if trial is not None and record.response is not None:
                correct = counts_as_correct(adaptive.task, trial.condition, trial.catch,
                                            str(record.response))
                if correct != cells.correct:
                    raise PinArrayError(
                        f"{where}: correct is {str(cells.correct).lower()}, but the response "
                        f"{str(record.response)!r} counts as {str(correct).lower()} (edited by "
                        "hand?); put the row back as it was, then resume")
            if not self.runs(cells.procedure):
                raise PinArrayError(f"{where} names procedure {cells.procedure!r}, which the "
                                    "protocol does not run")
            due = self.next()
            if due.procedure != cells.procedure or due.value is None \
                    or float(due.value) != cells.intensity:
                raise PinArrayError(
                    f"{where} presented {cells.intensity} for {cells.procedure!r}, but the "
                    f"procedures' rules give {due.value} for {due.procedure!r} from the rows "
                    "before: the protocol or its seed changed, or a row before was edited")
            self.take(cells.procedure, due.value, cells.correct)

    def presented(self, planned: PlannedTrial) -> Presented:
        """What ``planned`` presents, the procedures standing as they do."""
        return self.next(planned.practice, planned.catch)

    def cells(self, presented: Presented) -> AdaptiveCells:
        """The cells of a row without an answer that counts (redone, aborted, invalid)."""
        return AdaptiveCells(presented.procedure, self.adaptive.parameter.value,
                             None if presented.value is None else float(presented.value),
                             float(self.adaptive.guess_rate))

    def answer(self, planned: PlannedTrial, presented: Presented, response: str,
               status: TrialStatus) -> AdaptiveCells:
        """The cells of ``planned``'s row answered ``response``; an ok row of a procedure's
        trial moves its procedure. The session writes the row at once: a write that fails ends
        the sitting, and the next one rebuilds the procedures from the rows that are on disk."""
        cells = self.cells(presented)
        correct = counts_as_correct(self.adaptive.task, planned.condition, planned.catch,
                                    response)
        if status is not TrialStatus.OK or presented.procedure in (CATCH, PRACTICE):
            return replace(cells, correct=correct)
        assert isinstance(presented.value, Fraction)
        fields = self.take(presented.procedure, presented.value, correct)
        return replace(cells, correct=correct, reversal=fields.reversal, estimate=fields.estimate,
                       estimate_ci_low=fields.ci_low, estimate_ci_high=fields.ci_high)
