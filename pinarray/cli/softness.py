"""The ``pinarray softness ...`` subcommands: print a table, optionally write a PNG.

Every subcommand takes ``--png PATH`` (that file) or ``--out DIR`` (``DIR/<subcommand>.png``).
Numbers on the command line are in the lab's units (mm, kPa, N, cm for the seed's fits);
each handler converts them to SI before calling the models.
"""

import argparse


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``softness`` and its subcommands to the `pinarray` parser."""
    softness = subparsers.add_parser(
        "softness", help="softness display models: Hertz contact, TF/CASR display, control"
    )
    sub = softness.add_subparsers(dest="softness_command", metavar="MODEL", required=True)

    p = _add(sub, "hertz", "contact area, approach and pressure of a Hertz contact")
    p.add_argument("--radius-mm", type=float, default=10.0, help="radius of the body (mm)")
    p.add_argument("--young-kpa", type=float, default=75.0, help="Young's modulus (kPa)")
    p.add_argument("--poisson", type=float, default=0.5)
    p.add_argument("--radius2-mm", type=float, default=float("inf"), help="default: flat")
    p.add_argument("--young2-kpa", type=float, default=float("inf"), help="default: rigid")
    p.add_argument("--poisson2", type=float, default=0.5)
    p.add_argument("--max-force-n", type=float, default=10.0)
    p.add_argument("--rows", type=int, default=11)

    p = _add(sub, "telescopic", "the stepped force of the telescopic display")
    p.add_argument("--central-area-mm2", type=float, default=20.0)
    p.add_argument("--area-ratio", type=float, default=1.5)
    p.add_argument("--step-mm", type=float, default=1.0)
    p.add_argument("--cylinders", type=int, default=6)
    p.add_argument("--pressure-kpa", type=float, default=20.0)
    p.add_argument("--match-young-kpa", type=float, help="also give pressures to mimic a tissue")
    p.add_argument("--match-radius-mm", type=float, default=10.0)

    p = _add(sub, "display", "force of the TF/CASR cone display, F = p A(z)")
    p.add_argument("--pressure-kpa", type=float, nargs="+", default=[10.0, 20.0, 40.0])
    p.add_argument("--rows", type=int, default=11)
    p.add_argument("--force-n", type=float, help="solve for this force (needs one of the next)")
    p.add_argument("--indentation-mm", type=float, help="with --force-n: pressure needed here")

    p = _add(sub, "fit", "least-squares force/area or force/displacement fit")
    p.add_argument("--csv", help="header area_cm2,force_n (or _m2/_mm2) or displacement_cm,...")
    p.add_argument("--noise-n", type=float, default=0.05, help="without --csv: noise on eq. 9.4")
    p.add_argument("--seed", type=int, default=1)

    p = _add(sub, "track", "combined CASR + DHD control on a force ramp (Figs. 9.9/9.10)")
    p.add_argument("--alpha-n-per-cm4", type=float, default=1.4, help="default: eq. 9.4")
    p.add_argument("--beta-cm-per-n", type=float, default=1 / 23, help="default: eq. 9.5")
    p.add_argument("--peak-force-n", type=float, default=2.0)
    p.add_argument("--duration-s", type=float, default=2.0)
    p.add_argument("--time-step-ms", type=float, default=1.0)
    p.add_argument("--valve-min-kpa", type=float, default=0.0)
    p.add_argument("--valve-max-kpa", type=float, default=100.0)
    p.add_argument("--valve-lag-ms", type=float, default=20.0)
    p.add_argument("--dhd-lag-ms", type=float, default=10.0)
    p.add_argument("--rows", type=int, default=11)

    p = _add(sub, "forceps", "forceps samples -> modulus -> force/area -> pressure")
    p.add_argument("--csv", help="header displacement_mm,force_n; default: synthetic tissue")
    p.add_argument("--radius-mm", type=float, default=10.0, help="tissue curvature radius")
    p.add_argument("--poisson", type=float, default=0.5)
    p.add_argument("--constant-modulus", action="store_true", help="no strain dependence")
    p.add_argument("--rows", type=int, default=11)


def _add(sub, name: str, help_text: str) -> argparse.ArgumentParser:
    parser = sub.add_parser(name, help=help_text, description=help_text)
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--png", metavar="PATH", help="write the plot to this PNG file")
    where.add_argument("--out", metavar="DIR", help=f"write the plot to DIR/{name}.png")
    parser.set_defaults(func=_later(name), plot_name=name)
    return parser


def _later(name: str):
    """The handler ``name`` of `pinarray.cli.softness_handlers`, imported only when it runs."""

    def run(args: argparse.Namespace) -> int:
        from pinarray.cli import softness_handlers

        return getattr(softness_handlers, name)(args)

    return run
