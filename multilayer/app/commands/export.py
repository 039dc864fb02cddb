"""Export a run for ParaView: one VTK structured grid per output time in DIR/vtk/.

Open DIR/vtk/result.pvd in ParaView for the whole time series (docs/results.md).
Example: multilayer export results/erodible-bed-collapse --vtk
"""

from __future__ import annotations

import argparse

from multilayer.app.commands import RUN_DIRECTORY, directory, not_a_file
from multilayer.errors import InputError, printable, warn

HELP = "export DIR/result.nc to other formats (--vtk: ParaView)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``multilayer export``."""
    parser.add_argument(
        "directory", metavar="DIR", type=directory, help="output directory of 'multilayer run'"
    )
    parser.add_argument(
        "--vtk", action="store_true", help="VTK XML structured grids (.vts) and a .pvd time series"
    )


def main(args: argparse.Namespace) -> int:
    """Write the requested formats and list the index files."""
    from multilayer.io.export import export_vtk

    if not args.vtk:
        raise InputError("multilayer export: choose a format; accepted: --vtk")
    paths, end = export_vtk(not_a_file(args.directory, RUN_DIRECTORY))
    print(printable(f"{paths[0]} ({len(paths) - 1} output times)"))
    if end:
        warn(f"{end}; exported up to its last output time")
    return 0
