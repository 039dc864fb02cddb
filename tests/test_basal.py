"""The worked example of docs/architecture.md, "Adding a basal condition, end to end": the
documented registration of a cohesive Coulomb bed is run (in a copy of the registry), and
the condition is checked against the exact motion of a rigid block on a slope."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from engine import simulation

from multilayer.app import factory
from multilayer.engine import basal
from multilayer.errors import InputError
from multilayer.scenario import from_dict

ARCHITECTURE = Path(__file__).resolve().parents[1] / "docs" / "architecture.md"
THETA, H, RHO, MU, MU_S = 30.0, 0.05, 1500.0, 0.3, 1.0


@pytest.fixture
def mohr_coulomb(monkeypatch):
    """The registry with the documented condition added (the built-in one left untouched)."""
    monkeypatch.setattr(basal, "CONDITIONS", dict(basal.CONDITIONS))
    section = ARCHITECTURE.read_text().split("### Adding a basal condition, end to end", 1)[1]
    block = re.search(r"```python\n(.*?)```", section, re.S)
    assert block is not None
    exec(block.group(1), {})  # noqa: S102 - the documented code, as a user would run it
    return basal.CONDITIONS["mohr_coulomb"]


def block_on_a_slope(cohesion: float):
    """A uniform layer ``H`` thick on a periodic slope, locked by a bulk friction ``MU_S``
    far above what the bed can hold, on a cohesive Coulomb bed."""
    return simulation(
        slope_deg=THETA,
        domain={"x_min": 0.0, "x_max": 0.1, "cells": 4, "layers": 4},
        material={"density": RHO, "grain_diameter": 1e-3},
        rheology={"name": "drucker_prager", "mu_s": MU_S, "nu": 0.0},
        base=[{"condition": "mohr_coulomb", "mu": MU, "cohesion": cohesion}],
        initial=[{"shape": "layer", "thickness": H}],
        boundaries={"left": "periodic", "right": "periodic"},
    )


def test_a_block_slides_at_the_acceleration_the_cohesive_bed_leaves(mohr_coulomb):
    """``a = g sin(theta) - mu g cos(theta) - c / (rho h)``, every layer at ``u = a t``
    (the implicit step of a rigid block is exact: the bed's stress is constant while it
    slides)."""
    cohesion = 50.0
    g = 9.81
    a = g * math.sin(math.radians(THETA)) - MU * g * math.cos(math.radians(THETA)) - cohesion / (RHO * H)
    sim = block_on_a_slope(cohesion)
    sim.advance(0.2)
    assert a > 1.0 and np.all(sim.h == H)
    np.testing.assert_allclose(sim.u, a * sim.t, rtol=1e-12)


def test_a_block_the_cohesion_holds_stays_exactly_at_rest(mohr_coulomb):
    g = 9.81
    cohesion = 1.2 * RHO * H * g * (math.sin(math.radians(THETA)) - MU * math.cos(math.radians(THETA)))
    sim = block_on_a_slope(cohesion)
    sim.advance(0.2)
    assert sim.steps > 10 and np.all(sim.u == 0.0)


def test_the_scenario_names_what_the_new_condition_needs(mohr_coulomb):
    with pytest.raises(InputError, match=r"base\.0\.cohesion: condition mohr_coulomb requires cohesion; "):
        simulation(base=[{"condition": "mohr_coulomb", "mu": MU}])
    with pytest.raises(
        InputError, match=r"accepted: no_slip, coulomb \(with mu\), free_slip or mohr_coulomb"
    ):
        simulation(base=[{"condition": "sticky"}])
    with pytest.raises(InputError, match=r"base\.0\.cohesion: got -1.0; accepted: a cohesion >= 0 \(Pa\)"):
        simulation(base=[{"condition": "mohr_coulomb", "mu": MU, "cohesion": -1.0}])


def test_the_built_in_conditions_are_the_coefficients_of_interface_0():
    x = np.array([-1.0, 0.5, 1.5])
    regions = from_dict(
        {
            "name": "zones",
            "domain": {"x_min": -2.0, "x_max": 2.0, "cells": 4},
            "material": {"density": 1500.0, "grain_diameter": 1e-3},
            "rheology": {"name": "drucker_prager", "mu_s": 0.3, "nu": 0.0},
            "base": [
                {"condition": "free_slip", "x_max": 0.0},
                {"condition": "no_slip", "x_min": 0.0},
                {"condition": "coulomb", "mu": 0.4, "x_min": 1.0},
            ],
            "time": {"end": 1.0, "output_interval": 1.0},
        }
    ).base
    columns = basal.columns(factory.basal_regions(regions), x)
    assert columns.bulk.tolist() == [False, True, False]
    assert columns.friction.tolist() == [0.0, 0.0, 0.4] and columns.cohesion.tolist() == [0.0, 0.0, 0.0]
