"""The lifting gate (engine/gate.py): limits and conservation on a coarse flagship collapse."""

import math
from pathlib import Path

import numpy as np
import pytest
from engine import simulation

from multilayer import scenario as scenarios
from multilayer.app.simulation import Simulation
from multilayer.engine.gate import Gate
from multilayer.engine.transport import kernel as transport_kernel

FLAGSHIP = Path(__file__).resolve().parent.parent / "scenarios" / "erodible_bed_collapse.yaml"
COARSE = ("domain.x_max=1.25", "domain.cells=120", "domain.layers=4")


def _run(*overrides: str, t_end: float = 0.25) -> Simulation:
    sim = Simulation(scenarios.load(FLAGSHIP, [*COARSE, *overrides]))
    sim.advance(t_end)
    return sim


def test_opening_fractions_are_the_parts_of_the_layers_below_the_edge():
    interfaces = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    gate = Gate(0.0, 0.1, -1.0, 0.2, 10, interfaces)
    assert gate.face == 5 and gate.x == 0.0
    h = np.zeros(10)
    h[4] = 0.08  # the column west of the face; the east one is dry
    # edge at 0.03 m in a 0.08 m column of 0.02 m layers: 1, 1/2, 0, 0
    np.testing.assert_allclose(gate.opening(h, 0.3), [1.0, 0.5, 0.0, 0.0], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(gate.opening(h, 0.0), 0.0)
    assert gate.opening(h, 0.8) is None  # the edge is above the material: no gate
    assert Gate(0.0, np.inf, -1.0, 0.2, 10, interfaces).opening(h, 0.0) is None


def test_infinite_lift_speed_is_the_instantaneous_release_bit_for_bit():
    free = _run()
    gated = _run("gate={x: -0.05, lift_speed: .inf}")
    assert free.steps == gated.steps
    np.testing.assert_array_equal(gated.h, free.h)
    np.testing.assert_array_equal(gated.u, free.u)


def test_a_gate_that_does_not_lift_holds_the_column_exactly_at_rest():
    sim = Simulation(scenarios.load(FLAGSHIP, [*COARSE, "gate={x: -0.05, lift_speed: 0}"]))
    h0 = sim.h.copy()
    sim.advance(0.3)
    assert sim.steps > 10
    np.testing.assert_array_equal(sim.h, h0)
    assert np.all(sim.u == 0.0)


@pytest.mark.parametrize("order", [1, 2])
def test_a_closed_gate_over_a_bed_step_holds_a_lake_at_rest_on_each_side(order):
    """Two lakes of different levels, 0.1 m on the bed and 0.2 m on a 0.05 m step up at
    the gate (free surfaces 0.1 and 0.25 m), frictionless: each side feels its own
    hydrostatic pressure at the gate (transport/reference.py, ``_gate_walls``), u == 0.0
    and h kept to the bit for 300 steps.  Before, the low side felt
    ``g_n (h_j - hL)(hR - hL) / 2`` = 0.0075 g_n more at the gate at both orders
    (tests/test_rest.py), and the run at order 2 left it."""
    sim = simulation(
        domain={"x_min": 0.0, "x_max": 0.4, "cells": 80, "layers": 4},
        bed={"points": [[0.0, 0.0], [0.2 - 1e-4, 0.0], [0.2 + 1e-4, 0.05], [0.4, 0.05]]},
        initial=[
            {"shape": "rectangle", "x_min": 0.0, "x_max": 0.2, "height": 0.1},
            {"shape": "rectangle", "x_min": 0.2, "x_max": 0.4, "height": 0.2},
        ],
        gate={"x": 0.2, "lift_speed": 0.0},
        numerics={"order": order},
    )
    h0 = sim.h.copy()
    assert np.array_equal(sim.bed[39:41], [0.0, 0.05]) and np.array_equal(h0[39:41], [0.1, 0.2])
    for _ in range(300):
        sim.step()
    assert not np.any(sim.u) and np.array_equal(sim.h, h0)


@pytest.mark.parametrize("speed", [0.5, 2.0])
def test_mass_is_conserved_while_the_gate_lifts(speed):
    sim = Simulation(scenarios.load(FLAGSHIP, [*COARSE, f"gate={{x: -0.05, lift_speed: {speed}}}"]))
    m0 = sim.diagnostics()["mass"]
    sim.advance(0.2)
    assert sim.gate.opening(sim.h, 0.1) is not None or speed * 0.1 > 0.14  # the gate acted
    assert np.any(sim.u != 0.0) and np.all(np.isfinite(sim.u))
    # nothing has reached the outflow end: the mass is conserved to round-off
    assert sim.h[-10:].max() == pytest.approx(0.003)
    assert sim.diagnostics()["mass"] == pytest.approx(m0, rel=1e-13)


@pytest.mark.slow
def test_a_slow_gate_delays_the_front():
    fast = _run("gate={x: -0.05, lift_speed: 4.0}")
    slow = _run("gate={x: -0.05, lift_speed: 0.5}")
    free = _run()
    fronts = [s.diagnostics()["front"] for s in (slow, fast, free)]
    assert fronts[0] < fronts[1] <= fronts[2]


def test_material_passing_under_the_gate_onto_a_dry_bed_stays_physical():
    """The first material under the edge enters a dry column: no layer may move faster than
    free fall from the top of the column allows (the receiving column spreads the gate
    flux over its layers; entering its lowest layer alone gave hundreds of m/s)."""
    sim = Simulation(
        scenarios.load(
            FLAGSHIP, [*COARSE, "slope_deg=16", "initial.0.thickness=0", "gate={x: -0.05, lift_speed: 2.0}"]
        )
    )
    mass = sim.diagnostics()["mass"]
    fastest = 0.0
    while sim.t < 0.1:
        sim.step(0.1)
        fastest = max(fastest, float(np.abs(sim.u).max()))
    drop = 0.14 * math.cos(math.radians(16)) + 0.3 * math.sin(math.radians(16))
    assert 0.1 < fastest < math.sqrt(2 * 9.81 * drop)
    assert sim.diagnostics()["mass"] == pytest.approx(mass, rel=1e-13)


def test_the_compiled_transport_runs_the_gate_as_the_numpy_reference_does():
    """A lifting gate with the compiled transport (the default) and with the numpy
    reference formulation: the same run to the last bit."""
    runs = []
    for solver in ("kernel", "numpy"):
        sim = Simulation(
            scenarios.load(
                FLAGSHIP, [*COARSE, "gate={x: -0.05, lift_speed: 0.5}", f"numerics.transport_solver={solver}"]
            )
        )
        assert (sim.transport is transport_kernel.transport) == (solver == "kernel")
        sim.advance(0.1)
        runs.append(sim)
    kernel, reference = runs
    assert kernel.steps == reference.steps and kernel.gate.opening(kernel.h, kernel.t) is not None
    np.testing.assert_array_equal(kernel.h, reference.h)
    np.testing.assert_array_equal(kernel.u, reference.u)
