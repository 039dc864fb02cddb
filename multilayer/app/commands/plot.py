"""Draw the figures of a run, a calibration or a sensitivity study into DIR/plots/.

DIR holding result.nc: the run's figures (docs/results.md); calibration.nc: misfit
history, parameter pairs and observed against fitted values; sensitivity.nc: the Sobol'
indices (docs/calibration.md).
Example: multilayer plot results/erodible-bed-collapse
"""

from __future__ import annotations

import argparse
from pathlib import Path

from multilayer.app.commands import positive_int

HELP = "draw PNG figures of DIR/result.nc (or calibration.nc, sensitivity.nc) into DIR/plots/"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``multilayer plot``."""
    parser.add_argument(
        "directory",
        metavar="DIR",
        type=Path,
        help="output directory of 'multilayer run', 'calibrate' or 'sensitivity'",
    )
    parser.add_argument(
        "--times",
        type=positive_int,
        default=4,
        metavar="N",
        help="number of times in the X-Z section figure (default 4)",
    )


def main(args: argparse.Namespace) -> int:
    """Write the figures and list them."""
    from multilayer.app.calibration import CALIBRATION_FILE
    from multilayer.app.sensitivity import SENSITIVITY_FILE

    studies = [name for name in (CALIBRATION_FILE, SENSITIVITY_FILE) if (args.directory / name).is_file()]
    if studies:
        from multilayer.io.study_plotting import plot_study

        paths = [path for name in studies for path in plot_study(args.directory, name)]
    else:
        from multilayer.io.plotting import plot_run

        paths = plot_run(args.directory, times=args.times)
    for path in paths:
        print(path)
    return 0
