"""The grain–fluid mixture in x (engine/mixture/flow.py, local_step.py, solid_transport.py):
conservation, exact rest, the dry limit, the uniform layer in a periodic domain, resume,
and the scenario keys."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import multilayer
from multilayer.engine.config import InitialEntry, MixtureConfig, SimulationConfig
from multilayer.engine.mixture.flow import buoyant_fraction
from multilayer.engine.simulation import Simulation
from multilayer.errors import InputError
from multilayer.plugins.builtins import DilatantCoulomb, DruckerPrager
from multilayer.plugins.contract import Material

# Pailha et al. (2008), first fluid
FLUID = MixtureConfig(
    fluid_density=1041.0, fluid_viscosity=96e-3, phi_critical=0.582, dilatancy=4.09, critical_shift=25.0
)
GRAINS = Material(density=1480.0, grain_diameter=160e-6, particle_density=2500.0)


def mixture_run(initial, *, slope=25.0, cells=20, x_max=0.1, sides=("wall", "outflow"), mixture=FLUID, **kw):
    config = SimulationConfig(
        x_min=0.0, x_max=x_max, cells=cells, fractions=(1.0,), material=GRAINS, slope_deg=slope,
        initial=tuple(initial), left=sides[0], right=sides[1], mixture=mixture, **kw,
    )  # fmt: skip
    return Simulation(config, DilatantCoulomb(delta_deg=22.5, K1=90.5))


def test_solid_conserved_and_fluid_balanced_in_a_collapse():
    sim = mixture_run([InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=0.56)], slope=10.0)
    solid0, volume0 = sim.mixture.solid.sum() * sim.dx, sim.h.sum() * sim.dx
    for _ in range(15):
        sim.step()
        sim.check_state()  # the guard: mixture volume = start + boundaries + ambient exchange
    assert np.any(sim.u != 0.0)
    assert abs(sim.mixture.solid.sum() * sim.dx - solid0) <= 1e-14 * solid0
    # fluid: what the mixture holds more is what it drew from the ambient fluid
    fluid = (sim.h.sum() - sim.mixture.solid.sum()) * sim.dx
    assert fluid - (volume0 - solid0) == pytest.approx(sim.mixture.ambient_exchange, abs=1e-15)
    phi = sim.mixture.phi(sim.h)[sim.h > 1e-4]
    assert np.all((phi > 0.5) & (phi < 0.6))
    assert sim.mixture.pore_pressure[0].max() > 0.0  # a loose packing contracts: positive excess


def test_immersed_heap_at_rest_is_exact():
    points = ((0.0, 0.0), (0.05, 0.004), (0.1, 0.0))  # surface slope 0.08, below tan(22.5 deg)
    sim = mixture_run([InitialEntry("profile", points=points, phi=0.582)], slope=0.0, sides=("wall", "wall"))
    h0, solid0 = sim.h.copy(), sim.mixture.solid.copy()
    for _ in range(30):
        sim.step()
    assert np.all(sim.u == 0.0)
    assert np.array_equal(sim.h, h0) and np.array_equal(sim.mixture.solid, solid0)
    assert np.all(sim.mixture.pore_pressure == 0.0)


def test_dry_limit_equals_the_dry_run():
    """No fluid (rho_f = eta_f = 0) and no dilatancy (K = 0): the Coulomb collapse of the
    dry engine with the bulk density rho_s phi."""
    phi = 0.6
    dry_mixture = MixtureConfig(0.0, 0.0, 0.582, 0.0, 0.0)
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=phi)
    wet = mixture_run([entry], slope=20.0, mixture=dry_mixture)
    config = SimulationConfig(
        x_min=0.0, x_max=0.1, cells=20, fractions=(1.0,), slope_deg=20.0, left="wall", right="outflow",
        material=Material(2500.0 * phi, 160e-6, 2500.0 * phi),
        initial=(InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01),),
    )  # fmt: skip
    dry = Simulation(config, DruckerPrager(mu_s=math.tan(math.radians(22.5)), nu=0.0))
    for _ in range(40):
        wet.step()
        dry.advance(wet.t)  # the same steps, but for a last one of round-off length
    scale = np.abs(dry.u).max()
    assert scale > 0.0
    np.testing.assert_allclose(wet.h, dry.h, rtol=0, atol=1e-12 * dry.h.max())
    np.testing.assert_allclose(wet.u, dry.u, rtol=0, atol=1e-10 * scale)


def test_periodic_uniform_layer_is_the_column_step():
    """A uniform layer in a periodic domain stays uniform, and its trajectory is the
    local step of one column with the buoyant weight along the slope, to round-off."""
    sim = mixture_run(
        [InitialEntry("layer", thickness=4.9e-3, phi=0.584)], sides=("periodic", "periodic"), cells=4
    )
    column = sim.mixture.local
    s, h, v = sim.mixture.solid[:, :1].copy(), sim.h[:1].copy(), np.zeros((1, 1))
    g_t = 9.81 * math.sin(math.radians(25.0))
    for _ in range(40):
        dt = sim.step()
        r = buoyant_fraction(s / h, 2500.0, 1041.0)
        result = column(s, h, v + dt * r * g_t, dt)
        v, h = result.u, result.h
        assert np.ptp(sim.u) == 0.0 and np.ptp(sim.h) == 0.0
        assert sim.u[0, 0] == pytest.approx(v[0, 0], rel=1e-12)
        assert sim.h[0] == pytest.approx(h[0], rel=1e-14)
    assert sim.mixture.pore_pressure[0, 0] < 0.0  # dense: dilates, held by suction
    assert sim.mixture.phi(sim.h)[0] < 0.584


def test_resume_carries_the_mixture_state():
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=0.59)
    first = mixture_run([entry])
    for _ in range(10):
        first.step()
    saved = first.state_dict()
    assert {"solid", "pore_pressure"} <= set(saved)
    for _ in range(10):
        first.step()
    second = mixture_run([entry])
    second.load_state(saved)
    for _ in range(10):
        second.step()
    assert np.array_equal(first.u, second.u) and np.array_equal(first.h, second.h)
    assert np.array_equal(first.mixture.solid, second.mixture.solid)


SCENARIO = {
    "name": "immersed",
    "domain": {"x_min": 0.0, "x_max": 0.1, "cells": 10},
    "material": {"density": 1480, "grain_diameter": 160e-6, "particle_density": 2500},
    "rheology": {"name": "dilatant_coulomb", "delta_deg": 22.5, "K1": 90.5},
    "fluid": {"density": 1041, "viscosity": 0.096},
    "mixture": {"phi_critical": 0.582, "dilatancy": 4.09, "critical_shift": 25.0},
    "initial": [{"shape": "layer", "thickness": 0.005, "phi": 0.58}],
    "time": {"end": 1.0, "output_interval": 0.5},
}


@pytest.mark.parametrize(
    ("change", "key"),
    [
        ({"initial": [{"shape": "layer", "thickness": 0.005}]}, "initial.0.phi"),
        ({"mixture": None}, "mixture"),
        ({"fluid": {"density": 2600, "viscosity": 0.1}}, "fluid.density"),
        ({"fluid": {"density": 1000, "viscosity": -1}}, "fluid.viscosity"),
        (
            {"mixture": {"phi_critical": 1.2, "dilatancy": 4.09, "critical_shift": 25.0}},
            "mixture.phi_critical",
        ),
    ],
)
def test_mixture_keys_are_validated(change, key):
    data = {**SCENARIO, **change}
    data = {k: v for k, v in data.items() if v is not None}
    with pytest.raises(InputError, match=key.replace(".", r"\.")):
        multilayer.load(data)


def test_a_dry_scenario_refuses_phi():
    data = {k: v for k, v in SCENARIO.items() if k not in ("fluid", "mixture")}
    with pytest.raises(InputError, match=r"initial\.0\.phi"):
        multilayer.load(data)


def test_discrete_energy_identity_of_the_uniform_layer():
    """Per unit area, with the grains' buoyant weight P (normal) and F (downslope) and the
    distance X travelled, E = m v^2/2 + P h/2 - F X obeys, step by step,
    E' - E = -dt D' - m (v' - v)^2 / 2 with D = tan(delta) p_s |v| + K1 eta_f gamma |v|
    - tan(psi) p_e |v| >= 0 (gamma = 2 |v| / h: the lifting work of dilation, P |v| tan(psi),
    is what the dilatancy friction at p_s = P pays; the rest is Darcy's dissipation)."""
    phi0, theta = 0.584, math.radians(25.0)
    sim = mixture_run(
        [InitialEntry("layer", thickness=4.9e-3, phi=phi0)], sides=("periodic", "periodic"), cells=2
    )
    s = float(sim.mixture.solid[0, 0])
    weight = (2500.0 - 1041.0) * 9.81 * s
    P, F = weight * math.cos(theta), weight * math.sin(theta)

    def energy(x: float) -> float:
        h, v = float(sim.h[0]), float(sim.u[0, 0])
        mass = 2500.0 * s + 1041.0 * (h - s)
        return 0.5 * mass * v * v + 0.5 * P * h - F * x

    x = 0.0
    for _ in range(30):
        before, v0, h0 = energy(x), float(sim.u[0, 0]), float(sim.h[0])
        mass = 2500.0 * s + 1041.0 * (h0 - s)
        dt = sim.step()
        h, v, p_e = float(sim.h[0]), float(sim.u[0, 0]), float(sim.mixture.pore_pressure[0, 0])
        x += dt * v
        gamma, p_s = 2.0 * abs(v) / h, P - p_e
        tan_psi = FLUID.dilatancy * (
            s / h - FLUID.phi_critical + FLUID.critical_shift * FLUID.fluid_viscosity * gamma / p_s
        )
        D = (math.tan(math.radians(22.5)) * p_s + 90.5 * FLUID.fluid_viscosity * gamma - tan_psi * p_e) * abs(
            v
        )
        assert D >= 0.0
        change = energy(x) - before
        expected = -dt * D - 0.5 * mass * (v - v0) ** 2
        # the step's iteration stops at numerics.tolerance = 1e-10 (measured: 4e-12)
        assert change == pytest.approx(expected, rel=1e-9)


def test_result_file_holds_the_mixture_and_is_plotted(tmp_path):
    """phi, phi_layer and the basal pore pressure in result.nc, their summary means, the figure."""
    from multilayer.app import runner
    from multilayer.io.plotting import mixture_figure
    from multilayer.io.results import open_result

    path = Path(__file__).resolve().parents[1] / "scenarios" / "immersed_layer_loose.yaml"
    scenario = multilayer.load(path, {"time.end": 0.1, "time.output_interval": 0.1})
    summary = runner.run(scenario, tmp_path, quiet=True)
    assert summary["pore_pressure_bed_mean_final"] > 0.0  # loose: contracts
    assert summary["phi_mean_final"] == pytest.approx(0.562, abs=1e-3)
    ds = open_result(tmp_path)
    assert (
        ds["phi_layer"].dims == ("time", "layer", "x") and ds["pore_pressure_excess"].attrs["units"] == "Pa"
    )
    figure = mixture_figure(ds, scenario.name)  # drawn by plot_run beside the others
    assert [ax.get_ylabel().split()[0] for ax in figure.axes] == ["solid", "excess", "mean"]


def test_a_law_without_mixture_methods_is_a_law_of_the_effective_pressure():
    """The contract's defaults: drucker_prager (no mixture_* methods) with mu_s = tan(delta)
    and rho nu = K1 eta_f runs in a mixture exactly as dilatant_coulomb without dilatancy."""
    no_dilatancy = MixtureConfig(1041.0, 96e-3, 0.582, 0.0, 0.0)
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=0.58)
    config = SimulationConfig(
        x_min=0.0, x_max=0.1, cells=20, fractions=(1.0,), material=GRAINS, slope_deg=25.0,
        initial=(entry,), left="wall", right="outflow", mixture=no_dilatancy,
    )  # fmt: skip
    dilatant = Simulation(config, DilatantCoulomb(delta_deg=22.5, K1=90.5))
    coulomb = Simulation(
        config, DruckerPrager(mu_s=math.tan(math.radians(22.5)), nu=90.5 * 96e-3 / GRAINS.density)
    )
    for _ in range(20):
        dilatant.step()
        coulomb.advance(dilatant.t)
    assert np.abs(dilatant.u).max() > 0.0
    np.testing.assert_allclose(coulomb.u, dilatant.u, rtol=1e-12, atol=1e-12 * np.abs(dilatant.u).max())
    np.testing.assert_allclose(coulomb.h, dilatant.h, rtol=1e-13)


def test_a_dry_scenario_refuses_the_mixture_quantities():
    data = {k: v for k, v in SCENARIO.items() if k not in ("fluid", "mixture")}
    data["initial"] = [{"shape": "layer", "thickness": 0.005}]
    data["expect"] = [{"kind": "regression", "quantity": "phi_mean_final", "value": 0.5, "rtol": 0.1}]
    with pytest.raises(InputError, match=r"expect\.0\.quantity"):
        multilayer.load(data)
