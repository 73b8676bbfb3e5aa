"""``pinarray analyse`` (results in, tables, figures and a page out) and ``pinarray power``
(how many subjects a protocol needs, from simulated subjects; for an adaptive design, how
its procedures' estimates fall against a simulated subject's known threshold)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from pinarray.cli import common

if TYPE_CHECKING:
    from pinarray.protocol import Protocol

# The bootstrap draws resamples x subjects indices at once: 100 000 x 100 subjects is 80 MB.
MAX_RESAMPLES = 100_000
# A power study simulates studies x subjects whole sessions for each number of subjects.
MAX_STUDIES, MAX_SUBJECTS, MAX_SUBJECT_COUNTS = 10_000, 1000, 20
# Each input is bounded; their product is the work: refused past half an hour (estimated
# before it starts), said as it goes past `common.PROGRESS_AFTER_S`.
MAX_POWER_S = 1800
POWER_FILES = ("power.md", "power.csv", "precision.csv", "power_curves.png",
               "power_curves.pdf")
MAX_PINS = 64 * 64  # the largest grid a protocol may describe


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``analyse`` and ``power`` to the `pinarray` parser."""
    parser = subparsers.add_parser(
        "analyse",
        help="subject-level tables, figures and a one-page summary from results files",
        description="Analyse beh.tsv results with subjects as the unit: per-subject "
        "percentages, their across-subject mean with a subject bootstrap interval (a t "
        "interval on request), the trial-pooled Wilson interval beside them, answer types A-D and nothing felt, chance "
        "levels, a confusion matrix, per-pin accuracy, apparent motion, and a mixed-effects "
        "logistic fit of the frequency effect when there are enough subjects; for adaptive "
        "designs, thresholds (each procedure's estimate and a Bayesian "
        "psychometric fit per subject, their across-subject means) in thresholds.csv with "
        "staircase tracks and fitted functions. Runs whose "
        "manifest is not 'completed', or with no counted trial, are listed and left out. "
        "Writes CSV tables, PNG and PDF figures and summary.md.",
    )
    parser.add_argument("results", nargs="+", metavar="RESULTS",
                        help="beh.tsv files, or folders searched recursively for *_beh.tsv")
    parser.add_argument("--out", default="analysis", metavar="DIR",
                        help="folder for the tables, figures and summary (default: analysis)")
    parser.add_argument("--include-incomplete", action="store_true",
                        help="also count runs whose manifest says running, aborted or crashed")
    parser.add_argument("--skip-damaged", action="store_true",
                        help="go on without results files that cannot be read (each is named "
                        "with the reason); by default they stop the analysis")
    parser.add_argument("--interval", choices=("bootstrap", "t"), default="bootstrap",
                        help="across-subject interval of figures and tables (default: "
                        "bootstrap, which stays within 0-100 %%; t is not bounded and is "
                        "given beside the bootstrap)")
    parser.add_argument("--bootstrap-seed", type=common.seed, default=None, metavar="N",
                        help="seed of the subject bootstrap (default: 20240501; recorded)")
    parser.add_argument("--bootstrap-resamples", type=common.count(100, MAX_RESAMPLES), default=None,
                        metavar="N", help="bootstrap resamples (default: 10000)")
    parser.add_argument("--answer-pins", type=common.counts(1, MAX_PINS, MAX_PINS), default=None,
                        metavar="LIST",
                        help="pins a subject could name, e.g. 1,4,6,7 (default: every pin of "
                        "the grid); sets the chance levels")
    parser.add_argument("--no-figures", action="store_true",
                        help="tables and summary.md only, no PNG or PDF figures (drawing them "
                        "takes most of the time of a small study)")
    parser.set_defaults(func=_cmd_analyse)

    power = subparsers.add_parser(
        "power",
        help="how many subjects a protocol needs: power curves from simulated subjects",
        description="Simulate whole studies of a protocol with the simulated observer "
        "(between-subject spread included) for several numbers of subjects, analyse each as "
        "`pinarray analyse` would (subjects as the unit), and report how often each effect "
        "is found. Writes power.csv, power_curves.png/.pdf and prints the table.",
    )
    power.add_argument("protocol", metavar="PROTOCOL", help="a localisation or motion protocol")
    power.add_argument("--observer", default="default", metavar="MODEL",
                       help="the simulated population ('default' or name=value overrides, "
                       "e.g. subject_sd_logit=1)")
    power.add_argument("--subjects", type=common.counts(2, MAX_SUBJECTS, MAX_SUBJECT_COUNTS),
                       default=[4, 6, 8, 12, 16, 24], metavar="LIST",
                       help="numbers of subjects to try (default: 4,6,8,12,16,24)")
    power.add_argument("--studies", type=common.count(10, MAX_STUDIES), default=400, metavar="N",
                       help="simulated studies per number of subjects (default: 400)")
    power.add_argument("--seed", type=common.seed, default=1, metavar="N",
                       help="seed of the simulation (default: 1; recorded)")
    power.add_argument("--out", default="power", metavar="DIR",
                       help="folder for power.csv and the figure (default: power)")
    power.set_defaults(func=_cmd_power)


