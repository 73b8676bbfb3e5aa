"""The ``pinarray softness ...`` subcommands: print a table, optionally write a PNG.

Every subcommand takes ``--png PATH`` (that file) or ``--out DIR`` (``DIR/<subcommand>.png``).
Numbers on the command line are in the lab's units (mm, kPa, N, cm for the seed's fits);
each handler converts them to SI before calling the models.
"""

import argparse

from pinarray.cli import common

# No quantity here (mm, mm^2, kPa, N, ms, s) comes near 1e9 in a lab; past it the models'
# floating-point results overflow. NaN is refused everywhere, +inf only where it means
# something (a flat or rigid second body).
MAX_MAGNITUDE = 1e9
_real = common.number(-MAX_MAGNITUDE, MAX_MAGNITUDE)
_real_or_inf = common.number(-MAX_MAGNITUDE, MAX_MAGNITUDE, infinite=True)
_rows = common.count(2, 10_000)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``softness`` and its subcommands to the `pinarray` parser.

    Every option's help gives its unit (or says it has none) and its default.
    """
    softness = subparsers.add_parser(
        "softness", help="softness display models: Hertz contact, TF/CASR display, control"
    )
    sub = softness.add_subparsers(dest="softness_command", metavar="MODEL", required=True)

    p = _add(sub, "hertz", "contact area, approach and pressure of a Hertz contact")
    p.add_argument("--radius-mm", type=_real, default=10.0,
                   help="radius of curvature of the body (mm); default: %(default)s")
    p.add_argument("--young-kpa", type=_real, default=75.0,
                   help="Young's modulus of the body (kPa); default: %(default)s")
    p.add_argument("--poisson", type=_real, default=0.5,
                   help="Poisson's ratio of the body, in (-1, 0.5] (dimensionless); "
                        "default: %(default)s, incompressible")
    p.add_argument("--radius2-mm", type=_real_or_inf, default=float("inf"),
                   help="radius of curvature of the second body (mm); default: %(default)s, flat")
    p.add_argument("--young2-kpa", type=_real_or_inf, default=float("inf"),
                   help="Young's modulus of the second body (kPa); default: %(default)s, rigid")
    p.add_argument("--poisson2", type=_real, default=0.5,
                   help="Poisson's ratio of the second body (dimensionless); default: %(default)s")
    p.add_argument("--max-force-n", type=_real,
                   help="largest force in the table (N); default: the force that makes the "
                        "contact radius 0.1 R, the edge of Hertz's "
                        "small-contact range")
    p.add_argument("--rows", type=_rows, default=11,
                   help="rows of the table, forces evenly spaced from 0 (a count); "
                        "default: %(default)s")

    p = _add(sub, "telescopic", "the stepped force of the telescopic display")
    p.add_argument("--central-area-mm2", type=_real, default=20.0,
                   help="contact area of the central cylinder (mm^2); default: %(default)s")
    p.add_argument("--area-ratio", type=_real, default=1.5,
                   help="each cylinder's contact area over the one inside it, > 1 "
                        "(dimensionless); default: %(default)s")
    p.add_argument("--step-mm", type=_real, default=1.0,
                   help="indentation between one cylinder's contact and the next (mm); "
                        "default: %(default)s")
    p.add_argument("--cylinders", type=common.count(1, 1000), default=6,
                   help="number of cylinders (a count); default: %(default)s")
    p.add_argument("--pressure-kpa", type=_real, default=20.0,
                   help="pressure inside the display (kPa); default: %(default)s")
    p.add_argument("--match-young-kpa", type=_real,
                   help="also give the pressures that mimic a tissue of this Young's modulus "
                        "(kPa); default: none")
    p.add_argument("--match-radius-mm", type=_real, default=10.0,
                   help="with --match-young-kpa: the tissue's radius of curvature (mm); "
                        "default: %(default)s")

    p = _add(sub, "display", "force of the TF/CASR cone display, F = p A(z)")
    p.add_argument("--pressure-kpa", type=_real, nargs="+", default=[10.0, 20.0, 40.0],
                   metavar="KPA", help="pressures inside the display (kPa); default: 10 20 40")
    p.add_argument("--rows", type=_rows, default=11,
                   help="rows of the table, indentations evenly spaced from 0 (a count); "
                        "default: %(default)s")
    p.add_argument("--force-n", type=_real,
                   help="solve for this force (N): the indentation at each pressure, or with "
                        "--indentation-mm the pressure; default: none, print the table")
    p.add_argument("--indentation-mm", type=_real,
                   help="with --force-n: the indentation at which to deliver it (mm); "
                        "default: none")

    p = _add(sub, "fit", "least-squares force/area or force/displacement fit")
    p.add_argument("--csv", help="samples with a header area_cm2,force_n (or _m2/_mm2) or "
                                 "displacement_cm,force_n (or _m/_mm); default: eq. 9.4 sampled")
    p.add_argument("--noise-n", type=_real, default=0.05,
                   help="without --csv: noise added to eq. 9.4 (N); default: %(default)s")
    p.add_argument("--seed", type=common.seed, default=1,
                   help="without --csv: seed of the noise (a whole number); default: %(default)s")

    p = _add(sub, "track", "combined CASR + DHD control on a force ramp (Figs. 9.9/9.10)")
    p.add_argument("--alpha-n-per-cm4", type=_real, default=1.4,
                   help="alpha in the material's F = alpha A^2 (N/cm^4); default: %(default)s, "
                        "eq. 9.4")
    p.add_argument("--beta-cm-per-n", type=_real, default=1 / 23,
                   help="beta in the material's z = beta F (cm/N); default: 1/23 "
                        "(%(default).4g), eq. 9.5")
    p.add_argument("--peak-force-n", type=_real, default=2.0,
                   help="force at the end of the ramp (N); default: %(default)s")
    p.add_argument("--duration-s", type=_real, default=2.0,
                   help="duration of the ramp (s); default: %(default)s")
    p.add_argument("--time-step-ms", type=_real, default=1.0,
                   help="simulation step (ms); default: %(default)s")
    p.add_argument("--valve-min-kpa", type=_real, default=0.0,
                   help="lowest pressure the valve holds (kPa); default: %(default)s")
    p.add_argument("--valve-max-kpa", type=_real, default=100.0,
                   help="highest pressure the valve holds (kPa); default: %(default)s")
    p.add_argument("--valve-lag-ms", type=_real, default=20.0,
                   help="time constant of the valve's pressure (ms); default: %(default)s")
    p.add_argument("--dhd-lag-ms", type=_real, default=10.0,
                   help="time constant of the DHD's position loop (ms); default: %(default)s")
    p.add_argument("--rows", type=_rows, default=11,
                   help="rows of the table, evenly spaced in time (a count); default: %(default)s")

    p = _add(sub, "forceps", "forceps samples -> modulus -> force/area -> pressure")
    p.add_argument("--csv", help="samples with a header displacement_mm,force_n (or _m/_cm); "
                                 "default: a synthetic tissue")
    p.add_argument("--radius-mm", type=_real, default=10.0,
                   help="radius of curvature of the tissue (mm); default: %(default)s")
    p.add_argument("--poisson", type=_real, default=0.5,
                   help="Poisson's ratio of the tissue, in (-1, 0.5] (dimensionless); "
                        "default: %(default)s, incompressible")
    p.add_argument("--constant-modulus", action="store_true",
                   help="fit a modulus that does not change with strain; default: it may")
    p.add_argument("--rows", type=_rows, default=11,
                   help="rows of the table, areas evenly spaced from 0 (a count); "
                        "default: %(default)s")


def _add(sub, name: str, help_text: str) -> argparse.ArgumentParser:
    parser = sub.add_parser(name, help=help_text, description=help_text)
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--png", metavar="PATH",
                       help="write the plot to this PNG file; default: no plot")
    where.add_argument("--out", metavar="DIR",
                       help=f"write the plot to DIR/{name}.png; default: no plot")
    parser.set_defaults(func=_later(name), plot_name=name)
    return parser


def _later(name: str):
    """The handler ``name`` of `pinarray.cli.softness_handlers`, imported only when it runs."""

    def run(args: argparse.Namespace) -> int:
        from pinarray.cli import softness_handlers
        from pinarray.cli.common import png_path
        from pinarray.errors import PinArrayError

        if args.png:
            png_path(args.png)  # a folder is refused before the table is printed
        try:
            return getattr(softness_handlers, name)(args)
        except OSError as problem:  # the plot (or its folder) could not be written
            raise PinArrayError(f"{problem.filename or args.png or args.out}: cannot write: "
                                f"{problem.strerror}") from None

    return run
