"""Check scenario, sweep and study files without running them (exit 2 if any is invalid).

Every file is checked; each invalid one gets one message naming the file, the key path,
the YAML line and what is accepted.  The memory and output size of each run are
estimated and checked against the budget, as `multilayer run` does, and every ``expect:``
comparison with an exact solution must apply to the file, as `multilayer check` requires.
A sweep file (a ``base`` that is a path) is checked with every member, as `multilayer
sweep` would run it; a calibration or sensitivity file (such a ``base`` with
``observations``, or with ``outputs``), as `multilayer calibrate` and `multilayer
sensitivity` read it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from multilayer import scenario as scenarios
from multilayer.app import expectations, factory, resources
from multilayer.app.commands import add_budget_arguments, add_set_argument, budget, file_path
from multilayer.errors import InputError, printable, to_stderr, warn
from multilayer.scenario import Scenario

HELP = "check scenario, sweep and study files without running them"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``multilayer validate``."""
    parser.add_argument(
        "files", metavar="FILE", nargs="+", type=file_path, help="scenario, sweep or study YAML files"
    )
    add_set_argument(parser, "override a key in every scenario file and every member of a sweep")
    add_budget_arguments(parser)


def main(args: argparse.Namespace) -> int:
    """Validate every file; print 'ok' lines on stdout and errors on stderr."""
    invalid = 0
    for path in args.files:
        try:
            line = _check_file(path, args)
        except InputError as exc:
            to_stderr(f"multilayer: error: {printable(str(exc))}")
            invalid += 1
            continue
        print(printable(f"{path}: ok ({line})"))
    return 2 if invalid else 0


def _check_file(path: str, args: argparse.Namespace) -> str:
    """The summary of a valid file of any kind (:class:`InputError` otherwise): a file whose
    ``base`` is a path (a scenario's is a list of basal conditions) or that has
    ``parameters`` (no scenario has) is a calibration with ``observations``, a sensitivity
    study with ``outputs``, else a sweep.  (A sweep whose ``base`` was a list was
    validated as a scenario: ``time`` missing, ``parameters`` unknown.)"""
    from multilayer.io import study

    data, lines = scenarios.read_yaml(path)  # once: the file may change between two reads
    study_base = isinstance(data, dict) and (isinstance(data.get("base"), str) or "parameters" in data)
    if study_base and "observations" in data:
        calibration = study.load_calibration(path, factory.check_start)
        searched = ", ".join(calibration.config.parameters)
        return f"calibration of {searched} against {len(calibration.data)} observations"
    if study_base and "outputs" in data:
        from multilayer.app import sensitivity  # SALib's design, checked as the command does

        loaded = study.load_sensitivity(path, factory.check_start)
        sensitivity.sample(loaded)
        config = loaded.config
        return f"sensitivity of {', '.join(config.outputs)} to {', '.join(config.parameters)}"
    if study_base:
        from multilayer.app import sweep as sweeps  # the engine, for the sweep's runs

        plan = sweeps.load(path)
        members = plan.members()
        for member in members:
            try:
                _check(plan.member_scenario(member, args.overrides), plan.base, args)
            except InputError as exc:
                raise InputError(
                    f"{path}: member {member.id} ({', '.join(member.overrides)}):\n{exc}"
                ) from None
        return f"sweep of {len(members)} members of {plan.base}, each valid"
    scenario = scenarios.from_dict(data, source=Path(path), overrides=args.overrides, lines=lines)
    return _check(scenario, path, args)


def _check(scenario: Scenario, path: str | Path, args: argparse.Namespace) -> str:
    """The summary of a valid scenario: its size and estimates (:class:`InputError` if it
    is beyond the budget, holds material outside its domain or expects what cannot apply)."""
    limits = budget(args)
    scenario.check_material()
    need = resources.check(scenario, scenario.output.directory or Path("results"), limits)
    dom = scenario.domain
    # a forced mesh may not fit: the run checks it as it builds the mesh
    factory.check_initial(scenario, str(path), on_mesh=not limits.force)
    steps = resources.check_steps(scenario, limits)
    factory.check_pressure(scenario)  # as the run: after the estimate of its steps
    expectations.validate(scenario)
    if (absent := scenario.front_never_found()) is not None:  # as the run says it
        warn(f"{path}: numerics.front_threshold = {absent}")
    return (
        f"{scenario.name}: {dom.cells} cells x {dom.layers} layers, "
        f"rheology {scenario.rheology.name}, t_end = {scenario.time.end:g} s; about "
        f"{resources.size_text(need.memory)} of memory, {need.records:.0f} output times, "
        f"result.nc about {resources.size_text(need.output)}, about {steps.count:.2g} time steps "
        f"(--max-steps {limits.step_limit:.3g})"
    )
