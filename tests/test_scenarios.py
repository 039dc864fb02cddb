"""The shipped scenario library: valid, documented, and meeting its own expectations.

Each file's ``expect:`` entries are of two kinds, tested separately: ``regression`` pins
(values taken from the code's own output, a change detector) and ``reference`` values (an
exact solution or a published result, with its source: a validation).  Each file runs once.
"""

import dataclasses
import functools
from pathlib import Path

import pytest

from multilayer import scenario as scenarios
from multilayer.app import cli
from multilayer.app import expectations as expect
from multilayer.scenario.schema import QUANTITIES

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
NAMES = (
    "erodible_bed_collapse",
    "erodible_bed_collapse_coulomb",
    "smooth_to_rough_chute",
    "static_flowing_interface",
    "coulomb_dam_break",
    "column_collapse",
    "column_collapse_channel",
    "bagnold_chute",
    "immersed_layer_loose",
    "immersed_layer_dense",
    "submarine_collapse_loose",
    "submarine_collapse_dense",
)
SLOW_RUNS = {
    "immersed_layer_loose",
    "immersed_layer_dense",
    "submarine_collapse_loose",
    "submarine_collapse_dense",
    "erodible_bed_collapse",
    "erodible_bed_collapse_coulomb",
    "column_collapse",
    "column_collapse_channel",
    "smooth_to_rough_chute",
}
"""Runs of 2 to 13 s of CPU each, so they run under ``slow``: the grain–fluid mixtures, the
collapses on erodible beds, in a channel and on a rough bed, and the chute's boundary layer.
The default run keeps the scenarios checked against exact solutions in a second or less."""


def _path(name: str) -> Path:
    return SCENARIOS / f"{name}.yaml"


def test_library_is_complete_and_valid(capsys):
    """The scenario files lie directly in scenarios/; sweep files in scenarios/sweeps/."""
    assert sorted(p.stem for p in SCENARIOS.glob("*.yaml")) == sorted(NAMES)
    assert cli.main(["validate", *map(str, map(_path, NAMES))]) == 0
    assert capsys.readouterr().out.count(": ok (") == len(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_scenario_is_documented_and_pinned(name):
    """A header comment naming what is reproduced, parameters and resolution; expectations."""
    text = _path(name).read_text()
    header = text[: text.index("\nname:")]
    assert all(line.startswith("#") for line in header.splitlines())
    for word in ("Reproduces:", "Parameters", "Resolution:"):
        assert word in header, f"{name}: header lacks '{word}'"
    scenario = scenarios.load(_path(name))
    assert scenario.expect and {e.quantity for e in scenario.expect if e.exact is None} <= set(QUANTITIES)
    for entry in scenario.expect:
        assert entry.kind in ("regression", "reference")
        assert (entry.source is not None) == (entry.kind == "reference")


EXACT = {
    "coulomb_dam_break": "coulomb_dam_break",
    "static_flowing_interface": "inviscid_simple_shear",
    "bagnold_chute": "bagnold",
    "smooth_to_rough_chute": "granular_blasius",
}
"""The shipped files that have an exact (or similarity) solution, and that solution."""


@pytest.mark.parametrize("name", NAMES)
def test_a_file_with_an_exact_solution_compares_with_it(name):
    """Its reference check is the exact solution by a norm, not only the conserved volume;
    the others (collapses, erodible beds) have none."""
    entries = scenarios.load(_path(name)).expect
    assert {e.exact.solution for e in entries if e.exact is not None} == (
        {EXACT[name]} if name in EXACT else set()
    )


def test_erodible_bed_thickness_is_the_first_initial_entry():
    base = scenarios.load(_path("erodible_bed_collapse"))
    assert base.initial[0].shape == "layer" and base.initial[0].thickness == 0.003
    assert base.slope_deg == 22.0 and base.domain.width == 0.10
    thicker = scenarios.load(_path("erodible_bed_collapse"), ["initial.0.thickness=0.005"])
    assert thicker.initial[0].thickness == 0.005


@functools.cache
def _outcomes(name: str) -> tuple[expect.Outcome, ...]:
    """The file's run (once per session) checked against all its entries."""
    return tuple(expect.check(scenarios.load(_path(name))))


def _with_kind(kind: str) -> list:
    return [
        pytest.param(n, marks=pytest.mark.slow) if n in SLOW_RUNS else n
        for n in NAMES
        if any(e.kind == kind for e in scenarios.load(_path(n)).expect)
    ]


@pytest.mark.parametrize("name", _with_kind("reference"))
def test_reference_values_are_met(name):
    """Validation: the file as shipped meets its exact or published values (see each source)."""
    outcomes = _outcomes(name)
    assert all(o.passed for o in outcomes if o.kind == "reference"), expect.report(name, outcomes)


@pytest.mark.parametrize("name", _with_kind("regression"))
def test_regression_pins_hold(name):
    """Change detection: the values pinned from the code's own output at the file's resolution."""
    outcomes = _outcomes(name)
    assert all(o.passed for o in outcomes if o.kind == "regression"), expect.report(name, outcomes)


SWEEPS = sorted((SCENARIOS / "sweeps").glob("*.yaml"))
COARSE = {"domain.cells": [30], "domain.layers": [2], "time.end": [0.02], "time.output_interval": [0.02]}
"""Added to a shipped sweep to run every member in a fraction of a second."""


QUICK_SWEEP = "column_collapse_gate"
"""The sweep the default run runs; the others run under ``slow`` (1-3 s of CPU each)."""


@pytest.mark.parametrize(
    "path",
    [p if p.stem == QUICK_SWEEP else pytest.param(p, marks=pytest.mark.slow) for p in SWEEPS],
    ids=[p.stem for p in SWEEPS],
)
def test_shipped_sweep_is_valid_and_runs_small(path, tmp_path):
    """Every member is a valid scenario; a coarse copy of the sweep runs all of them."""
    from dask.distributed import LocalCluster

    from multilayer.app import sweep

    plan = sweep.load(path)
    assert plan.base.parent.resolve() == SCENARIOS
    members = plan.members()
    for member in members:
        scenarios.load(plan.base, member.overrides)
    repeat = len(members) if plan.paired else 1  # zipped lists stay of equal length
    coarse = dataclasses.replace(
        plan, parameters={**plan.parameters, **{k: v * repeat for k, v in COARSE.items()}}
    )
    assert len(coarse.members()) == len(members)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as cluster:
        outcomes = sweep.run(coarse, tmp_path, scheduler=cluster.scheduler_address)
    assert [o.status for o in outcomes] == ["ok"] * len(members), [o.error for o in outcomes]
    sweep.write_summary(coarse, outcomes, tmp_path / "summary.csv")
    assert len((tmp_path / "summary.csv").read_text().splitlines()) == len(members) + 1
