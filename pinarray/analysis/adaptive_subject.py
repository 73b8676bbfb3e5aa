"""A simulated subject for adaptive designs: answers from a known psychometric function.

``--observer threshold=120,slope=3,lapse=0.02`` (any of function, threshold, slope, guess,
lapse; the rest default: a Weibull whose threshold is the middle of the design's values, slope
3, the design's guess rate, lapse 0.02). A trial at value ``x`` is answered correctly with
probability ``p(x)`` (`pinarray.adaptive.observer`: a draw from the seed, the trial number and
the value only, so a resumed run gets the answers it would have had). A correct answer is
what the task counts as correct, a wrong one another of the design's answers (or nothing felt,
for detection), as the paradigm says them (`pinarray.protocol.seam.ParadigmDesign.felt_answer`,
``wrong_answer``). A catch trial is answered rightly (nothing felt) unless the subject lapses.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from fractions import Fraction

from pinarray.adaptive.observer import PsychometricObserver
from pinarray.adaptive.psychometric import Psychometric
from pinarray.analysis.observers import observer_items, observer_number, quoted
from pinarray.errors import PinArrayError
from pinarray.protocol.model import Condition, Protocol
from pinarray.protocol.procedures import Adaptive, Function

NOTHING = "none"  # a detection task's catch trial answered rightly: nothing felt

KEYS = ("function", "threshold", "slope", "guess", "lapse")


def default_function(adaptive: Adaptive) -> Psychometric:
    """The subject ``--observer default`` simulates for ``adaptive``."""
    values = adaptive.values
    return Psychometric("weibull", float(values[len(values) // 2]), 3.0,
                        float(adaptive.guess_rate), 0.02)


def parse_psychometric(spec: str, adaptive: Adaptive) -> Psychometric:
    """The subject's function from ``default`` or ``key=value,...`` (keys: `KEYS`)."""
    function = default_function(adaptive)
    if spec.strip() in ("", "default"):
        return function
    changes: dict[str, object] = {}
    for item, name, text in observer_items(spec):
        if name == "function":
            if text not in tuple(Function):
                raise PinArrayError(f"observer: {quoted(item)}: expected function=weibull or "
                                    "function=logistic")
            changes["kind"] = text
            continue
        if name not in KEYS:
            raise PinArrayError(f"observer: unknown parameter {quoted(name)} for an adaptive "
                                f"design; expected one of {', '.join(KEYS)}")
        changes[name] = observer_number(item, text)
    try:
        return replace(function, **changes)  # type: ignore[arg-type]
    except PinArrayError as problem:
        raise PinArrayError(f"observer: {problem}") from None


@dataclass(frozen=True)
class AdaptiveSubject:
    """Answers an adaptive design's trials as `function` says (see the module)."""

    protocol: Protocol
    function: Psychometric
    seed: int

    def respond(self, trial: int, condition: Condition, catch: bool,
                value: Fraction | None) -> str:
        adaptive = self.protocol.design.adaptive
        assert adaptive is not None
        observer = PsychometricObserver(self.function, self.seed)
        if catch or value is None:
            # A Weibull is its guess rate at 0: a draw that comes out True with p = lapse.
            slips = PsychometricObserver(Psychometric("weibull", 1.0, 1.0, self.function.lapse,
                                                      0.0), self.seed)
            return self._felt(condition, trial) if slips.answer(trial, 0.0) else NOTHING
        if observer.answer(trial, float(value)):
            return self._felt(condition, trial)
        design = self.protocol.design
        return design.paradigm.wrong_answer(adaptive.task, condition, design,
                                            self.protocol.device.grid.pin_count, trial)

    def _felt(self, condition: Condition, trial: int) -> str:
        design = self.protocol.design
        return design.paradigm.felt_answer(condition, design, trial)
