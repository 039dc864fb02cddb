"""Full-resolution validation against the references that the model meets.

Marked ``validation``: deselected by default, run with ``python -m pytest -m validation``
(a few minutes on 2 cores).  ``docs/make_validation.py`` writes the full report, including
the references that are not met; these tests keep the met ones from regressing.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from test_transport import ritter_error

from multilayer.engine.simulation import Simulation
from multilayer.io.scenario import load
from multilayer.reference import similarity
from multilayer.reference.exact import BagnoldFlow, InviscidSimpleShear, jop_inertial_number

pytestmark = pytest.mark.validation

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"


def run(name: str, *overrides: str) -> Simulation:
    sim = Simulation(load(SCENARIOS / f"{name}.yaml", overrides))
    sim.advance(sim.scenario.time.end)
    return sim


def test_ritter_dam_break_order_at_high_resolution():
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


@pytest.mark.parametrize(
    "changes",
    [
        (),  # power law alpha = 0.34 on 16 deg: measured slope 0.725 vs 0.746, size 0.95
        # classical Blasius (alpha = 1) on a horizontal chute, where gravity does not
        # accelerate the outer flow: measured slope 0.483 vs 0.5, size 1.06
        ("rheology.alpha=1", "rheology.m=0.2", "slope_deg=0"),
    ],
    ids=["power_law", "linear_horizontal"],
)
def test_granular_blasius_boundary_layer_grows_like_x_to_the_one_over_one_plus_alpha(changes):
    """Tsang et al. (2019): the displacement thickness grows like x^(1/(1+alpha)) and
    matches the size of the similarity solution, without a fitted constant."""
    sim = run("smooth_to_rough_chute", "domain.cells=440", "time.end=1.2", *changes)
    sc = sim.scenario
    alpha, m = sc.rheology.params["alpha"], sc.rheology.params["m"]
    h_in, speed = sc.boundaries.inflow.thickness, sc.boundaries.inflow.velocity.speed
    disp = similarity.displacement_thickness(sim.u, sim.fractions[:, None] * sim.h[None, :])
    solution = similarity.solve_similarity(alpha)
    eps = similarity.boundary_layer_scale(alpha, m, sc.slope_deg, h_in, speed, sc.material.grain_diameter)
    predicted = (
        solution.displacement_thickness * eps * h_in * (np.maximum(sim.x, 0) / h_in) ** (1 / (1 + alpha))
    )
    thin = (sim.x >= 4 * sim.dx) & (predicted <= 0.1 * h_in)
    slope = np.polyfit(np.log(sim.x[thin]), np.log(disp[thin]), 1)[0]
    assert slope == pytest.approx(1 / (1 + alpha), abs=0.04)
    assert np.median(disp[thin] / predicted[thin]) == pytest.approx(1.0, abs=0.1)


def test_bagnold_profile_converges_with_the_layers():
    """Layer velocities against Bagnold's profile averaged over each layer: second order."""
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
    assert errors[-1] < 0.005
    assert np.all(orders > 1.3)


def test_erodible_bed_lengthens_the_runout_at_22_degrees_with_mu_i():
    """Farin et al. (2014), Fernandez-Nieto et al. (2016): with mu(I) at 22 degrees the
    run-out grows with the erodible-bed thickness (measured 0.894 m bare, 0.947 m on 5 mm)."""
    bare = run(
        "erodible_bed_collapse",
        "time.end=3.0",
        "numerics.front_threshold=0.001",
        "initial=[{shape: rectangle, x_min: -0.25, x_max: -0.05, height: 0.14}]",
    )
    bed = run(
        "erodible_bed_collapse", "time.end=3.0", "initial.0.thickness=0.005", "numerics.front_threshold=0.006"
    )
    assert bed.diagnostics()["front"] > bare.diagnostics()["front"] + 0.03
