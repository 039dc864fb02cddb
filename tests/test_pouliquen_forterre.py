"""The pouliquen_forterre law, mu = max(mu_stop(h), mu_J(I)), against its own references:
h_stop(theta) exactly (Forterre & Pouliquen 2003), the flow rule Fr = beta h / h_stop
(Pouliquen 1999; Jop, Forterre & Pouliquen 2005, appendix A) with the layers refined,
exact arrest of layers thinner than h_stop, and the column thickness it is given."""

from __future__ import annotations

import math

import numpy as np
import pytest
from engine import simulation

from multilayer.engine.plugin_output import PluginOutputError
from multilayer.engine.vertical import newton
from multilayer.engine.vertical.forms import law_of
from multilayer.plugins.builtins import PouliquenForterre
from multilayer.plugins.contract import Material
from multilayer.reference.exact import pouliquen_beta, pouliquen_h_stop

# Glass beads: mu_1 = tan 20.9 deg, mu_2 = tan 32.76 deg, L = 0.825 mm and beta = 0.136 as
# quoted from Forterre & Pouliquen (2003) and Pouliquen (1999) by later work; d = 0.5 mm,
# phi = 0.6; I_0 from beta (Jop et al. 2005, appendix A).
MU_1, MU_2, LENGTH, BETA = 0.3819, 0.6435, 0.825e-3, 0.136
GRAIN, GRAIN_DENSITY, PACKING = 0.5e-3, 2500.0, 0.6
I_0 = 5 * BETA * GRAIN / (2 * LENGTH * math.sqrt(PACKING))
MATERIAL = Material(density=PACKING * GRAIN_DENSITY, grain_diameter=GRAIN, particle_density=GRAIN_DENSITY)


def layer(theta, h, layers=8, speed=0.0, **extra):
    """A uniform glass-bead layer of thickness ``h`` on the slope ``theta`` (4 periodic
    columns), at rest or moving as a plug at ``speed``; ``extra`` parameters of the law."""
    initial = {"shape": "layer", "thickness": h}
    if speed:
        initial["velocity"] = {"profile": "plug", "speed": speed}
    return simulation(
        slope_deg=theta,
        domain={"x_min": 0.0, "x_max": 0.04, "cells": 4, "layers": layers},
        material={
            "density": PACKING * GRAIN_DENSITY,
            "grain_diameter": GRAIN,
            "particle_density": GRAIN_DENSITY,
        },
        rheology={"name": "pouliquen_forterre", "mu_1": MU_1, "mu_2": MU_2, "L": LENGTH, "I_0": I_0, **extra},
        base=[{"condition": "no_slip"}],
        initial=[initial],
        boundaries={"left": "periodic", "right": "periodic"},
    )


def test_beta_of_the_law_is_the_flow_rule_s():
    assert pouliquen_beta(I_0, LENGTH, GRAIN, PACKING) == pytest.approx(BETA, rel=1e-14)
    law = PouliquenForterre(mu_1=MU_1, mu_2=MU_2, L=LENGTH, I_0=I_0)
    for theta in (21.5, 25.0, 31.0):
        h_stop = pouliquen_h_stop(theta, MU_1, MU_2, LENGTH)
        assert law.mu_stop(h_stop) == pytest.approx(math.tan(math.radians(theta)), rel=1e-14)


@pytest.mark.parametrize("theta", [22.0, 25.0, 28.0])
def test_h_stop_is_exact(theta):
    """A layer 0.1 % thinner than h_stop(theta) stays exactly at rest (u == 0.0); one 0.1 %
    thicker flows."""
    h_stop = pouliquen_h_stop(theta, MU_1, MU_2, LENGTH)
    below, above = layer(theta, 0.999 * h_stop), layer(theta, 1.001 * h_stop)
    for _ in range(10):
        below.step()
        above.step()
    assert np.all(below.u == 0.0)
    assert np.all(above.u[-1] > 0.0)


def steady_froude(theta, h, layers):
    """Fr = u_mean / sqrt(g h cos theta) of the steady uniform flow: backward Euler steps of
    1 s of the vertical step (a uniform periodic layer: transport adds g sin(theta) dt)."""
    sim = layer(theta, h, layers)
    dt, u = 1.0, sim.u.copy()
    for _ in range(100):
        ustar = u + 9.81 * math.sin(math.radians(theta)) * dt
        new, _ = newton.implicit_step(sim.vertical.stresses, sim.h, ustar, u, dt)
        if np.abs(new - u).max() <= 1e-13:
            break
        u = new
    return float(sim.fractions @ new[:, 0]) / math.sqrt(9.81 * h * math.cos(math.radians(theta)))


