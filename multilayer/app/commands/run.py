"""Run a scenario and write DIR/result.nc (plus run.log and a checkpoint for --resume).

DIR is -o/--output, else the scenario's output.directory, else results/<name>.
Example: multilayer run scenarios/erodible_bed_collapse.yaml --set domain.cells=200
"""

from __future__ import annotations

import argparse
from pathlib import Path

from multilayer import scenario as scenarios
from multilayer.app.commands import add_budget_arguments, add_output_argument, add_set_argument, budget

HELP = "run a scenario file and write DIR/result.nc"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``multilayer run``."""
    parser.add_argument("scenario", metavar="SCENARIO", help="scenario YAML file")
    add_output_argument(parser, "output.directory, else results/<name>")
    add_set_argument(
        parser,
        "override a scenario key, e.g. --set domain.cells=200 "
        "or --set initial.0.thickness=0.005 (value read as YAML; repeatable)",
    )
    parser.add_argument(
        "--resume", action="store_true", help="continue an interrupted run from the checkpoint in DIR"
    )
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress line and no summary")
    add_budget_arguments(parser)


def main(args: argparse.Namespace) -> int:
    """Validate the scenario, run it, print the summary."""
    from multilayer.app import runner  # the engine is imported only to run

    scenario = scenarios.load(args.scenario, args.overrides)
    outdir = args.output or scenario.output.directory or Path("results") / scenario.name
    summary = runner.run(
        scenario, outdir, resume=args.resume, quiet=True if args.quiet else None, budget=budget(args)
    )
    if not args.quiet:
        print(f"{scenario.name}: wrote {Path(outdir) / 'result.nc'}")
        for key, value in summary.items():
            print(f"  {key} = {value:.6g}" if isinstance(value, float) else f"  {key} = {value}")
    return 0
