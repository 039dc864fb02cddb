"""Full-resolution validation against the references that the model meets.

Marked ``validation``: deselected by default, run with ``python -m pytest -m validation``
(a few minutes on 2 cores).  ``docs/make_validation.py`` writes the full report, including
the references that are not met; these tests keep the met ones from regressing.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np
import pytest
from test_transport import ritter_error

from multilayer.engine import diagnostics
from multilayer.engine.simulation import Simulation
from multilayer.reference import similarity
from multilayer.reference.exact import BagnoldFlow, InviscidSimpleShear, jop_inertial_number
from multilayer.scenario import load

pytestmark = pytest.mark.validation

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"


def run(name: str, *overrides: str) -> Simulation:
    sim = Simulation(load(SCENARIOS / f"{name}.yaml", overrides))
    sim.advance(sim.scenario.time.end)
    return sim


def test_ritter_dam_break_order_at_high_resolution():
    """Order about 1 is expected (kinks at the fan edges, a dry front); at high resolution
    the pre-asymptotic allowance of the default test (0.8) narrows to 0.9."""
    errors = np.array([ritter_error(n, order=2) for n in (400, 800, 1600)])
    assert np.all(np.log2(errors[:-1] / errors[1:]) >= 0.9)


@pytest.mark.parametrize("theta", [19.0, 22.0, 24.0])
def test_inviscid_static_flowing_interface_at_three_slopes(theta):
    """b(t) = b0 + S t / 70 within one layer (40 layers), Bouchut et al. 2016, Prop. 2.2."""
    sim = Simulation(
        load(
            SCENARIOS / "static_flowing_interface.yaml",
            [f"slope_deg={theta}", "rheology.nu=0", "domain.layers=40"],
        )
    )
    exact = InviscidSimpleShear(theta, math.tan(math.radians(26.0)), depth=0.02, b0=0.005, shear=70.0)
    for t in np.linspace(0.05, 0.95 * exact.stop_time, 12):
        sim.advance(t)
        b = sim.diagnostics()["static_interface"].mean()
        assert abs(b - exact.interface(t)) <= exact.depth / 40
    sim.advance(exact.stop_time * 1.01)
    assert np.all(sim.u == 0.0)


CHUTE = ("domain.cells=440", "time.end=1.2")  # dx = 2.5 mm, steady in the fitted window
#: the horizontal chute with the normal gravity g cos(16 deg) of the inclined one
LEVEL = ("slope_deg=0", f"gravity={9.81 * math.cos(math.radians(16.0)):.6f}")
#: x from 0.01 to 0.061 m: where the predicted delta* of the alpha = 0.34 layer is below H/10
FIXED_WINDOW = (0.01, 0.061)
#: the theory is leading order: where delta* reaches H/10 the neglected outer-flow
#: perturbation (Tsang et al. 2019, sec. 4.6, h/H = 1 + O(delta*/H)) is of relative order
#: 0.1, so exponents and thickness are required within 10 %.  The resolution study of the
#: exponent (docs/validation.md, chute section) moves it by less than 0.01 per halving of dx.
THEORY_ACCURACY = 0.1


@functools.cache
def chute(*changes: str) -> dict:
    """The chute at 2.5 mm, run once per set of changes: delta*, chi and the prediction."""
    sim = run("smooth_to_rough_chute", *CHUTE, *changes)
    sc = sim.scenario
    alpha, m = sc.rheology.params["alpha"], sc.rheology.params["m"]
    h_in, speed = sc.boundaries.inflow.thickness, sc.boundaries.inflow.velocity.speed
    solution = similarity.solve_similarity(alpha)
    eps = similarity.boundary_layer_scale(
        alpha, m, sc.slope_deg, h_in, speed, sc.material.grain_diameter, sc.gravity
    )
    x = sim.x
    return dict(
        x=x,
        alpha=alpha,
        window=(x >= FIXED_WINDOW[0]) & (x <= FIXED_WINDOW[1]),
        disp=similarity.displacement_thickness(sim.u, sim.fractions[:, None] * sim.h[None, :]),
        chi=similarity.shape_factor(sim.u, sim.fractions),
        predicted=solution.displacement_thickness
        * eps
        * h_in
        * (np.maximum(x, 0) / h_in) ** (1 / (1 + alpha)),
    )


def log_slope(x: np.ndarray, y: np.ndarray) -> float:
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


BLASIUS_CASES = pytest.mark.parametrize(
    "changes",
    [(), ("rheology.alpha=1", "rheology.m=0.2", *LEVEL)],
    ids=["power_law_16deg", "linear_horizontal_same_normal_gravity"],
)


@BLASIUS_CASES
def test_granular_blasius_layer_grows_like_x_to_the_one_over_one_plus_alpha(changes):
    """Tsang et al. (2019), eq. 4.13 and 4.15-4.17: delta* = zeta_disp eps H (x/H)^(1/(1+alpha)),
    exponent and size without a fitted constant.  Not asserted: alpha = 1 on the 16 deg
    chute, whose exponent falls short (docs/validation.md)."""
    c = chute(*changes)
    w = c["window"]
    assert log_slope(c["x"][w], c["disp"][w]) * (1 + c["alpha"]) == pytest.approx(1.0, abs=THEORY_ACCURACY)
    assert np.median(c["disp"][w] / c["predicted"][w]) == pytest.approx(1.0, abs=THEORY_ACCURACY)


@BLASIUS_CASES
def test_shape_factor_excess_grows_like_x_to_the_one_over_one_plus_alpha(changes):
    """Tsang et al. (2019), eq. 4.26 (sec. 4.6, 5.4): chi - 1 proportional to x^(1/(1+alpha))
    while the layer is thin."""
    c = chute(*changes)
    w = c["window"]
    slope = log_slope(c["x"][w], c["chi"][w] - 1)
    assert slope * (1 + c["alpha"]) == pytest.approx(1.0, abs=THEORY_ACCURACY)


def test_jop_law_at_its_alpha_minus_one_asymptote_forms_no_wall_layer():
    """Tsang et al. (2019), sec. 4.5: for I >> I_0 the Jop law is mu_2 - (mu_2 - mu_1) I_0 / I
    (alpha = -1) and admits no self-similar boundary layer.  With I_0 = 0.01 the bottom
    layer stays above 10 I_0 over the window; no wall layer forms: the bottom layer keeps
    more than half the outer speed and the deficit is spread over the depth.  The
    similarity layers of the power laws give at most 0.1 for both measures
    (docs/validation.md), a wall-free deficit spread linearly over the depth gives 1: the
    thresholds 0.5 and 0.25 lie between."""
    sim = run(
        "smooth_to_rough_chute",
        *CHUTE,
        "rheology={name: jop_mu_i, mu_s: 0.30249, mu_2: 1.38043, I_0: 0.01}",
    )
    i = int(np.argmin(np.abs(sim.x - FIXED_WINDOW[1])))
    u, h, frac = sim.u[:, i], sim.h[i], sim.fractions
    d, g_n = sim.scenario.material.grain_diameter, 9.81 * math.cos(math.radians(16.0))
    wall_inertial = d * u[0] / (0.5 * frac[0] * h) / math.sqrt(g_n * h)
    disp = similarity.displacement_thickness(u, frac * h)
    mid_deficit = np.interp(0.5, np.cumsum(frac) - frac / 2, 1 - u / u[-1]) * h / disp
    assert wall_inertial > 10 * 0.01
    assert u[0] / u[-1] > 0.5
    assert mid_deficit > 0.25


def test_bagnold_profile_converges_with_the_layers():
    """Layer velocities against Bagnold's profile averaged over each layer (eq. 4.1)."""
    errors = []
    for layers in (10, 20, 40):
        sim = run("bagnold_chute", f"domain.layers={layers}")
        sc, h = sim.scenario, float(sim.h[0])
        i_theta = jop_inertial_number(sc.slope_deg, **sc.rheology.params)
        mat = sc.material
        flow = BagnoldFlow(
            h, i_theta, mat.grain_diameter, sc.slope_deg, sc.gravity, mat.density / mat.particle_density
        )
        exact = flow.layer_means(sim.mesh.interfaces * h)
        errors.append(np.abs(sim.u[:, 0] - exact).max() / exact.max())
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    # the report's criterion for "met" (docs/validation.md, Bagnold section): 2 % of u_s
    assert errors[-1] < 0.02
    # the (h - z)^(3/2) term has an unbounded curvature at the surface, which caps the order
    # of the layer discretisation near 3/2 (second order elsewhere): require at least 1.3
    assert np.all(orders > 1.3)


