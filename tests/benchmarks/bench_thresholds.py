"""Do the thresholds' 95 % intervals hold the truth 95 % of the time? Simulated subjects of
known threshold run the seed's adaptive designs; each subject's answers are fitted by
pinarray's Bayesian grid posterior (`pinarray.adaptive.posterior`, what `pinarray analyse`
reports) and, on the same answers in the same run, by psignifit 4 (Schuett et al. 2016), the
reference a reviewer knows.

Target (issue 37): coverage 92-98 % on each design, intervals no wider than they need be.

Subjects: `SUBJECTS` per design, Weibull thresholds log-uniform across the design's values,
slopes uniform in 1.5-5, lapse rates uniform in 0-0.04, the design's guess rate; each runs
the protocol's procedures as a run interleaves them (`simulated_run`). A fit that gives words
instead of a threshold is counted by the bound it states (`ThresholdPosterior.holds`); the
widths are those of the subjects given a number.

psignifit 4.3 (GPL-3.0) is a benchmark-only reference: `make bench` installs it into .venv;
pinarray never imports it. It is run as its documentation asks of adaptive data: the Weibull
on log intensities with the design's whole range as ``stimulus_range``, ``thresh_PC`` = 1 - 1/e
so its threshold is the same as pinarray's (63.2 % of the way from guess to 1 - lapse), 2AFC
for the direction task and yes/no with the guess rate fixed at 0 for detection; otherwise its
defaults (beta-binomial, its priors, its grid). Its fits run on two processes at once; each
fit's time is its process's CPU time.
"""

from __future__ import annotations

import math
import statistics
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pinarray.adaptive.posterior import ThresholdStatus, threshold_posterior
from pinarray.adaptive.psychometric import Psychometric
from pinarray.analysis.procedure_check import simulated_run, subject_seed
from pinarray.analysis.stats import wilson_interval
from pinarray.protocol.load import load_protocol

PROTOCOLS = Path(__file__).resolve().parents[2] / "protocols"
DESIGNS = ("staircase_motion", "quest_stroke")
SUBJECTS = 300
SEED = 37
SLOPES = (1.5, 5.0)
LAPSES = (0.0, 0.04)
WEIBULL_RISE = -math.expm1(-1.0)  # 1 - 1/e: where a Weibull's threshold stands


@dataclass(frozen=True)
class Subject:
    truth: Psychometric
    intensities: tuple[float, ...]
    correct: tuple[int, ...]
    trials: tuple[int, ...]


@dataclass(frozen=True)
class Outcome:
    """One fit of one subject: whether what it states holds the truth, the interval's width
    (NaN for words), and its time (s)."""

    holds: bool
    width: float
    words: bool
    seconds: float


def subjects(design: str) -> tuple[tuple[float, float], list[Subject]]:
    adaptive = load_protocol(PROTOCOLS / f"{design}.yaml").design.adaptive
    assert adaptive is not None
    values = [float(v) for v in adaptive.values]
    rng = np.random.default_rng(SEED)
    found = []
    for i in range(SUBJECTS):
        truth = Psychometric("weibull", float(np.exp(rng.uniform(np.log(values[0]),
                                                                 np.log(values[-1])))),
                             float(rng.uniform(*SLOPES)), float(adaptive.guess_rate),
                             float(rng.uniform(*LAPSES)))
        _, answers = simulated_run(adaptive, truth, subject_seed(SEED, i))
        xs = sorted({a.intensity for a in answers})
        found.append(Subject(truth, tuple(xs),
                             tuple(sum(a.correct for a in answers if a.intensity == x) for x in xs),
                             tuple(sum(a.intensity == x for a in answers) for x in xs)))
    return (values[0], values[-1]), found


def pinarray_fit(subject: Subject) -> Outcome:
    started = time.process_time()
    fit = threshold_posterior("weibull", subject.intensities, subject.correct, subject.trials,
                              guess=subject.truth.guess)
    seconds = time.process_time() - started
    estimated = fit.status is ThresholdStatus.ESTIMATED
    return Outcome(fit.holds(subject.truth.threshold),
                   fit.ci_high - fit.ci_low if estimated else math.nan, not estimated, seconds)


