"""The grain–fluid mixture in several layers (engine/mixture/local_step.py: the Newton
iteration on the pore pressures and the thickness of the whole column): conservation,
exact rest, the one-layer run where the model makes the layers equivalent, the dry limit,
the convergence of the closure, and the layered result file and figure."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import multilayer
from multilayer.engine.config import InitialEntry, MixtureConfig, SimulationConfig
from multilayer.engine.simulation import Simulation
from multilayer.plugins.builtins import DilatantCoulomb, DruckerPrager
from multilayer.plugins.contract import Material

FLUID = MixtureConfig(
    fluid_density=1041.0, fluid_viscosity=96e-3, phi_critical=0.582, dilatancy=4.09, critical_shift=25.0
)
GRAINS = Material(density=1480.0, grain_diameter=160e-6, particle_density=2500.0)
TAN_DELTA = math.tan(math.radians(22.5))


def run(initial, *, layers=3, slope=25.0, cells=20, sides=("wall", "outflow"), mixture=FLUID, **kw):
    config = SimulationConfig(
        x_min=0.0, x_max=0.1, cells=cells, fractions=(1.0 / layers,) * layers, material=GRAINS,
        slope_deg=slope, initial=tuple(initial), left=sides[0], right=sides[1], mixture=mixture, **kw,
    )  # fmt: skip
    return Simulation(config, DilatantCoulomb(delta_deg=22.5, K1=90.5))


@pytest.mark.slow
@pytest.mark.parametrize("phi", [0.56, 0.6])
def test_layered_collapse_conserves_solid_and_balances_fluid(phi):
    """Loose (contracting) and dense (dilating) columns of three layers collapse: the
    solid is conserved to round-off, the pore fluid gained is what the ambient fluid lost,
    and the basal excess pore pressure of largest magnitude has the sign of the packing."""
    sim = run([InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=phi)], slope=10.0)
    solid0, volume0 = sim.mixture.solid.sum() * sim.dx, sim.h.sum() * sim.dx
    for _ in range(15):
        sim.step()
        sim.check_state()  # the guard: mixture volume = start + boundaries + ambient exchange
    assert np.any(sim.u != 0.0)
    assert abs(sim.mixture.solid.sum() * sim.dx - solid0) <= 1e-14 * solid0
    fluid = (sim.h.sum() - sim.mixture.solid.sum()) * sim.dx
    assert fluid - (volume0 - solid0) == pytest.approx(sim.mixture.ambient_exchange, abs=1e-15)
    bed = sim.mixture.pore_pressure[0]
    assert math.copysign(1.0, FLUID.phi_critical - phi) * bed[np.argmax(np.abs(bed))] > 0.0


def test_layered_heap_at_rest_is_exact():
    """An immersed heap below its static friction, three layers: u == 0.0, h, the solid of
    every layer and the pore pressures unchanged bit for bit."""
    points = ((0.0, 0.0), (0.05, 0.004), (0.1, 0.0))
    sim = run([InitialEntry("profile", points=points, phi=0.582)], slope=0.0, sides=("wall", "wall"))
    h0, solid0 = sim.h.copy(), sim.mixture.solid.copy()
    for _ in range(20):
        sim.step()
    assert np.all(sim.u == 0.0)
    assert np.array_equal(sim.h, h0) and np.array_equal(sim.mixture.solid, solid0)
    assert np.all(sim.mixture.pore_pressure == 0.0)


def test_uniform_layers_sliding_as_a_plug_are_the_one_layer_run():
    """Without fluid (rho_f = eta_f = 0) but with dilatancy (K > 0), a uniform dense layer
        slides as a plug on the bed: the dilation of the sheared bottom layer, l_0 h Phi_0 =
        2 |u| K (phi - phi_c), is the one-layer column's, and the yield stresses of the interfaces
        are proportional to the weight above them, so three layers move as the single layer
        does, and their solid fractions stay equal: the same run to 1e-12 (the Newton iterations
    stop at numerics.tolerance = 1e-10 of the residual; measured: 3e-14)."""
    dry_dilatant = MixtureConfig(0.0, 0.0, 0.582, 4.09, 0.0)
    entry = InitialEntry("layer", thickness=4.9e-3, phi=0.59)
    one = run([entry], layers=1, cells=2, sides=("periodic", "periodic"), mixture=dry_dilatant, slope=30.0)
    three = run([entry], layers=3, cells=2, sides=("periodic", "periodic"), mixture=dry_dilatant, slope=30.0)
    for _ in range(15):
        dt = one.step()
        assert three.step() == pytest.approx(dt, rel=1e-14)
        np.testing.assert_allclose(three.u, np.broadcast_to(one.u, three.u.shape), rtol=1e-12, atol=0.0)
        np.testing.assert_allclose(three.h, one.h, rtol=1e-12)
        phi = three.mixture.phi_layers(three.h)
        np.testing.assert_allclose(phi, np.broadcast_to(one.mixture.phi(one.h), phi.shape), rtol=1e-12)
    assert one.u.min() > 0.0 and one.mixture.phi(one.h)[0] < 0.59  # it slides and dilates


def test_dry_limit_of_three_layers_equals_the_dry_run():
    """No fluid and no dilatancy: the Coulomb collapse of the dry engine in three layers
    with the bulk density rho_s phi."""
    phi = 0.6
    dry_mixture = MixtureConfig(0.0, 0.0, 0.582, 0.0, 0.0)
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=phi)
    wet = run([entry], slope=20.0, mixture=dry_mixture)
    config = SimulationConfig(
        x_min=0.0, x_max=0.1, cells=20, fractions=(1.0 / 3.0,) * 3, slope_deg=20.0, left="wall",
        right="outflow", material=Material(2500.0 * phi, 160e-6, 2500.0 * phi),
        initial=(InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01),),
    )  # fmt: skip
    dry = Simulation(config, DruckerPrager(mu_s=TAN_DELTA, nu=0.0))
    for _ in range(40):
        wet.step()
        dry.advance(wet.t)
    scale = np.abs(dry.u).max()
    assert scale > 0.0
    np.testing.assert_allclose(wet.h, dry.h, rtol=0, atol=1e-12 * dry.h.max())
    np.testing.assert_allclose(wet.u, dry.u, rtol=0, atol=1e-10 * scale)


@pytest.mark.slow
def test_the_closure_of_several_layers_is_solved():
    """In a sheared dense column of four layers the effective pressures solve
    p_s = P + M Phi(p_s) (the pore pressures the dilation of every layer creates), and the
    local step converges in a few Newton iterations (counted: deterministic; a regression bound)."""
    sim = run(
        [InitialEntry("layer", thickness=4.9e-3, phi=0.588)],
        layers=4,
        cells=2,
        sides=("periodic", "periodic"),
    )
    iterations = []
    for _ in range(20):
        sim.step()
        iterations.append(sim.newton_iterations)
    local = sim.mixture.local
    solid, h = sim.mixture.solid[:, :1], sim.h[:1]
    gamma, p_s, dilation, pressure = local.closure(solid, h, sim.u[:, :1])
    assert np.all(gamma[0] > 0.0) and np.all(dilation[0] > 0.0)  # dense: the bed shears and dilates
    weight = local.buoyant_g_n * np.cumsum(solid[::-1], axis=0)[::-1]
    np.testing.assert_allclose(p_s, weight - pressure, rtol=1e-14)
    # the pore pressure integrated from the top down, layer by layer (trapezoidal)
    thickness, phi = local.l * h, solid / (local.l * h)
    D = local.drag(phi) / (1.0 - phi) ** 2
    rise = np.concatenate([[[0.0]], np.cumsum(thickness * dilation, axis=0)])
    expected = np.zeros(5)
    for a in range(3, -1, -1):
        expected[a] = expected[a + 1] - D[a, 0] * thickness[a, 0] * 0.5 * (rise[a, 0] + rise[a + 1, 0])
    np.testing.assert_allclose(pressure[:, 0], expected[:4], rtol=1e-12)
    assert pressure[0, 0] < 0.0
    steps = np.diff([0, *iterations])
    # measured: 14 at the onset from rest (where the search for the moving branch brackets
    # the pore pressures), then 3 per step
    assert steps[0] <= 20 and steps[1:].max() <= 4, steps


@pytest.mark.slow
def test_layered_result_holds_phi_per_layer_and_is_plotted(tmp_path):
    from multilayer.app import runner
    from multilayer.io.plotting import mixture_figure
    from multilayer.io.results import open_result

    path = Path(__file__).resolve().parents[1] / "scenarios" / "immersed_layer_dense.yaml"
    overrides = {"time.end": 0.1, "time.output_interval": 0.1, "domain.layers": 3, "domain.cells": 4}
    scenario = multilayer.load(path, overrides)
    summary = runner.run(scenario, tmp_path, quiet=True)
    assert summary["pore_pressure_bed_mean_final"] < 0.0  # dense: dilates
    ds = open_result(tmp_path)
    assert ds.sizes["layer"] == 3 and ds["phi_layer"].dims == ("time", "layer", "x")
    figure = mixture_figure(ds, scenario.name)
    assert figure.axes[3].get_ylabel().startswith("phi per layer")
    assert len(figure.axes[3].lines) == 3