ERODIBLE_END = {16.0: 2.5, 19.0: 2.5, 22.0: 3.0, 23.0: 4.0}  # s, as docs/make_validation.py


def erodible_runout(name: str, theta: float, bed: float) -> float:
    """Run-out of the front of the material thicker than the bed + 1 mm (the measure of
    docs/validation.md, "erodible") at the shipped resolution."""
    sim = Simulation(
        load(
            SCENARIOS / f"{name}.yaml",
            [f"slope_deg={theta}", f"initial.0.thickness={bed}", f"time.end={ERODIBLE_END[theta]}"],
        )
    )
    start = diagnostics.front_position(sim.x, sim.h, bed + 0.001)
    sim.advance(sim.scenario.time.end)
    return diagnostics.front_position(sim.x, sim.h, bed + 0.001) - start


@pytest.mark.parametrize("theta", [19.0, 22.0, 23.0])
def test_erodible_bed_lengthens_the_runout_with_mu_i_and_start_stop_friction(theta):
    """Mangeney et al. (2010), Farin et al. (2014), Fernandez-Nieto et al. (2016): the
    run-out grows with the erodible-bed thickness (more than 2 % from 0 to 5 mm)."""
    bare, bed = (erodible_runout("erodible_bed_collapse", theta, b) for b in (0.0, 0.005))
    assert bed > 1.02 * bare


def test_erodible_bed_barely_changes_the_runout_at_16_degrees():
    """Flat or slightly growing at 16 deg (within -2 % from 0 to 5 mm)."""
    bare, bed = (erodible_runout("erodible_bed_collapse", 16.0, b) for b in (0.0, 0.005))
    assert bed >= 0.98 * bare


@pytest.mark.parametrize("theta", [16.0, 19.0])
def test_pure_coulomb_friction_reverses_the_trend(theta):
    """Fernandez-Nieto et al. (2016): with a constant friction coefficient the erodible bed
    shortens the run-out (by more than 2 % from 0 to 5 mm)."""
    bare, bed = (erodible_runout("erodible_bed_collapse_coulomb", theta, b) for b in (0.0, 0.005))
    assert bed < 0.98 * bare