@pytest.mark.parametrize("theta, ratio", [(25.0, 1.2), (28.0, 5.0)])
def test_the_flow_rule_is_met_as_the_layers_are_refined(theta, ratio):
    """Fr at 8 and 16 layers approaches beta h / h_stop at second order (the midpoint
    layers of the Bagnold profile: errors +0.45 % and +0.12 %, 0.03 % at 32), and the
    Richardson extrapolation of the two meets the flow rule to 1e-4."""
    h = ratio * pouliquen_h_stop(theta, MU_1, MU_2, LENGTH)
    coarse, fine = steady_froude(theta, h, 8), steady_froude(theta, h, 16)
    target = BETA * ratio
    order = math.log2((coarse - target) / (fine - target))
    assert 1.9 < order < 2.1
    assert (4 * fine - coarse) / 3 == pytest.approx(target, rel=1e-4)


def test_a_layer_thinner_than_h_stop_launched_stops_exactly():
    """0.8 h_stop(25 deg) launched at 5 cm/s decelerates through the kink of mu at I_c and
    comes exactly to rest (u == 0.0), and stays there."""
    sim = layer(25.0, 0.8 * pouliquen_h_stop(25.0, MU_1, MU_2, LENGTH), speed=0.05)
    while not np.all(sim.u == 0.0):
        assert sim.t < 1.0
        sim.step()
    for _ in range(5):
        sim.step()
    assert np.all(sim.u == 0.0)


def test_the_start_friction_holds_a_layer_between_h_stop_and_h_start():
    """With mu_3 = 0.40 a layer at rest holds up to h_start(25 deg) = L (Delta mu / (tan theta
    - mu_3) - 1) = 2.43 mm (Pouliquen & Forterre 2002): 2 mm, thicker than h_stop = 1.73 mm,
    stays exactly at rest, and flows without the start friction."""
    tan, delta = math.tan(math.radians(25.0)), MU_2 - MU_1
    h_start = LENGTH * (delta / (tan - 0.40) - 1.0)
    assert pouliquen_h_stop(25.0, MU_1, MU_2, LENGTH) < 2e-3 < h_start
    held, free = layer(25.0, 2e-3, mu_3=0.40), layer(25.0, 2e-3)
    for _ in range(10):
        held.step()
        free.step()
    assert np.all(held.u == 0.0) and np.all(free.u[-1] > 0.0)


def test_the_law_is_given_the_column_thickness_and_has_no_compiled_form():
    """Every call gets ``thickness`` = the column's h (broadcast like the pressure), and the
    law runs on the numpy path (the compiled forms take no thickness)."""
    sim = layer(25.0, 3e-3)
    sim.h[:] = [1e-3, 2e-3, 3e-3, 4e-3]
    law = sim.vertical.stresses.bulk
    seen = []
    original = law.yield_stress

    def recording(pressure, material, *, thickness):
        seen.append(np.array(thickness))
        return original(pressure, material, thickness=thickness)

    law.yield_stress = recording
    sim.vertical.stresses.columns(sim.h, np.arange(4))
    assert seen and np.array_equal(seen[0], np.broadcast_to(sim.h, seen[0].shape))
    assert law_of(PouliquenForterre(mu_1=MU_1, mu_2=MU_2, L=LENGTH, I_0=I_0), MATERIAL) is None


def test_a_bad_value_names_the_thickness_it_was_given():
    sim = layer(25.0, 3e-3)
    law = sim.vertical.stresses.bulk
    law.yield_stress = lambda pressure, material, *, thickness: np.where(thickness > 0, np.nan, 0.0)
    with pytest.raises(PluginOutputError, match="thickness"):
        sim.vertical.stresses.columns(sim.h, np.arange(4))


@pytest.mark.parametrize(
    "parameters, message",
    [
        ({"mu_1": 0.6, "mu_2": 0.5, "L": 1e-3, "I_0": 0.3}, "mu_2 must be > mu_1"),
        ({"mu_1": 0.4, "mu_2": 0.6, "L": 0.0, "I_0": 0.3}, "L must be > 0"),
        ({"mu_1": 0.4, "mu_2": 0.6, "L": 1e-3, "I_0": 0.3, "mu_3": 0.3}, "mu_3 must be >= mu_1"),
    ],
)
def test_bad_parameters_are_refused(parameters, message):
    with pytest.raises(ValueError, match=message):
        PouliquenForterre(**parameters)
