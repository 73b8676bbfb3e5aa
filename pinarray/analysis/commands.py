"""``pinarray analyse``: tables, figures and a summary page from results files."""

import argparse


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``analyse`` to the `pinarray` parser."""
    parser = subparsers.add_parser(
        "analyse",
        help="tables, figures and a one-page summary from results files",
        description="Analyse beh.tsv results: correct localisation per frequency with 95 %% "
        "intervals, error types A-D, confusion matrix, per-pin accuracy, apparent motion; "
        "per subject and pooled. Writes CSV tables, PNG figures and summary.md.",
    )
    parser.add_argument("results", nargs="+", metavar="RESULTS",
                        help="beh.tsv files, or folders searched recursively for *_beh.tsv")
    parser.add_argument("--out", default="analysis", metavar="DIR",
                        help="folder for the tables, figures and summary (default: analysis)")
    parser.set_defaults(func=_cmd_analyse)


def _cmd_analyse(args: argparse.Namespace) -> int:
    from pathlib import Path

    from pinarray.analysis.load import load_results
    from pinarray.analysis.report import write_report
    from pinarray.analysis.stats import summarise_subjects

    trials = load_results(args.results)
    summaries = summarise_subjects((t.subject, t.record) for t in trials)
    sources = sorted({t.source for t in trials})
    try:
        page = write_report(summaries, sources, Path(args.out))
    except OSError as problem:
        from pinarray.errors import ResultsError

        raise ResultsError(f"{problem.filename or args.out}: cannot write the report there: "
                           f"{problem.strerror}") from None
    pooled = summaries[0]
    print(f"{len(trials)} trial rows from {len(sources)} file(s), "
          f"{len(pooled.subjects)} subject(s)")
    for row in pooled.localisation:
        print(f"  {row.frequency_hz:g} Hz: {row.correct.pct:.1f} % correct of {row.trials}")
    if pooled.motion.felt.trials:
        print(f"  motion felt {pooled.motion.felt.pct:.0f} %, direction right "
              f"{pooled.motion.direction_right.pct:.0f} % of those")
    print(f"summary: {page}")
    return 0
