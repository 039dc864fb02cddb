"""Side-wall friction: summed over the layers it is the mu_w h / W of depth-averaged
models (Jop, Forterre & Pouliquen 2005; docs/model.md), so a rigid layer on a Coulomb base
stays at rest exactly up to tan(theta) = mu + mu_w h / W and accelerates beyond it at
g cos(theta) (tan(theta) - mu - mu_w h / W)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from engine import simulation

MU, MU_W, WIDTH, H = 0.3, 0.2, 0.1, 0.05
THRESHOLD = MU + MU_W * H / WIDTH  # 0.4


def channel(tan_theta: float):
    return simulation(
        slope_deg=math.degrees(math.atan(tan_theta)),
        domain={"x_min": 0.0, "x_max": 0.1, "cells": 4, "layers": 8, "width": WIDTH},
        material={"density": 1550.0, "grain_diameter": 0.7e-3},
        rheology={"name": "drucker_prager", "mu_s": 0.8, "nu": 0.0},
        walls={"name": "wall_friction", "mu_w": MU_W},
        base=[{"condition": "coulomb", "mu": MU}],
        initial=[{"shape": "layer", "thickness": H}],
        boundaries={"left": "periodic", "right": "periodic"},
    )


def test_rigid_layer_held_by_base_and_walls_below_the_threshold():
    sim = channel(THRESHOLD - 0.02)
    for _ in range(500):
        sim.step()
    assert np.all(sim.u == 0.0)


@pytest.mark.parametrize("excess", [0.02, 0.1])
def test_rigid_layer_accelerates_at_the_depth_averaged_rate_above_it(excess):
    tan_theta = THRESHOLD + excess
    sim = channel(tan_theta)
    sim.advance(0.5)
    cos = 1.0 / math.sqrt(1.0 + tan_theta**2)
    expected = 9.81 * cos * (tan_theta - THRESHOLD) * 0.5
    assert np.ptp(sim.u) <= 1e-12 * expected  # one plug
    assert sim.u[0, 0] == pytest.approx(expected, rel=1e-10)


def test_without_walls_the_same_layer_slides():
    """The walls are what holds it: remove them and mu = 0.3 < tan(theta) = 0.38."""
    sim = channel(THRESHOLD - 0.02)
    sim.vertical.stresses.walls = None
    sim.advance(0.1)
    assert np.all(sim.u > 0.0)
