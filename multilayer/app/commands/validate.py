"""Check scenario files without running them (exit 2 if any is invalid).

Every file is checked; each invalid one gets one message naming the file, the key path,
the YAML line and what is accepted.
"""

from __future__ import annotations

import argparse
import sys

from multilayer.errors import InputError
from multilayer.io import scenario as scenarios

HELP = "check scenario files without running them"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``multilayer validate``."""
    parser.add_argument("files", metavar="FILE", nargs="+", help="scenario YAML files")
    parser.add_argument(
        "--set",
        dest="overrides",
        metavar="KEY=VALUE",
        action="append",
        default=[],
        help="override a key in every file, as for 'multilayer run'",
    )


def main(args: argparse.Namespace) -> int:
    """Validate every file; print 'ok' lines on stdout and errors on stderr."""
    invalid = 0
    for path in args.files:
        try:
            scenario = scenarios.load(path, args.overrides)
        except InputError as exc:
            print(f"multilayer: error: {exc}", file=sys.stderr)
            invalid += 1
            continue
        domain = scenario.domain
        print(
            f"{path}: ok ({scenario.name}: {domain.cells} cells x {domain.layers} layers, "
            f"rheology {scenario.rheology.name}, t_end = {scenario.time.end:g} s)"
        )
    return 2 if invalid else 0