def _cmd_analyse(args: argparse.Namespace) -> int:
    import math
    import sys
    from pathlib import Path

    from pinarray.analysis.load import scan, select_runs
    from pinarray.analysis.report import run_lines, write_report
    from pinarray.analysis.run_files import at_its_place, raw_data_holding
    from pinarray.analysis.study import study
    from pinarray.analysis.subjects import (
        DEFAULT_BOOTSTRAP_RESAMPLES,
        DEFAULT_BOOTSTRAP_SEED,
        IntervalMethod,
        IntervalSettings,
    )
    from pinarray.analysis.tables import significant
    from pinarray.analysis.thresholds import interval_name
    from pinarray.errors import ResultsError

    settings = IntervalSettings(
        IntervalMethod(args.interval),
        bootstrap_seed=DEFAULT_BOOTSTRAP_SEED if args.bootstrap_seed is None
        else args.bootstrap_seed,
        bootstrap_resamples=DEFAULT_BOOTSTRAP_RESAMPLES if args.bootstrap_resamples is None
        else args.bootstrap_resamples,
    )
    scanned = scan(args.results)
    loaded, damaged = list(scanned.runs), scanned.damaged
    for line in scanned.passed_over:  # copies of a run: each said before anything else
        print(f"pinarray: {line}", file=sys.stderr)
    reasons = [d.reason for d in damaged]
    if damaged and not args.skip_damaged:
        raise ResultsError("\n".join([*reasons, f"{len(damaged)} damaged results file(s); "
                                      "--skip-damaged analyses the rest without them"]))
    for reason in reasons:
        print(f"pinarray: {reason} (skipped)", file=sys.stderr)
    if not loaded:
        raise ResultsError("no results left to analyse: every results file found is damaged "
                           "or passed over")
    inside = raw_data_holding(Path(args.out), {run.paths.root for run in loaded
                                               if at_its_place(run.paths, run.source)})
    if inside:
        raise ResultsError(f"{args.out}: expected a report folder outside the raw data, found "
                           f"one in {inside}; write it elsewhere (a BIDS dataset keeps it in "
                           "derivatives/)")
    runs = select_runs(loaded, args.include_incomplete)
    result = study(runs, settings, args.answer_pins)
    try:
        report = write_report(result, Path(args.out), figures=not args.no_figures)
    except OSError as problem:
        raise ResultsError(f"{problem.filename or args.out}: cannot write the report there: "
                           f"{problem.strerror}") from None
    counted = [f.counted() for f in result.findings]
    trials = (", ".join(counted[:-1]) + " and " + counted[-1] if len(counted) > 1
              else counted[0] if counted else "no trials")
    print(f"counted {len(runs.included)} run(s): {len(result.subjects)} subject(s), "
          f"{trials} (main trials with status ok)")
    for line in run_lines(runs):
        print(f"  {line}")
    for run in loaded:
        if run.torn:
            print(f"  {run.source}: its last row was cut short by an interrupted write and is "
                  f"left out ({len(run.torn)} characters)")
    method = settings.method
    for found in result.findings:
        for line in found.lines():
            print(line)
    if result.thresholds.found:
        print(f"thresholds, mean of per-subject thresholds [{interval_name(settings)}] "
              "(each subject's in thresholds.csv):")
        for t in result.thresholds.across:
            low, high = t.interval(method)
            interval = ("n/a, fewer than two subjects" if math.isnan(low)
                        else f"{significant(low)}-{significant(high)}")
            print(f"  {t.task} {t.adapted_parameter} {t.method} ({t.procedure}): {significant(t.mean)} "
                  f"[{interval}] ({t.subjects} subj., {t.n_trials} trials)")
    print(f"summary: {report.summary}")
    return 0


