"""Draw the figures of a run into DIR/plots/ (docs/results.md lists them).

Example: multilayer plot results/erodible-bed-collapse
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from multilayer.app.commands import positive_int

HELP = "draw PNG figures of DIR/result.nc into DIR/plots/"


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


def main(args: argparse.Namespace) -> int:
    """Write the figures and list them; say on stderr what could not be drawn."""
    from multilayer.io.plotting import plot_run

    paths, notes = plot_run(args.directory, times=args.times)
    for path in paths:
        print(path)
    for note in notes:
        print(f"multilayer: warning: {note}", file=sys.stderr)
    return 0
