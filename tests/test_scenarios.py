"""The shipped scenario library: valid, documented, and meeting its own expectations."""

from pathlib import Path

import pytest

from multilayer.app import cli
from multilayer.io import scenario as scenarios
from multilayer.io.scenario import QUANTITIES
from multilayer.testing import expectations as expect

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
NAMES = (
    "erodible_bed_collapse",
    "erodible_bed_collapse_coulomb",
    "smooth_to_rough_chute",
    "static_flowing_interface",
    "coulomb_dam_break",
    "column_collapse",
    "bagnold_chute",
)


def _path(name: str) -> Path:
    return SCENARIOS / f"{name}.yaml"


def test_library_is_complete_and_valid(capsys):
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
    assert scenario.expect and {e.quantity for e in scenario.expect} <= set(QUANTITIES)


def test_erodible_bed_thickness_is_the_first_initial_entry():
    base = scenarios.load(_path("erodible_bed_collapse"))
    assert base.initial[0].shape == "layer" and base.initial[0].thickness == 0.003
    assert base.slope_deg == 22.0 and base.domain.width == 0.10
    thicker = scenarios.load(_path("erodible_bed_collapse"), ["initial.0.thickness=0.005"])
    assert thicker.initial[0].thickness == 0.005


@pytest.mark.parametrize("name", NAMES)
def test_scenario_meets_its_expectations(name):
    """Every shipped file runs in seconds at its own resolution."""
    outcomes = expect.check(scenarios.load(_path(name)))
    assert all(o.passed for o in outcomes), expect.report(name, outcomes)