def _cmd_power(args: argparse.Namespace) -> int:
    from pathlib import Path

    from pinarray.analysis.power import power_seconds, power_study, write_power
    from pinarray.analysis.seam import analysis_of
    from pinarray.errors import PinArrayError, ResultsError
    from pinarray.protocol.load import load_protocol

    protocol = load_protocol(args.protocol)
    if protocol.design.adaptive is not None:
        return _check_procedures(protocol, args)
    name = protocol.design.paradigm.name
    model = analysis_of(name).power(protocol, args.observer)
    if model is None:
        raise PinArrayError(f"{protocol.source}: power simulates the designs whose paradigm "
                            f"says how (localisation, apparent motion), and adaptive ones; "
                            f"not a fixed {name} design")
    common.check_output_folder(args.out, POWER_FILES)  # before the work, not after
    counts = sorted(args.subjects)
    seconds = power_seconds(model, counts, args.studies)
    common.refuse_long_work(
        f"power: {args.studies:,} studies for each of {len(counts)} numbers of subjects "
        f"({sum(counts):,} simulated subjects a round)", seconds, MAX_POWER_S,
        "fewer --studies, fewer or smaller --subjects")
    print(f"{protocol.name}: {args.studies} simulated studies per number of subjects, "
          f"subject SD {model.subject_sd:g} logit, seed {args.seed}")
    curves = power_study(protocol.name, model, counts, args.studies, args.seed,
                         common.progress("power: simulated subjects",
                                         args.studies * sum(counts), seconds))
    try:
        paths = write_power(curves, Path(args.out))
    except OSError as problem:
        raise ResultsError(f"{problem.filename or args.out}: cannot write there: "
                           f"{problem.strerror}") from None
    for line in curves.table_lines():
        print(line)
    print("written: " + ", ".join(str(p) for p in paths))
    return 0


def _check_procedures(protocol: Protocol, args: argparse.Namespace) -> int:
    """``pinarray power`` on an adaptive design: its procedures run by simulated subjects of
    the --observer function, one per --studies; a table and procedure_check.csv."""
    import csv
    from pathlib import Path

    from pinarray.analysis.adaptive_subject import parse_psychometric
    from pinarray.analysis.procedure_check import check_procedures, check_seconds, check_table
    from pinarray.errors import ResultsError

    adaptive = protocol.design.adaptive
    assert adaptive is not None
    function = parse_psychometric(args.observer, adaptive)
    common.check_output_folder(args.out, ("procedure_check.csv",))  # before the work
    seconds = check_seconds(adaptive, args.studies)
    common.refuse_long_work(
        f"power: {args.studies:,} simulated subjects (--studies) running {len(adaptive.procedures)} "
        f"procedure(s) to their trial limits", seconds, MAX_POWER_S,
        "fewer --studies, or a design with smaller QUEST+ grids (values, thresholds, slopes, "
        "lapse_rates) or lower stop_after_trials")
    unit = adaptive.parameter.unit
    print(f"{protocol.name}: {len(adaptive.procedures)} procedure(s) adapting "
          f"{adaptive.parameter.value}, each run by {args.studies} simulated subjects (--studies) "
          f"of a {function.kind} with threshold {function.threshold:g} {unit}, slope "
          f"{function.slope:g}, guess {function.guess:g}, lapse {function.lapse:g}; seed {args.seed}")
    checks = check_procedures(adaptive, function, args.studies, args.seed,
                              common.progress("power: simulated subjects", args.studies, seconds))
    out = Path(args.out) / "procedure_check.csv"
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        with open(out, "w", newline="", encoding="utf-8") as handle:
            table = csv.writer(handle)
            table.writerow(["procedure", "truth", "truth_is", "unit", "bias", "sd", "low_2.5",
                            "high_97.5", "subjects", "without_estimate", "trials_median",
                            "trials_min", "trials_max"])
            for c in checks:
                t = sorted(c.trials)
                table.writerow([c.name, c.truth, c.truth_is, unit, c.bias, c.sd, *c.interval(),
                                len(t), c.no_estimate, t[len(t) // 2], t[0], t[-1]])
    except OSError as problem:
        raise ResultsError(f"{problem.filename or args.out}: cannot write there: "
                           f"{problem.strerror}") from None
    for line in check_table(checks, unit):
        print(line)
    print(f"written: {out}")
    return 0
