"""Draw the figures of a run, a calibration or a sensitivity study into DIR/plots/.

DIR holding result.nc: the run's figures (docs/results.md); calibration.nc: misfit
history, parameter pairs and observed against fitted values; sensitivity.nc: the Sobol'
indices (docs/calibration.md).

Examples:
  multilayer plot results/erodible-bed-collapse
  multilayer plot results/erodible-bed-collapse --at 0.2 --at 0.6 --format svg --animate
  multilayer plot results/erodible-bed-collapse --xlim -0.25 1.5
"""

from __future__ import annotations

import argparse
import os

from multilayer.app.commands import RUN_DIRECTORY, decimal, directory, not_a_file, positive_int
from multilayer.errors import InputError, printable, warn

HELP = (
    "draw figures (and an animation) of DIR/result.nc, or of calibration.nc / sensitivity.nc, into DIR/plots/"
)
FORMATS = ("png", "pdf", "svg")
"""File formats of the figures (Matplotlib writes each without extra software)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``multilayer plot``."""
    parser.add_argument(
        "directory",
        metavar="DIR",
        type=directory,
        help="output directory of 'multilayer run', 'calibrate' or 'sensitivity'",
    )
    parser.add_argument(
        "--times",
        type=positive_int,
        default=None,  # 4: None tells a --times given to a study's directory
        metavar="N",
        help="number of times in the X-Z section figure (default 4)",
    )
    parser.add_argument(
        "--at",
        type=decimal,
        action="append",
        default=[],
        metavar="X",
        help="downslope position (m) of a column for the u(z) and b(t) figures (repeatable; "
        "default: three columns spread over the material)",
    )
    parser.add_argument(
        "--xlim",
        type=decimal,
        nargs=2,
        metavar=("X0", "X1"),
        help="downslope range (m) of the X-Z section, its animation and the thickness figure "
        "(default: where the material moves, with a margin)",
    )
    parser.add_argument(
        "--format",
        dest="fmt",
        choices=FORMATS,
        default=None,  # png: None tells a --format given to a study's directory
        help="file format of the figures (default png)",
    )
    parser.add_argument(
        "--animate",
        action="store_true",
        help="also write the X-Z section over time: section.mp4 if ffmpeg is installed, else section.gif",
    )


def _matplotlib() -> None:
    """Import Matplotlib, naming the environment variable it refuses: ``MPLBACKEND`` naming
    no backend made its import raise (a traceback, exit 1), though the figures are drawn on
    the Agg canvas whatever backend it names."""
    try:
        import matplotlib  # noqa: F401
    except ValueError as exc:
        if "MPLBACKEND" not in os.environ:
            raise
        raise InputError(
            f"environment variable MPLBACKEND={os.environ['MPLBACKEND']!r}: Matplotlib refuses it ({exc}); "
            "accepted: one of those backends, or unset (multilayer draws its figures with Agg)"
        ) from None


def main(args: argparse.Namespace) -> int:
    """Write the figures and list them; say on stderr what could not be drawn."""
    _matplotlib()
    not_a_file(args.directory, f"{RUN_DIRECTORY}, `calibrate` or `sensitivity`")
    from multilayer.app.calibration import CALIBRATION_FILE
    from multilayer.app.sensitivity import SENSITIVITY_FILE
    from multilayer.io.results import RESULT_FILE

    studies = [name for name in (CALIBRATION_FILE, SENSITIVITY_FILE) if (args.directory / name).is_file()]
    if studies and (args.directory / RESULT_FILE).is_file():  # the study's figures were drawn, the run's not
        raise InputError(
            f"{args.directory}: holds {RESULT_FILE} (a run) and {' and '.join(studies)} (a study): which one "
            "to draw is not known; accepted: the directory of one run or of one study (a study's runs are "
            "in its members/ directory)"
        )
    options = {"--times": args.times, "--at": args.at, "--xlim": args.xlim, "--format": args.fmt}
    given = [name for name, value in options.items() if value not in (None, [])] + (
        ["--animate"] if args.animate else []
    )
    if studies and given:  # the study's figures are png: the options were ignored, exit 0
        raise InputError(
            f"{args.directory}: {' and '.join(studies)} is a study's file; {', '.join(given)} "
            "apply to a run's figures only; accepted: plot DIR alone for a study's figures (png)"
        )
    notes: list[str] = []
    if studies:
        from multilayer.io.study_plotting import plot_study

        drawn = [plot_study(args.directory, name) for name in studies]
        paths, notes = [p for d in drawn for p in d[0]], [n for d in drawn for n in d[1]]
    else:
        from multilayer.io.plotting import plot_run

        paths, notes = plot_run(
            args.directory,
            times=4 if args.times is None else args.times,
            at=args.at,
            fmt=args.fmt or "png",
            animate=args.animate,
            xlim=args.xlim,
        )
    for path in paths:
        print(printable(str(path)))
    for note in notes:
        warn(note)
    return 0
