"""Start/stop friction (Pouliquen & Forterre 2002): a static yield stress mu_start p for
material at rest, the flowing mu_s p elsewhere, chosen per interface at the start of each
step (engine/stress.py).  A uniform layer on a periodic slope isolates the vertical step."""

import math
from pathlib import Path

import numpy as np
import pytest
from engine import simulation

from multilayer import scenario as scenarios
from multilayer.app.simulation import Simulation
from multilayer.plugins.builtins import DruckerPrager, JopMuI, PowerLawMuI
from multilayer.plugins.contract import Material

MU_S, MU_START = math.tan(math.radians(23.5)), math.tan(math.radians(25.5))
H, NU, G = 0.01, 1.0e-4, 9.81
BETWEEN = 24.5  # degrees: tan(theta) between mu_s and mu_start


def _layer(theta: float, speed: float = 0.0, layers: int = 1) -> Simulation:
    """A uniform layer of thickness H on a periodic slope, no-slip bed, Drucker-Prager with
    the constant viscosity rho NU and start/stop friction."""
    velocity = {"velocity": {"profile": "plug", "speed": speed}} if speed else {}
    return simulation(
        slope_deg=theta,
        domain={"x_min": 0.0, "x_max": 0.04, "cells": 4, "layers": layers},
        rheology={"name": "drucker_prager", "mu_s": MU_S, "nu": NU, "mu_start": MU_START},
        base=[{"condition": "no_slip"}],
        initial=[{"shape": "layer", "thickness": H, **velocity}],
        boundaries={"left": "periodic", "right": "periodic"},
    )


@pytest.mark.parametrize("layers", [1, 4])
def test_a_layer_at_rest_between_the_two_angles_stays_exactly_at_rest(layers):
    sim = _layer(BETWEEN, layers=layers)
    sim.advance(0.5)
    assert sim.steps > 20
    assert np.all(sim.u == 0.0)
    # the same slope without hysteresis (mu_start = mu_s) sets it moving at once
    moving = _layer(BETWEEN, layers=layers)
    moving.vertical.stresses.bulk.mu_start = MU_S
    moving.step()
    assert np.all(moving.u > 0.0)


def test_the_same_layer_flowing_keeps_flowing_with_the_analytic_acceleration():
    """du/dt = g (sin - mu_s cos) - 2 nu u / h^2 for one layer on a no-slip bed: the
    implicit step follows its backward-Euler recurrence to round-off, and the exact
    exponential approach to u_inf to the order of dt / tau."""
    theta = math.radians(BETWEEN)
    drive = G * (math.sin(theta) - MU_S * math.cos(theta))
    rate = 2.0 * NU / H**2
    u0 = 0.05
    sim = _layer(BETWEEN, speed=u0)
    discrete, steps = [u0], []
    sim.advance(1.0, on_step=lambda s, dt: steps.append(dt))
    for dt in steps:
        discrete.append((discrete[-1] + dt * drive) / (1.0 + dt * rate))
    np.testing.assert_allclose(sim.u, discrete[-1], rtol=1e-9)
    u_inf = drive / rate
    exact = u_inf + (u0 - u_inf) * math.exp(-rate * sim.t)
    assert sim.u[0, 0] == pytest.approx(exact, rel=max(steps) * rate)
    assert np.all(sim.u > u0)  # it accelerated: the static threshold never applied


def test_onset_exactly_when_tan_theta_passes_mu_start():
    critical = math.degrees(math.atan(MU_START))
    below, above = _layer(critical - 1e-6, layers=4), _layer(critical + 1e-6, layers=4)
    below.advance(0.1)
    above.step()
    assert np.all(below.u == 0.0)
    assert np.all(above.u > 0.0)


@pytest.mark.parametrize(
    "law",
    [
        DruckerPrager(mu_s=0.47, nu=1e-3),
        JopMuI(mu_s=0.47, mu_2=0.72, I_0=0.279),
        PowerLawMuI(mu_s=0.47, m=0.5, alpha=0.5),
    ],
)
def test_mu_start_defaults_to_mu_s(law):
    p = np.linspace(-10.0, 1e4, 7)
    material = Material(1550.0, 7e-4, 2500.0)
    assert law.mu_start == law.mu_s
    np.testing.assert_array_equal(law.static_yield_stress(p, material), law.yield_stress(p, material))


def test_mu_start_below_mu_s_is_rejected():
    with pytest.raises(ValueError, match="mu_start must be >= mu_s"):
        JopMuI(mu_s=0.47, mu_2=0.72, I_0=0.279, mu_start=0.4)


def test_mu_start_equal_to_mu_s_is_bit_identical_to_the_law_without_it():
    flagship = Path(__file__).resolve().parent.parent / "scenarios" / "erodible_bed_collapse.yaml"
    law = "rheology={name: jop_mu_i, mu_s: 0.4770, mu_2: 0.7265, I_0: 0.279}"
    coarse = ["domain.x_max=1.25", "domain.cells=100", "domain.layers=4", law]
    plain = Simulation(scenarios.load(flagship, coarse))
    same = Simulation(scenarios.load(flagship, [*coarse, "rheology.mu_start=0.4770"]))
    assert plain.vertical.stresses.bulk.mu_start == 0.4770  # the default
    for sim in (plain, same):
        sim.advance(0.2)
    assert plain.steps == same.steps
    np.testing.assert_array_equal(same.h, plain.h)
    np.testing.assert_array_equal(same.u, plain.u)
