"""Flows that stop: the friction felt within each stage of the transport
(``Simulation.step``; docs/numerics.md, "Time stepping").

A Coulomb layer decelerating on a slope below its friction angle follows the exact
solution and stops exactly (``u == 0``) within a step of the exact stop time; a collapse
below the friction angle stops, and its deposit converges at first order in the step.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from engine import simulation

MU = math.tan(math.radians(30.0))
SLOPE = 15.0


def sliding_layer(order: int, speed: float):
    """A 5 cm layer sliding at ``speed`` on a periodic 15 degree slope, one layer,
    basal Coulomb friction tan(30 deg) and no internal stress."""
    return simulation(
        slope_deg=SLOPE,
        domain={"x_min": 0.0, "x_max": 1.0, "cells": 4, "layers": 1},
        material={"density": 1550.0, "grain_diameter": 0.7e-3},
        base=[{"condition": "coulomb", "mu": MU}],
        initial=[{"shape": "layer", "thickness": 0.05, "velocity": {"profile": "plug", "speed": speed}}],
        boundaries={"left": "periodic", "right": "periodic"},
        numerics={"order": order},
    )


@pytest.mark.parametrize("order", [1, 2])
def test_a_coulomb_layer_below_its_friction_angle_stops_at_the_exact_time(order):
    """``du/dt = -g (mu cos(theta) - sin(theta))`` while ``u > 0``: the velocity is the
    exact one at every step (the splitting is exact for a uniform layer: the transport
    adds ``g sin(theta)``, the friction removes ``mu g cos(theta)``, each over the whole
    step in total) and the layer stops exactly, within one step of ``u0 / a``; its
    thickness never changes."""
    sim = sliding_layer(order, speed=1.0)
    a = 9.81 * (MU * math.cos(math.radians(SLOPE)) - math.sin(math.radians(SLOPE)))
    h0 = sim.h.copy()
    while np.any(sim.u != 0.0):
        dt = sim.step()
        if np.any(sim.u != 0.0):
            np.testing.assert_allclose(sim.u, 1.0 - a * sim.t, rtol=1e-12)
    assert sim.t - dt < 1.0 / a <= sim.t
    for _ in range(20):
        sim.step()
    assert np.all(sim.u == 0.0)
    np.testing.assert_array_equal(sim.h, h0)


@pytest.mark.parametrize("order", [1, 2])
def test_a_wedge_below_its_friction_angle_stays_exactly_at_rest(order):
    """A wedge on a 15 degree slope whose flank (slope 0.2) keeps the driving slope
    tan(15) + 0.2 = 0.47 below tan(30) = 0.58 everywhere: h and u keep their bits."""
    sim = simulation(
        slope_deg=SLOPE,
        domain={"x_min": -0.5, "x_max": 1.5, "cells": 80, "layers": 1},
        material={"density": 1550.0, "grain_diameter": 0.7e-3},
        base=[{"condition": "coulomb", "mu": MU}],
        initial=[{"shape": "profile", "points": [[0.0, 0.0], [0.5, 0.1], [1.0, 0.0]]}],
        numerics={"order": order},
    )
    h0 = sim.h.copy()
    for _ in range(500):
        sim.step()
    np.testing.assert_array_equal(sim.h, h0)
    assert np.all(sim.u == 0.0)


def collapse(cfl: float) -> tuple[float, float]:
    """A 10 cm x 20 cm block released on a 15 degree slope with basal Coulomb friction
    tan(30 deg) at 60 cells: the time it stops (the last step with a non-zero velocity)
    and the centre of mass of its deposit."""
    sim = simulation(
        slope_deg=SLOPE,
        domain={"x_min": -0.4, "x_max": 0.8, "cells": 60, "layers": 1},
        material={"density": 1550.0, "grain_diameter": 0.7e-3},
        base=[{"condition": "coulomb", "mu": MU}],
        initial=[{"shape": "rectangle", "x_min": -0.4, "x_max": -0.2, "height": 0.1}],
        boundaries={"left": "wall", "right": "outflow"},
        time={"end": 2.0, "output_interval": 1.0, "cfl": cfl},
    )
    stop = 0.0
    while sim.t < 2.0 and not sim.t > stop + 0.1:
        sim.step(2.0)
        if np.any(sim.u != 0.0):
            stop = sim.t
    assert sim.t < 2.0, "the block did not stop"
    return stop, float(np.sum(sim.x * sim.h) / np.sum(sim.h))


@pytest.mark.slow
def test_a_collapse_below_the_friction_angle_stops_and_converges_in_dt():
    """Courant numbers 0.4 to 0.025: the deposit's centre of mass converges at first
    order (its differences halve; measured 0.77, 0.41, 0.21, 0.11 mm) and the stop time
    converges (differences 7.4, 5.8, 6.1, 1.4 ms: the stop is read at the step, and the
    thin front deposits cell by cell)."""
    runs = [collapse(cfl) for cfl in (0.4, 0.2, 0.1, 0.05, 0.025)]
    stops, centres = np.array(runs).T
    ratios = np.abs(np.diff(centres))[:-1] / np.abs(np.diff(centres))[1:]
    assert np.all(ratios > 1.5), centres
    differences = np.abs(np.diff(stops))
    assert differences[-1] < differences[0] / 3.0, stops
