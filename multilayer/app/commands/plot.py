"""Draw the figures of a run into DIR/plots/ (docs/results.md lists them).

Examples:
  multilayer plot results/erodible-bed-collapse
  multilayer plot results/erodible-bed-collapse --at 0.2 --at 0.6 --format svg --animate
"""

from __future__ import annotations

import argparse
from pathlib import Path

from multilayer.app.commands import positive_int

HELP = "draw figures (and an animation) of DIR/result.nc into DIR/plots/"
FORMATS = ("png", "pdf", "svg")
"""File formats of the figures (Matplotlib writes each without extra software)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``multilayer plot``."""
    parser.add_argument("directory", metavar="DIR", type=Path, help="output directory of 'multilayer run'")
    parser.add_argument(
        "--times",
        type=positive_int,
        default=4,
        metavar="N",
        help="number of times in the X-Z section figure (default 4)",
    )
    parser.add_argument(
        "--at",
        type=float,
        action="append",
        default=[],
        metavar="X",
        help="downslope position (m) of a column for the u(z) and b(t) figures (repeatable; "
        "default: three columns spread over the material)",
    )
    parser.add_argument(
        "--format",
        dest="fmt",
        choices=FORMATS,
        default="png",
        help="file format of the figures (default png)",
    )
    parser.add_argument(
        "--animate",
        action="store_true",
        help="also write the X-Z section over time: section.mp4 if ffmpeg is installed, else section.gif",
    )


def main(args: argparse.Namespace) -> int:
    """Write the figures and list them."""
    from multilayer.io.plotting import plot_run

    for path in plot_run(args.directory, times=args.times, at=args.at, fmt=args.fmt, animate=args.animate):
        print(path)
    return 0
