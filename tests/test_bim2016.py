"""The ``bim2016`` pressure (Bouchut, Ionescu & Mangeney 2016, eq. 4.9) against the
paper's particular solutions: simple shear (Prop. 2.2), rest equilibrium (sec. 4.1,
eq. 4.24) and steady flows with a static/flowing transition (sec. 4.2, eq. 4.29)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from engine import simulation
from test_vertical import simple_shear

from multilayer.engine.pressure import bim2016
from multilayer.engine.vertical import newton as vertical_step

THETA_DEG, PHI_DEG = 20.0, 30.0
MU = math.tan(math.radians(PHI_DEG))


def wedge(surface_slope: float, pressure: str, layers: int = 4, theta_deg: float = THETA_DEG):
    """A layer thinning linearly downslope, d_x h = surface_slope, on a plane (20 degrees),
    inviscid Drucker-Prager with mu_s = tan(30 deg) and a no-slip bed."""
    h_left = 0.15 - 0.5 * surface_slope  # h = 0.15 m at x = 0.5 m
    return simulation(
        slope_deg=theta_deg,
        domain={"x_min": 0.0, "x_max": 1.0, "cells": 50, "layers": layers},
        material={"density": 1500.0, "grain_diameter": 1e-3},
        rheology={"name": "drucker_prager", "mu_s": MU, "nu": 0.0},
        base=[{"condition": "no_slip"}],
        initial=[{"shape": "profile", "points": [[0.0, h_left], [1.0, h_left + surface_slope]]}],
        boundaries={"left": "outflow", "right": "outflow"},
        model={"pressure": pressure},
    )


# the free surface slope at the friction angle: eq. 4.24 for bim2016, tan(theta) - d_x h = mu_s
# for the hydrostatic model
CRITICAL = {
    "bim2016": math.tan(math.radians(THETA_DEG - PHI_DEG)),  # -0.176
    "hydrostatic": math.tan(math.radians(THETA_DEG)) - MU,  # -0.214
}


@pytest.mark.parametrize("pressure", ["bim2016", "hydrostatic"])
@pytest.mark.parametrize("side", [0.97, 1.03])
def test_rest_equilibrium_holds_exactly_when_the_slope_criterion_says_so(pressure, side):
    """Sec. 4.1: material at rest stays at rest iff
    |sin(theta) - cos(theta) d_x h| <= mu_s (cos(theta) + sin(theta) d_x h) (eq. 4.24, the free
    surface no steeper than the friction angle); 3 % on either side of the criterion."""
    sim = wedge(side * CRITICAL[pressure], pressure)
    sim.step()
    interior = sim.u[:, 3:-3]
    if side < 1:
        assert np.all(interior == 0.0)
    else:
        assert np.all(interior[-1] > 0.0)


def test_bim2016_and_hydrostatic_criteria_differ_between_them():
    """Between the two critical slopes the hydrostatic model holds the wedge and bim2016
    does not: the pressure correction sin(theta) d_x h of eq. 4.9 is what moves it."""
    between = 0.5 * (CRITICAL["bim2016"] + CRITICAL["hydrostatic"])
    held, released = wedge(between, "hydrostatic"), wedge(between, "bim2016")
    held.step()
    released.step()
    assert np.all(held.u[:, 3:-3] == 0.0)
    assert np.all(released.u[-1, 3:-3] > 0.0)


def test_proposition_2_2_is_unchanged_bit_for_bit():
    """Uniform simple shear has d_x h = d_x U = 0: eq. 4.9 is the hydrostatic pressure."""
    runs = {p: simple_shear(nu=0.0, layers=40, model={"pressure": p}) for p in ("hydrostatic", "bim2016")}
    for sim in runs.values():
        sim.advance(0.5)
    assert np.array_equal(runs["hydrostatic"].u, runs["bim2016"].u)
    assert runs["bim2016"].u.max() > 0.0


def steady_residual(theta_deg: float, pressure: str) -> tuple[float, float]:
    """Sec. 4.2: h linear with the free surface at the friction angle for bim2016 (eq. 4.29,
    d_x h = tan(theta - phi)), U = A max(Z - h + y0, 0).  One vertical step of the
    transport's driving g (sin(theta) - cos(theta) d_x h) and the stresses; returns the
    largest residual acceleration |u - U| / dt in the flowing layers of the middle column and
    the surface slope."""
    theta = math.radians(theta_deg)
    s = math.tan(theta - math.radians(PHI_DEG))
    sim = wedge(s, pressure, layers=20, theta_deg=theta_deg)
    A, y0, dt = 2.0, 0.05, 1e-3
    z = sim.sigma[:, None] * sim.h
    U = A * np.maximum(z - sim.h + y0, 0.0)
    sim.u[...] = U
    g = 9.81
    ustar = U + dt * g * (math.sin(theta) - math.cos(theta) * s)
    G = None
    if pressure == "bim2016":
        G = bim2016.yield_gravity(
            sim.h, sim.u, sim.bed, sim.fractions, dx=sim.dx, gravity=g, theta=theta, base_slip=~sim.base.bulk
        )
    u, _ = vertical_step.implicit_step(sim.vertical.stresses, sim.h, ustar, U, dt, yield_gravity=G)
    i = sim.h.size // 2
    flowing = z[:, i] - 0.5 * sim.fractions[:, None][:, 0] * sim.h[i] > sim.h[i] - y0  # whole layer flows
    return float(np.abs(u[flowing, i] - U[flowing, i]).max() / dt), s


@pytest.mark.parametrize("theta_deg", [25.0, 28.0])
def test_steady_flow_with_a_static_flowing_transition(theta_deg):
    """bim2016 keeps the flow of sec. 4.2 steady up to the regularisation of the ratio,
    2 |sin(theta)| (|s| - |s|/(1 + 4 s^2)^(1/2)) mu_s g cos(theta) ~ 4 mu_s g |sin(theta)| |s|^3;
    the hydrostatic model decelerates it by g mu_s sin(theta) |s|, first order in s."""
    theta = math.radians(theta_deg)
    residual, s = steady_residual(theta_deg, "bim2016")
    bound = 2 * math.sin(theta) * abs(s) * (1 - 1 / math.sqrt(1 + 4 * s * s)) * MU * 9.81
    assert residual <= 1.05 * bound + 1e-9
    hydro, _ = steady_residual(theta_deg, "hydrostatic")
    assert hydro == pytest.approx(9.81 * MU * math.sin(theta) * abs(s), rel=1e-6)
