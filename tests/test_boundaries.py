"""Inflow boundaries and basal conditions that change along the slope."""

from __future__ import annotations

import math

import numpy as np
from engine import simulation


def test_supercritical_inflow_fills_a_frictionless_channel_with_the_inflow_state():
    """Inflow h = 0.1 m, u = 2 m/s (Froude 2) onto a dry, flat, frictionless bed with an
    outflow end: once the front has left, the exact steady state is the inflow state."""
    sim = simulation(
        domain={"x_min": 0.0, "x_max": 2.0, "cells": 80, "layers": 3},
        boundaries={
            "left": "inflow",
            "right": "outflow",
            "inflow": {"thickness": 0.1, "velocity": {"profile": "plug", "speed": 2.0}},
        },
    )
    sim.advance(3.0)
    assert np.abs(sim.h - 0.1).max() < 1e-9
    assert np.abs(sim.u - 2.0).max() < 1e-9


def test_basal_condition_per_region_free_slip_upstream_no_slip_downstream():
    """A layer on a 20 degree slope with internal friction mu_s = 0.5 > tan(20): it slides
    as a plug at g sin(theta) t where the base is free (x < 0.5, later entry wins) and is
    exactly at rest on the no-slip base, away from the junction."""
    sim = simulation(
        slope_deg=20.0,
        domain={"x_min": 0.0, "x_max": 1.0, "cells": 100, "layers": 4},
        rheology={"name": "drucker_prager", "mu_s": 0.5, "nu": 0.0},
        base=[{"condition": "no_slip"}, {"x_max": 0.5, "condition": "free_slip"}],
        initial=[{"shape": "layer", "thickness": 0.05}],
        boundaries={"left": "periodic", "right": "periodic"},
    )
    t = 0.05
    sim.advance(t)
    upstream = (sim.x > 0.2) & (sim.x < 0.3)  # 20 cells from both junctions
    downstream = (sim.x > 0.7) & (sim.x < 0.8)
    exact = 9.81 * math.sin(math.radians(20.0)) * t
    assert np.abs(sim.u[:, upstream] - exact).max() < 1e-10
    assert np.all(sim.u[:, downstream] == 0.0)
