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


def heap_of_slope(ratio: float, cells: int, order: int):
    """A triangular heap 0.2 m wide on a horizontal no-slip bed whose flanks rise at
    ``ratio`` times its friction coefficient (Drucker-Prager, ``mu_s = 0.5``, one layer)."""
    slope = ratio * 0.5
    return simulation(
        domain={"x_min": 0.0, "x_max": 0.4, "cells": cells, "layers": 1},
        material={"density": 1500.0, "grain_diameter": 1e-3},
        rheology={"name": "drucker_prager", "mu_s": 0.5, "nu": 0.0},
        base=[{"condition": "no_slip"}],
        initial=[{"shape": "profile", "points": [[0.1, 0.0], [0.2, 0.1 * slope], [0.3, 0.0]]}],
        numerics={"order": order},
    )


@pytest.mark.parametrize("order", [1, 2])
def test_a_heap_kept_exactly_where_its_kinks_are_held(order):
    """The discrete heap is an exact equilibrium where the pressure force of every cell,
    summit and toes included, stays below its friction: flanks at 0.75 mu_s never move at
    either order (the limits at the kinks are in the next test)."""
    max_u, max_dh = held(heap_of_slope(0.75, cells=80, order=order), 20)
    assert max_u == 0.0 and max_dh == 0.0


@pytest.mark.parametrize("order", [1, 2])
def test_a_heap_steeper_than_its_kinks_hold_settles_by_a_discretisation_error(order):
    """Flanks at 0.9 mu_s: below the friction, but above what the kinks of the discrete heap
    hold (docs/model.md, "Rest"): at order 2 the limiter flattens the two summit cells, so
    their neighbours feel about 1.25 times the flank's slope (the mean face pressure of a
    linear and a flat reconstruction); at order 1 the toe cells feel 9/8 of it.  Those
    cells slump for a few steps, the heap then rests exactly, and what moved is a
    discretisation error of the kinks: the largest change of thickness falls at first order
    in dx (observed order within 0.15 of 1 from 160 to 320 cells)."""
    changes = []
    for cells in (160, 320):
        sim = heap_of_slope(0.9, cells=cells, order=order)
        h0 = sim.h.copy()
        sim.step()
        for _ in range(50):
            if not np.any(sim.u):
                break
            sim.step()
        changes.append(float(np.abs(sim.h - h0).max()))
        assert changes[-1] > 0.0
        max_u, max_dh = held(sim, 10)
        assert max_u == 0.0 and max_dh == 0.0
    assert abs(math.log2(changes[0] / changes[1]) - 1.0) <= 0.15