def psignifit_fit(job: tuple[Subject, tuple[float, float]]) -> Outcome:
    import psignifit

    subject, (lowest, highest) = job
    data = np.column_stack([np.log(subject.intensities), subject.correct,
                            subject.trials]).astype(float)
    options: dict[str, object] = {
        "sigmoid": "weibull", "thresh_PC": WEIBULL_RISE, "verbose": False,
        "stimulus_range": (math.log(lowest), math.log(highest))}
    if subject.truth.guess > 0:
        options["experiment_type"] = f"{round(1 / subject.truth.guess)}AFC"
    else:
        options |= {"experiment_type": "yes/no", "fixed_parameters": {"gamma": 0.0}}
    started = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # thresh_PC other than 0.5: said, and meant
        result = psignifit.psignifit(data, **options)
    seconds = time.process_time() - started
    low, high = np.exp(result.confidence_intervals["threshold"]["0.95"])
    return Outcome(bool(low <= subject.truth.threshold <= high), float(high - low), False,
                   seconds)


def row(design: str, method: str, outcomes: list[Outcome]) -> str:
    held = sum(o.holds for o in outcomes)
    n = len(outcomes)
    low, high = wilson_interval(held, n)
    widths = [o.width for o in outcomes if not math.isnan(o.width)]
    ms = sorted(1e3 * o.seconds for o in outcomes)
    return (f"{design:<17} {method:<22} {n:>4} {100 * held / n:>7.1f} % "
            f"[{100 * low:4.1f}-{100 * high:4.1f}] {statistics.median(widths):>9.2f} "
            f"{sum(o.words for o in outcomes):>6} {ms[0]:>8.0f} {statistics.median(ms):>8.0f} "
            f"{ms[-1]:>8.0f}")


def by_band(subjects_: list[Subject], outcomes: list[Outcome]) -> str:
    """Coverage (%) by thirds of the true thresholds and by slope band: is it even?"""
    t = np.array([s.truth.threshold for s in subjects_])
    s = np.array([s.truth.slope for s in subjects_])
    held = np.array([o.holds for o in outcomes])
    cuts = np.quantile(t, [1 / 3, 2 / 3])
    bands = [t < cuts[0], (t >= cuts[0]) & (t < cuts[1]), t >= cuts[1],
             s < 2.5, (s >= 2.5) & (s < 4), s >= 4]
    cells = [f"{100 * held[b].mean():3.0f}" for b in bands]
    return (f"    thresholds low/mid/high third {'/'.join(cells[:3])} %, "
            f"slopes 1.5-2.5/2.5-4/4-5 {'/'.join(cells[3:])} %")


def run() -> None:
    try:
        import psignifit  # noqa: F401
    except ImportError:
        psignifit_there = False
        print("psignifit is not installed (make bench installs it): pinarray's rows only")
    else:
        psignifit_there = True
    print(f"{SUBJECTS} simulated subjects per design (seed {SEED}): Weibull thresholds "
          f"log-uniform across the design's values, slopes {SLOPES[0]:g}-{SLOPES[1]:g}, lapse "
          f"rates {LAPSES[0]:g}-{LAPSES[1]:g}")
    print(f"{'design':<17} {'method':<22} {'n':>4} {'coverage':>9} {'[MC 95 %]':<11} "
          f"{'med.width':>9} {'words':>6} {'min ms':>8} {'med. ms':>8} {'max ms':>8}")
    for design in DESIGNS:
        tested, simulated = subjects(design)
        ours = [pinarray_fit(s) for s in simulated]
        print(row(design, "pinarray posterior", ours))
        print(by_band(simulated, ours))
        if psignifit_there:
            with ProcessPoolExecutor(2) as pool:
                theirs = list(pool.map(psignifit_fit, [(s, tested) for s in simulated],
                                       chunksize=10))
            print(row(design, "psignifit 4 (reference)", theirs))
            print(by_band(simulated, theirs))
            ratio = (statistics.median(o.width for o in theirs)
                     / statistics.median(o.width for o in ours if not math.isnan(o.width)))
            speed = (statistics.median(o.seconds for o in theirs)
                     / statistics.median(o.seconds for o in ours))
            print(f"    psignifit's median width {ratio:.2f}x pinarray's; its median fit "
                  f"{speed:.0f}x as long")
