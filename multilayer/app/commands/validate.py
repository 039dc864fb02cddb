"""Check scenario files without running them (exit 2 if any is invalid).

Every file is checked; each invalid one gets one message naming the file, the key path,
the YAML line and what is accepted.  The memory and output size of each run are
estimated and checked against the budget, as `multilayer run` does, and every ``expect:``
comparison with an exact solution must apply to the file, as `multilayer check` requires.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from multilayer import scenario as scenarios
from multilayer.app import expectations, factory, resources
from multilayer.app.commands import add_budget_arguments, add_set_argument, budget
from multilayer.engine import initial_state
from multilayer.errors import InputError

HELP = "check scenario files without running them"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``multilayer validate``."""
    parser.add_argument("files", metavar="FILE", nargs="+", help="scenario YAML files")
    add_set_argument(parser, "override a key in every file, as for 'multilayer run'")
    add_budget_arguments(parser)


def main(args: argparse.Namespace) -> int:
    """Validate every file; print 'ok' lines on stdout and errors on stderr."""
    invalid = 0
    for path in args.files:
        try:
            scenario = scenarios.load(path, args.overrides)
            limits = budget(args)
            need = resources.check(scenario, scenario.output.directory or Path("results"), limits)
            dom = scenario.domain
            dx = (dom.x_max - dom.x_min) / dom.cells
            entries = factory.initial_entries(scenario)
            initial_state.check_entries(entries, dom.x_min, dom.x_max, dx, str(path))
            steps = resources.check_steps(scenario, limits)
            expectations.validate(scenario)
        except InputError as exc:
            print(f"multilayer: error: {exc}", file=sys.stderr)
            invalid += 1
            continue
        domain = scenario.domain
        print(
            f"{path}: ok ({scenario.name}: {domain.cells} cells x {domain.layers} layers, "
            f"rheology {scenario.rheology.name}, t_end = {scenario.time.end:g} s; about "
            f"{resources.size_text(need.memory)} of memory, {need.records:.0f} output times, "
            f"result.nc about {resources.size_text(need.output)}, about {steps.count:.2g} time steps "
            f"(--max-steps {limits.step_limit:.3g}))"
        )
    return 2 if invalid else 0
