"""Run a scenario and write DIR/result.nc (plus run.log and a checkpoint for --resume).

DIR is -o/--output, else the scenario's output.directory, else results/<name>.
Example: multilayer run scenarios/erodible_bed_collapse.yaml --set domain.cells=200
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from multilayer import scenario as scenarios
from multilayer.app.commands import (
    add_budget_arguments,
    add_output_argument,
    add_set_argument,
    budget,
    file_path,
)
from multilayer.errors import printable

HELP = "run a scenario file and write DIR/result.nc"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``multilayer run``."""
    parser.add_argument("scenario", metavar="SCENARIO", type=file_path, help="scenario YAML file")
    add_output_argument(parser, "output.directory, else results/<name>")
    add_set_argument(
        parser,
        "override a scenario key, e.g. --set domain.cells=200 "
        "or --set initial.0.thickness=0.005 (value read as YAML; repeatable)",
    )
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue an interrupted run from the checkpoint in DIR; with a later time.end, extend a "
        "finished one (the uninterrupted run to the bit if it ended on an output time)",
    )
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress line and no summary")
    add_budget_arguments(parser)


def main(args: argparse.Namespace) -> int:
    """Validate the scenario, run it, print the summary."""
    from multilayer.app import runner  # the engine is imported only to run
    from multilayer.plugins.host import printing_to_stderr

    scenario = scenarios.load(args.scenario, args.overrides)
    outdir = args.output or scenario.output.directory or Path("results") / scenario.name
    with printing_to_stderr():  # the summary is stdout's: what a law prints as it runs is not
        summary = runner.run(
            scenario, outdir, resume=args.resume, quiet=True if args.quiet else None, budget=budget(args)
        )
    if not args.quiet:
        print(printable(f"{scenario.name}: wrote {Path(outdir) / 'result.nc'}"))
        for line in summary_lines(summary, scenario.numerics.front_threshold):
            print(f"  {line}")
    return 0


def summary_lines(summary: dict[str, float], threshold: float) -> list[str]:
    """The run summary, one ``key = value unit`` line each; a quantity that has no value
    (no material above the front threshold at the end, a single output time, a mixture's
    force) says why."""
    from multilayer.io.results import MIXTURE_SUMMARY_KEYS, SUMMARY_UNITS

    none = f"no cell thicker than the front threshold ({threshold:g} m) at the end"
    if MIXTURE_SUMMARY_KEYS[0] in summary:  # a mixture's result holds no forces (docs/mixture.md)
        single = "not computed for a grain-fluid mixture"
    else:
        single = "a single output time: no interval to average the force over"
    why = {
        "front_final": none,
        "runout": none,
        "static_interface_mean_final": none,
        "peak_seismic_force_x": single,
        "peak_seismic_force_z": single,
    }
    lines = []
    for key, value in summary.items():
        text = f"{value:.6g}" if isinstance(value, float) else f"{value}"
        unit = f" {SUMMARY_UNITS[key]}" if SUMMARY_UNITS.get(key) else ""
        note = f" ({why[key]})" if isinstance(value, float) and math.isnan(value) and key in why else ""
        lines.append(f"{key} = {text}{unit}{note}")
    return lines
