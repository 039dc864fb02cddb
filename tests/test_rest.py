"""Exact rest (Bouchut, Ionescu & Mangeney 2016, sec. 4.1): material whose driving
stress stays below the yield stress never moves, neither by transport nor by the
vertical step."""

from __future__ import annotations

import math

import numpy as np
import pytest
from engine import simulation

JOP = {"name": "jop_mu_i", "mu_s": math.tan(math.radians(26.0)), "mu_2": 0.7, "I_0": 0.279}
DRUCKER_PRAGER = {"name": "drucker_prager", "mu_s": math.tan(math.radians(26.0)), "nu": 5e-5}


def held(sim, steps: int) -> tuple[float, float]:
    h0 = sim.h.copy()
    for _ in range(steps):
        sim.step()
    return float(np.abs(sim.u).max()), float(np.abs(sim.h - h0).max())


@pytest.mark.slow
@pytest.mark.parametrize("rheology", [JOP, DRUCKER_PRAGER], ids=["jop_mu_i", "drucker_prager"])
def test_heap_below_the_friction_angle_on_an_inclined_no_slip_bed(rheology):
    """A triangular heap with flanks of slope 0.1 on a 10 degree plane: the driving
    slope tan(10) + 0.1 = 0.28 stays below mu_s = tan(26) = 0.49 everywhere."""
    sim = simulation(
        slope_deg=10.0,
        domain={"x_min": -0.5, "x_max": 2.5, "cells": 100, "layers": 8},
        material={"density": 1550.0, "grain_diameter": 0.7e-3},
        rheology=rheology,
        base=[{"condition": "no_slip"}],
        initial=[{"shape": "profile", "points": [[0.0, 0.0], [1.0, 0.1], [2.0, 0.0]]}],
    )
    max_u, max_dh = held(sim, 3000)
    assert max_u == 0.0
    assert max_dh <= 1e-12
    assert sim.steps == 3000


def layer_on_a_slope(slope_deg: float, cells: int):
    """A 5 cm layer on a periodic slope, Jop mu(I) with mu_s = tan(26 deg) = 0.49."""
    return simulation(
        slope_deg=slope_deg,
        domain={"x_min": 0.0, "x_max": 1.0, "cells": cells, "layers": 8},
        material={"density": 1550.0, "grain_diameter": 0.7e-3},
        rheology=JOP,
        base=[{"condition": "no_slip"}],
        initial=[{"shape": "layer", "thickness": 0.05}],
        boundaries={"left": "periodic", "right": "periodic"},
    )


def test_uniform_layer_on_a_slope_below_the_friction_angle():
    """tan(20 deg) = 0.36 < mu_s: the layer stays put."""
    max_u, max_dh = held(layer_on_a_slope(20.0, cells=50), 3000)
    assert max_u == 0.0
    assert max_dh <= 1e-12


def test_the_same_layer_above_the_friction_angle_flows():
    """The converse: at 28 degrees (tan = 0.53 > 0.49) the layer accelerates."""
    sim = layer_on_a_slope(28.0, cells=10)
    held(sim, 20)
    assert np.all(sim.u[-1] > 0.0)
