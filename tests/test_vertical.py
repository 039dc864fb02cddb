"""The implicit vertical step against exact solutions (docs/validation.md)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from engine import simulation

from multilayer.app.simulation import Simulation
from multilayer.engine.vertical import column_solve as column_kernel
from multilayer.plugins.contract import Rheology
from multilayer.reference import vertical_fipy
from multilayer.reference.exact import BagnoldFlow, InviscidSimpleShear, jop_inertial_number
from multilayer.scenario import load

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"

MU_S = math.tan(math.radians(26.0))
H, B0, SHEAR = 0.02, 0.005, 70.0
EXACT = InviscidSimpleShear(theta_deg=22.0, mu_s=MU_S, depth=H, b0=B0, shear=SHEAR)


def simple_shear(nu: float, layers: int = 200, **changes):
    """Bouchut, Ionescu & Mangeney (2016) single column: h = 2 cm on 22 degrees, linear profile above 5 mm."""
    return simulation(
        slope_deg=22.0,
        domain={"x_min": 0.0, "x_max": 0.005, "cells": 1, "layers": layers},
        material={"density": 1550.0, "grain_diameter": 0.7e-3},
        rheology={"name": "drucker_prager", "mu_s": MU_S, "nu": nu},
        base=[{"condition": "no_slip"}],
        initial=[
            {
                "shape": "layer",
                "thickness": H,
                "velocity": {"profile": "linear", "shear_rate": SHEAR, "from_height": B0},
            }
        ],
        boundaries={"left": "periodic", "right": "periodic"},
        **changes,
    )


def test_inviscid_simple_shear_matches_proposition_2_2():
    """U(t, z) = max(U0(z) - S t, 0) and U0(b(t)) = S t (Bouchut et al. 2016, Prop. 2.2)."""
    sim = simple_shear(nu=0.0)
    z = sim.sigma * H
    layer = H / 200
    for t in np.arange(0.1, 1.31, 0.1):
        sim.advance(t)
        # the kink of U at b(t) is resolved to a layer or two; away from it U is linear and
        # exact at layer centres: allow 3 layer increments of U0, 3 x 70/s x H/200 = 0.021 m/s
        assert np.abs(sim.u[:, 0] - EXACT.velocity(z, t)).max() < 3 * SHEAR * layer
        b_exact = EXACT.interface(t)
        b = sim.diagnostics()["static_interface"][0]
        assert abs(b - b_exact) <= 2 * layer, (t, b, b_exact)  # b is a layer top: resolution
    sim.advance(EXACT.stop_time + 0.005)
    assert np.all(sim.u == 0.0)
    assert sim.diagnostics()["static_interface"][0] == sim.h[0]


def test_viscous_simple_shear_erodes_then_deposits():
    """With nu = 5e-5 m^2/s the interface first moves down, then up to h
    (Lusso, Ern, Bouchut, Mangeney, Farin & Roche 2017, Appl. Sci. 7, 386, the simple-shear
    simulations with viscosity; without it b never falls: Bouchut, Ionescu & Mangeney 2016,
    remark after Prop. 2.2)."""
    sim = simple_shear(nu=5e-5, layers=100)
    times = np.arange(0.02, 2.0, 0.02)
    b = []
    for t in times:
        sim.advance(t)
        b.append(sim.diagnostics()["static_interface"][0])
    b = np.array(b)
    lowest = int(np.argmin(b))
    # a drop of 5 layers, well beyond the one-layer resolution of b, counts as erosion
    assert b[lowest] <= B0 - 5 * H / 100
    assert 0 < lowest < len(b) - 1
    assert np.all(np.diff(b[lowest:]) >= 0.0)  # then only deposition
    assert b[-1] == sim.h[0] and np.all(sim.u == 0.0)


def test_bagnold_profile_is_the_steady_state_of_jop_mu_i():
    """Uniform flow from rest on a no-slip base tends to Bagnold's profile
    (Tsang, Dalziel & Vriend 2019, eq. 4.1):
    u(z) = (2 I / 3 d) sqrt(g cos(theta) rho / rho_p) (h^1.5 - (h - z)^1.5)."""
    d, h = 0.5e-3, 0.01
    mu_s, mu_2, i0 = 0.38, 0.64, 0.279
    sim = simulation(
        gravity=9.81,
        slope_deg=25.0,
        domain={"x_min": 0.0, "x_max": 0.01, "cells": 1, "layers": 20},
        material={"density": 1500.0, "grain_diameter": d},
        rheology={"name": "jop_mu_i", "mu_s": mu_s, "mu_2": mu_2, "I_0": i0},
        base=[{"condition": "no_slip"}],
        initial=[{"shape": "layer", "thickness": h}],
        boundaries={"left": "periodic", "right": "periodic"},
    )
    sim.advance(15.0)
    i_theta = jop_inertial_number(25.0, mu_s, mu_2, i0)
    bagnold = BagnoldFlow(h, i_theta, d, 25.0).velocity(sim.sigma * h)
    before = sim.u[:, 0].copy()
    sim.advance(16.0)
    assert np.abs(sim.u[:, 0] - before).max() < 1e-3 * bagnold.max()  # steady
    # tolerance from the layer convergence study of the Bagnold profile (docs/validation.md,
    # Bagnold section; the scaled profile is the same for any parameters): 0.34 % of the
    # surface speed at 10 layers, 2x coarser than here (0.11 % at 20 layers, order 1.6)
    assert np.abs(sim.u[:, 0] - bagnold).max() < 0.0035 * bagnold.max()


def test_the_high_i_term_gives_a_steady_bagnold_flow_beyond_mu_2():
    """jop_mu_i with mu_inf = 0.05 (Barker & Gray 2017's high-I term) on a 35 degree slope,
    steeper than atan(mu_2) where Jop's law has no steady flow: backward Euler steps of 1 s
    of the vertical step (compiled, the inertial_quadratic form) reach the Bagnold profile of
    I_theta = 2.06, the positive root of mu_inf I^2 + (mu_2 - tan) I - (tan - mu_s) I_0 = 0:
    mean speed at 8 and 16 layers converging at second order, the Richardson limit within
    1e-4 of the exact one."""
    d, h, theta = 0.5e-3, 0.01, 35.0
    mu_s, mu_2, i0, mu_inf = 0.38, 0.64, 0.279, 0.05
    i_theta = jop_inertial_number(theta, mu_s, mu_2, i0, mu_inf)
    assert i_theta == pytest.approx(2.06, abs=0.01)
    exact = BagnoldFlow(h, i_theta, d, theta, density_ratio=1500.0 / 2500.0).mean_velocity
    means = []
    for layers in (8, 16):
        sim = simulation(
            slope_deg=theta,
            domain={"x_min": 0.0, "x_max": 0.01, "cells": 1, "layers": layers},
            material={"density": 1500.0, "grain_diameter": d, "particle_density": 2500.0},
            rheology={"name": "jop_mu_i", "mu_s": mu_s, "mu_2": mu_2, "I_0": i0, "mu_inf": mu_inf},
            base=[{"condition": "no_slip"}],
            initial=[{"shape": "layer", "thickness": h}],
            boundaries={"left": "periodic", "right": "periodic"},
        )
        u = sim.u.copy()
        for _ in range(100):
            ustar = u + 9.81 * math.sin(math.radians(theta))
            new, _ = sim.vertical(sim.h, ustar, 1.0, [u], rest=None, yield_gravity=None, threads=1)
            if np.abs(new - u).max() <= 1e-12 * exact:
                break
            u = new.copy()
        means.append(float(sim.fractions @ new[:, 0]))
    order = math.log2((means[0] - exact) / (means[1] - exact))
    assert 1.8 < order < 2.2
    assert (4 * means[1] - means[0]) / 3 == pytest.approx(exact, rel=1e-4)


class Bingham(Rheology):
    """Bingham plastic: constant yield stress and viscosity."""

    name = "bingham_test"

    def __init__(self, tau_y: float, eta: float):
        self.tau_y, self.eta = tau_y, eta

    def yield_stress(self, pressure, material):
        return np.full_like(pressure, self.tau_y)

    def viscosity(self, shear_rate, pressure, material):
        return np.full_like(pressure, self.eta)


def test_bingham_layer_flows_as_a_rigid_plug_over_the_analytic_sheared_zone():
    """Steady Bingham flow on a slope: sheared below z_p = h - tau_y / (rho g sin theta),
    u = (rho g sin(theta) (h z - z^2/2) - tau_y z) / eta there, one rigid plug above."""
    rho, theta, h, tau_y, eta = 1000.0, math.radians(10.0), 0.1, 50.0, 10.0
    sim = simulation(
        slope_deg=10.0,
        domain={"x_min": 0.0, "x_max": 1.0, "cells": 1, "layers": 50},
        material={"density": rho, "grain_diameter": 1e-3},
        base=[{"condition": "no_slip"}],
        initial=[{"shape": "layer", "thickness": h}],
        boundaries={"left": "periodic", "right": "periodic"},
    )
    sim.vertical.stresses.bulk = Bingham(tau_y, eta)
    sim.advance(30.0)  # 30 viscous times rho h^2 / eta
    drive = rho * 9.81 * math.sin(theta)
    z_p = h - tau_y / drive
    z = sim.sigma * h
    u = sim.u[:, 0]
    plug = z > z_p + h / 50
    assert np.ptp(u[plug]) <= 1e-9
    exact = (
        np.where(
            z < z_p, drive * (h * z - z * z / 2) - tau_y * z, drive * (h * z_p - z_p**2 / 2) - tau_y * z_p
        )
        / eta
    )
    # second order on uniform layers: the profile is C1 at z_p (no shear there), so the
    # error scale is the layer-mean vs centre difference dz^2 |u''| / 24 = 7e-5 of the plug
    # speed; a second-order solution error is a few times that: allow 10 times it
    dz = h / 50
    assert np.abs(u - exact).max() < 10 * dz**2 * drive / eta / 24


COLLAPSE = dict(
    slope_deg=22.0,
    domain={"x_min": 0.0, "x_max": 0.3, "cells": 10, "layers": 5, "width": 0.1},
    material={"density": 1550.0, "grain_diameter": 0.7e-3},
    rheology={"name": "jop_mu_i", "mu_s": 0.477, "mu_2": 0.7265, "I_0": 0.279},
    walls={"name": "wall_friction", "mu_w": 0.185},
    base=[{"condition": "no_slip"}],
    initial=[
        {"shape": "layer", "thickness": 0.003},
        {"shape": "rectangle", "x_min": 0.0, "x_max": 0.1, "height": 0.05},
    ],
    boundaries={"left": "wall", "right": "outflow"},
)


@pytest.mark.slow
def test_kernel_and_fipy_reference_solve_the_same_collapse_problem():
    """One linearised vertical step of a mu(I)
    collapse over an erodible layer with side walls (after 3 steps), solved by the numba
    kernel and by the FiPy formulation: the same velocities to 1e-10 and the same layers
    exactly at rest."""
    sim = simulation(**COLLAPSE)
    sim.advance(0.05)
    wet = np.flatnonzero(sim.h > 0)
    u = sim.u[:, wet]
    stresses = sim.vertical.stresses
    problem = stresses.linearise(stresses.columns(sim.h, wet), u, u, sim.time_step())
    kernel = column_kernel.solve(problem, guess=u)
    reference = vertical_fipy.solve(problem)
    assert np.abs(reference - kernel).max() <= 1e-10
    np.testing.assert_array_equal(reference == 0.0, kernel == 0.0)
    assert np.any(kernel == 0.0) and np.abs(kernel).max() > 0.1  # static and flowing layers


@pytest.mark.slow
def test_kernel_and_fipy_reference_give_the_same_step():
    """Steps of a mu(I) collapse over an erodible layer with side walls, each solved from
    the same state by the numba kernel and by the FiPy formulation: the velocities agree
    to 1e-10 and the static layers are the same ones (minutes through FiPy).  The second
    transport stage moves the material with the first stage's velocities, so the
    thicknesses differ by at most the flux of that velocity difference over the step,
    ``dt / dx * max(h) * 1e-10`` (with a factor 4 for the reconstruction's slopes)."""
    kernel = simulation(**COLLAPSE)
    reference = simulation(**COLLAPSE, numerics={"vertical_solver": "fipy"})
    for _ in range(6):
        reference.load_state(kernel.state_dict())
        dt = 0.5 * kernel.time_step()
        t_next = kernel.t + dt
        kernel.step(t_next)
        reference.step(t_next)
        assert np.abs(reference.u - kernel.u).max() <= 1e-10
        assert np.abs(reference.h - kernel.h).max() <= 4.0 * dt / kernel.dx * kernel.h.max() * 1e-10
        assert np.array_equal(reference.u == 0.0, kernel.u == 0.0)
    assert np.any(kernel.u == 0.0) and np.abs(kernel.u).max() > 0.05


@pytest.mark.parametrize(
    "law",
    [
        (),  # Jop mu(I), the file's law
        ("rheology={name: drucker_prager, mu_s: 0.4770, nu: 6.45e-4}",),  # constant viscosity
    ],
    ids=["jop_mu_i", "drucker_prager"],
)
def test_collapse_onto_a_thin_erodible_bed_stays_physical(law):
    """A 14 cm column released onto a 1 mm bed (16 deg): the Newton iteration converges at
    the default tolerance from the first step, and no layer ever moves faster than free
    fall from the top of the column down the first 10 cm of slope allows (energy bound)."""
    sc = load(
        SCENARIOS / "erodible_bed_collapse.yaml",
        ["slope_deg=16", "initial.0.thickness=0.001", "time.end=0.1", *law],
    )
    sim = Simulation(sc)
    mass = sim.diagnostics()["mass"]
    drop = 0.14 * math.cos(math.radians(16)) + 0.3 * math.sin(math.radians(16))
    bound = math.sqrt(2 * 9.81 * drop)
    fastest = 0.0
    while sim.t < 0.1:
        sim.step(0.1)
        fastest = max(fastest, float(np.abs(sim.u).max()))
    assert 0.1 < fastest < bound
    assert sim.diagnostics()["mass"] == pytest.approx(mass, rel=1e-12)  # wall left, nothing out yet
