"""The grain–fluid mixture in x, in one layer and in several (engine/mixture/flow.py,
local_step.py, solid_transport.py): conservation, the sign of the pore pressure below a
column and at its front, exact rest, the dry limit, the uniform layer in a periodic domain,
layers equal to one layer where the model says so, the coupled closure of several layers,
the discrete energy in layers, resume, the result file, and the scenario keys."""

from __future__ import annotations

import dataclasses
import functools
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import TINY_SCENARIO

import multilayer
from multilayer.engine.config import InitialEntry, MixtureConfig, Numerics, SimulationConfig
from multilayer.engine.mixture import solid_transport
from multilayer.engine.mixture.closure import DENSEST_PACKING
from multilayer.engine.mixture.flow import buoyant_fraction
from multilayer.engine.mixture.local_step import LocalStep
from multilayer.engine.simulation import Simulation
from multilayer.errors import InputError, RunError
from multilayer.io.results import open_result
from multilayer.plugins.builtins import DilatantCoulomb, DruckerPrager
from multilayer.plugins.contract import Material, MixtureState

# Pailha et al. (2008), first fluid
FLUID = MixtureConfig(
    fluid_density=1041.0, fluid_viscosity=96e-3, phi_critical=0.582, dilatancy=4.09, critical_shift=25.0
)
GRAINS = Material(density=1480.0, grain_diameter=160e-6, particle_density=2500.0)


def mixture_run(
    initial, *, slope=25.0, cells=20, x_max=0.1, sides=("wall", "outflow"), mixture=FLUID, layers=1, **kw
):
    config = SimulationConfig(
        x_min=0.0, x_max=x_max, cells=cells, fractions=(1.0 / layers,) * layers, material=GRAINS,
        slope_deg=slope, initial=tuple(initial), left=sides[0], right=sides[1], mixture=mixture, **kw,
    )  # fmt: skip
    return Simulation(config, DilatantCoulomb(delta_deg=22.5, K1=90.5))


@pytest.mark.parametrize(
    ("layers", "phi"),
    [(1, 0.56), pytest.param(3, 0.56, marks=pytest.mark.slow), pytest.param(3, 0.6, marks=pytest.mark.slow)],
)
def test_solid_conserved_and_fluid_balanced_in_a_collapse(layers, phi):
    """Loose (contracting) and dense (dilating) collapses, in one layer and in three: the
    solid is conserved to round-off, the pore fluid gained is what the ambient fluid lost."""
    sim, solid0, volume0 = small_collapse(layers, phi)
    assert np.any(sim.u != 0.0)
    assert abs(sim.mixture.solid.sum() * sim.dx - solid0) <= 1e-14 * solid0
    # fluid: what the mixture holds more is what it drew from the ambient fluid
    fluid = (sim.h.sum() - sim.mixture.solid.sum()) * sim.dx
    assert fluid - (volume0 - solid0) == pytest.approx(sim.mixture.ambient_exchange, abs=1e-15)
    phi_now = sim.mixture.phi(sim.h)[sim.h > 1e-4]
    assert np.all((phi_now > 0.5) & (phi_now < 0.61))


@functools.cache
def small_collapse(layers: int, phi: float) -> tuple[Simulation, float, float]:
    """A 1 cm x 3 cm column at ``phi`` on a 10 degree slope after 15 steps, the guard
    checked at each; its solid and its volume at the start."""
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=phi)
    sim = mixture_run([entry], slope=10.0, layers=layers)
    solid0, volume0 = sim.mixture.solid.sum() * sim.dx, sim.h.sum() * sim.dx
    for _ in range(15):
        sim.step()
        sim.check_state()  # the guard: mixture volume = start + boundaries + ambient exchange
    return sim, solid0, volume0


def pressure_below_the_column(
    layers: int, phi: float, t_end: float = 1.0, mixture: MixtureConfig = FLUID
) -> float:
    """The basal excess pore pressure averaged below the initial column of
    :func:`small_collapse` (``x < 3 cm``), at its largest magnitude over the first
    ``t_end`` seconds (Pa, signed): the measure of the validation case
    ``submarine_collapse``."""
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=phi)
    sim = mixture_run([entry], slope=10.0, layers=layers, mixture=mixture)
    below = sim.x < 0.03
    means = []
    while sim.t < t_end:
        sim.step(t_end)
        means.append(sim.mixture.pore_pressure[0, below].mean())
    return float(means[int(np.argmax(np.abs(means)))])


@pytest.mark.parametrize(
    ("layers", "phi"),
    [
        (1, 0.56),
        pytest.param(1, 0.6, marks=pytest.mark.slow),
        pytest.param(3, 0.56, marks=pytest.mark.slow),
        pytest.param(3, 0.6, marks=pytest.mark.slow),
    ],
)
def test_the_pore_pressure_below_the_column_has_the_sign_of_the_packing(layers, phi):
    """What Rondon, Pouliquen & Aussillous (2011) measured: the excess pore pressure at the
    bed below the column, positive below a loose (contracting) column, negative below a
    dense (dilating) one.  Averaged below the initial column, at its largest magnitude over
    the first second (measured, one layer, at 20, 40 and 80 cells: loose +13.0, +23.1 and
    +30.3 Pa, while the dilating corner of the first steps gives -5.4, -9.3 and -10.9 Pa;
    dense -9.5, -13.6 and -16.4 Pa, never positive)."""
    assert math.copysign(1.0, FLUID.phi_critical - phi) * pressure_below_the_column(layers, phi) > 0.0


def test_a_moving_front_dilates_where_its_critical_state_says():
    """At the thin fast front of a loose column the model itself predicts dilation: the
    shear rate ``gamma = 2 |u| / h`` is large and the buoyant weight ``P`` small, so the
    critical fraction at the hydrostatic effective pressure,
    ``phi_eq(P) = phi_c - K2 eta_f gamma / P`` (Pailha & Pouliquen 2009, as in Bouchut et
    al. 2016), falls below ``phi``.  As the closure's dilation rate decreases with ``p_s``
    and ``p_s = P + B Phi(p_s)``, ``p_e`` has exactly the sign of ``phi_eq(P) - phi`` in
    every moving column, and a loose packing's suction is bounded by the thin-layer limit
    of the quadratic, ``p_e >= -sqrt(c) = -2 |u| sqrt(K K2 eta_f beta / 2) / (1 - phi)``
    (measured after 15 steps: -22.6 Pa at the front, the largest suction, where the column
    is less than half as thick as its body, bound -211 Pa; -52, -80, -128 and -174 Pa at
    40, 80, 160 and 320 cells, where the resolved front is steeper and sheared faster).
    The body contracts, and the front's suction need not exceed every contraction: that is
    not a property of the model.  The excess pressure at the bed of a column is
    ``-D h^2 d / 2`` (``D`` the Darcy drag, ``d`` the dilation rate:
    test_the_closure_of_several_layers_is_solved), drained over the column's thickness, so
    that which is larger depends on the squared ratio of the two columns' thicknesses and
    on their shear, the state of the step, not on the closure: here +28.1 Pa at the back
    of the column (9.3 mm thick, ``phi_eq - phi`` = +0.0085, gamma = 0.42 /s) against
    -22.6 Pa at the front (4.0 mm, -0.0168, 0.52 /s); +12.1 against -22.7 Pa with the
    mean pressure at faces at rest, which set the back column moving at another step."""
    sim = small_collapse(1, 0.56)[0]
    u = np.abs(sim.u[0])
    moving = u > 0.0
    h, u, p_e = sim.h[moving], u[moving], sim.mixture.pore_pressure[0, moving]
    phi = sim.mixture.phi(sim.h)[moving]
    P = (GRAINS.particle_density - FLUID.fluid_density) * 9.81 * math.cos(math.radians(10.0)) * phi * h
    phi_eq = FLUID.phi_critical - FLUID.critical_shift * FLUID.fluid_viscosity * (2.0 * u / h) / P
    assert np.any(phi_eq > phi) and np.any(phi_eq < phi)  # a contracting body, a dilating front
    np.testing.assert_array_equal(np.sign(p_e), np.sign(phi_eq - phi))
    beta = sim.mixture.local.drag(phi)
    suction = 2.0 * u * np.sqrt(FLUID.dilatancy * FLUID.critical_shift * FLUID.fluid_viscosity * beta / 2.0)
    assert np.all(p_e >= -suction / (1.0 - phi))
    front = np.argmin(p_e)
    assert h[front] < 0.5 * h.max()  # the thin front sucks hardest


RELAXING = dataclasses.replace(FLUID, compressibility=5e-5)
"""Pailha et al. (2008)'s first fluid with a skeleton compressibility of 5e-5 1/Pa (docs/mixture.md,
"A pore pressure with its own evolution")."""


@pytest.mark.parametrize(("layers", "mixture"), [(1, FLUID), (3, FLUID), (1, RELAXING), (3, RELAXING)])
def test_immersed_heap_at_rest_is_exact(layers, mixture):
    points = ((0.0, 0.0), (0.05, 0.004), (0.1, 0.0))  # surface slope 0.08, below tan(22.5 deg)
    sim = mixture_run(
        [InitialEntry("profile", points=points, phi=0.582)],
        slope=0.0,
        sides=("wall", "wall"),
        layers=layers,
        mixture=mixture,
    )
    h0, solid0 = sim.h.copy(), sim.mixture.solid.copy()
    for _ in range(30):
        sim.step()
    assert np.all(sim.u == 0.0)
    assert np.array_equal(sim.h, h0) and np.array_equal(sim.mixture.solid, solid0)
    assert np.all(sim.mixture.pore_pressure == 0.0)


def test_a_heap_at_rest_with_a_pore_pressure_consolidates_while_it_decays():
    """One layer: the heap above with a relaxing pore pressure of 0.3 of the buoyant weight:
    held at ``u == 0.0``, the pore pressure decaying and the mixture losing the fluid it
    drives out (George & Iverson 2014): every wet column thins at every step, so its packing
    rises; the solid of each column kept to round-off (the transport's remap to the new
    thickness: measured 2.0e-16 of the largest), its total to round-off."""
    points = ((0.0, 0.0), (0.05, 0.004), (0.1, 0.0))
    entry = InitialEntry("profile", points=points, phi=0.582)
    sim = mixture_run([entry], slope=0.0, sides=("wall", "wall"), layers=1, mixture=RELAXING)
    h0, solid0, local = sim.h.copy(), sim.mixture.solid.copy(), sim.mixture.local
    weight = local.buoyant_g_n * solid0[0]
    saved = sim.state_dict()
    saved["pore_pressure"] = 0.3 * weight[None, :]
    sim.load_state(saved)
    wet = h0 > 0.0
    for _ in range(10):
        before, h_before = sim.mixture.pore_pressure[0, wet].copy(), sim.h.copy()
        sim.step()
        assert np.all(sim.u == 0.0)
        assert np.all(np.abs(sim.mixture.solid - solid0) <= 4 * np.finfo(float).eps * solid0)
        assert abs(sim.mixture.solid.sum() - solid0.sum()) <= 16 * np.finfo(float).eps * solid0.sum()
        assert np.all(sim.h[wet] < h_before[wet]) and np.all(sim.h[~wet] == 0.0)
        after = sim.mixture.pore_pressure[0, wet]
        assert np.all(after < before) and np.all(after > 0.0)


@pytest.mark.parametrize("layers", [3])
def test_a_heap_at_rest_with_a_pore_pressure_stays_at_rest_while_it_decays(layers):
    """The heap above in three layers with a relaxing pore pressure of 0.3 of the buoyant
    weight above each interface: held at ``u == 0.0``, ``h`` and the solid bit for bit (the
    layered relaxation changes the volume by the dilatancy: docs/mixture.md), each pore
    pressure decaying by ``t_IG,a / (t_IG,a + dt)`` a step (Heun's two local steps compose
    backward Euler over ``dt``; measured to 0.45 eps of the weight), ``t_IG,a = alpha B_a``."""
    points = ((0.0, 0.0), (0.05, 0.004), (0.1, 0.0))
    entry = InitialEntry("profile", points=points, phi=0.582)
    sim = mixture_run([entry], slope=0.0, sides=("wall", "wall"), layers=layers, mixture=RELAXING)
    h0, solid0, local = sim.h.copy(), sim.mixture.solid.copy(), sim.mixture.local
    weight = local.buoyant_g_n * np.cumsum(solid0[::-1], axis=0)[::-1]
    saved = sim.state_dict()
    saved["pore_pressure"] = 0.3 * weight
    sim.load_state(saved)
    wet = h0 > 0.0
    B = local.darcy(solid0[:, wet], h0[wet]).sum(axis=1)
    for _ in range(10):
        before = sim.mixture.pore_pressure[:, wet]
        dt = sim.step()
        assert np.all(sim.u == 0.0)
        assert np.array_equal(sim.h, h0) and np.array_equal(sim.mixture.solid, solid0)
        t_ig = RELAXING.compressibility * B
        expected = before * t_ig / (t_ig + dt)
        assert np.all(
            np.abs(sim.mixture.pore_pressure[:, wet] - expected) <= 4 * np.finfo(float).eps * weight[:, wet]
        )
    assert np.all(sim.mixture.pore_pressure[:, wet] > 0.0)


@pytest.mark.parametrize("layers", [1, 3])
def test_dry_limit_equals_the_dry_run(layers):
    """No fluid (rho_f = eta_f = 0) and no dilatancy (K = 0): the Coulomb collapse of the
    dry engine with the bulk density rho_s phi, in one layer and in three."""
    phi = 0.6
    dry_mixture = MixtureConfig(0.0, 0.0, 0.582, 0.0, 0.0)
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=phi)
    wet = mixture_run([entry], slope=20.0, mixture=dry_mixture, layers=layers)
    config = SimulationConfig(
        x_min=0.0, x_max=0.1, cells=20, fractions=(1.0 / layers,) * layers, slope_deg=20.0, left="wall",
        right="outflow",
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


@pytest.mark.parametrize("order", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_periodic_uniform_layer_is_the_column_step(order):
    """A uniform layer in a periodic domain stays uniform, and its trajectory is the
    local step of one column with the buoyant weight along the slope, to round-off: at
    order 1 one local step over ``dt``; at order 2 (docs/model.md, "Time stepping") one
    over ``dt``, the transport's reduced gravity ``r0 g sin(theta) dt`` added to it,
    Heun's average with the state at the start (of ``h`` and of the momentum ``h v``),
    and one over ``dt/2``."""
    sim = mixture_run(
        [InitialEntry("layer", thickness=4.9e-3, phi=0.584)], sides=("periodic", "periodic"), cells=4,
        numerics=Numerics(order=order),
    )  # fmt: skip
    column, r0 = sim.mixture.local, sim.mixture.reduction
    s, h, v = sim.mixture.solid[:, :1].copy(), sim.h[:1].copy(), np.zeros((1, 1))
    g_t = 9.81 * math.sin(math.radians(25.0))
    for _ in range(40):
        dt = sim.step()
        r = buoyant_fraction(s / h, 2500.0, 1041.0)
        result = column(s, h, v + dt * r * g_t, dt)
        if order == 2:
            h_bar = 0.5 * (h + result.h)
            v_bar = 0.5 * (h * v + result.h * (result.u + dt * r0 * g_t)) / h_bar
            r = buoyant_fraction(s / h_bar, 2500.0, 1041.0)
            result = column(s, h_bar, v_bar + 0.5 * dt * (r - r0) * g_t, 0.5 * dt)
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
        # packings at or above the densest packing of spheres (Hales 2005)
        ({"initial": [{"shape": "layer", "thickness": 0.005, "phi": 0.75}]}, "initial.0.phi"),
        (
            {"mixture": {"phi_critical": 0.7405, "dilatancy": 4.09, "critical_shift": 25.0}},
            "mixture.phi_critical",
        ),
        # grains denser than nothing: the bulk denser than the grains
        (
            {"material": {"density": 1480, "grain_diameter": 160e-6, "particle_density": 1400}},
            "material.particle_density",
        ),
        # a law of the layer's thickness, which the mixture's local step cannot give it
        (
            {"rheology": {"name": "pouliquen_forterre", "mu_1": 0.38, "mu_2": 0.64, "L": 1e-3, "I_0": 0.3}},
            "rheology",
        ),
        # a Darcy drag that is not a finite number, named by the key that makes it so
        ({"fluid": {"density": 1041, "viscosity": 1e300}}, "fluid.viscosity"),
        (
            {"material": {"density": 1480, "grain_diameter": 1e-300, "particle_density": 2500}},
            "material.grain_diameter",
        ),
        (
            {"mixture": {"phi_critical": 0.582, "dilatancy": 4.09, "critical_shift": 25.0, "kozeny": 1e305}},
            "mixture.kozeny",
        ),
        # a relaxing pore pressure: alpha in (0, 1] 1/Pa
        ({"fluid": {"density": 1041, "viscosity": 0.096, "compressibility": 0.0}}, "fluid.compressibility"),
        ({"fluid": {"density": 1041, "viscosity": 0.096, "compressibility": 2.0}}, "fluid.compressibility"),
    ],
)
def test_mixture_keys_are_validated(change, key):
    data = {**SCENARIO, **change}
    data = {k: v for k, v in data.items() if v is not None}
    with pytest.raises(InputError, match=key.replace(".", r"\.")):
        multilayer.load(data)


def test_every_key_a_fluid_excludes_is_named_in_one_message():
    """A mixture with a gate, side walls and the non-hydrostatic pressure: one message at
    the first key naming the other two and what each accepts, not one key a run."""
    data = {
        **SCENARIO,
        "model": {"pressure": "non_hydrostatic"},
        "gate": {"x": 0.05, "lift_speed": 1.0},
        "domain": {**SCENARIO["domain"], "width": 0.1},
        "walls": {"name": "wall_friction", "mu_w": 0.2},
    }
    with pytest.raises(InputError) as raised:
        multilayer.load(data)
    message = str(raised.value)
    assert "model.pressure" in message and "not supported with a fluid (nor are walls, gate)" in message
    assert "hydrostatic with fluid; no walls with fluid; no gate with fluid" in message
    assert message.count("not supported with a fluid") == 1


def test_a_relaxing_pore_pressure_is_accepted_in_layers():
    data = {
        **SCENARIO,
        "fluid": {"density": 1041, "viscosity": 0.096, "compressibility": 1e-6},
        "domain": {"x_min": 0.0, "x_max": 0.1, "cells": 10, "layers": 3},
    }
    assert multilayer.load(data).fluid.compressibility == 1e-6


@pytest.mark.parametrize(
    ("layers", "dilatancy", "viscosity"), [(1, 4.09, 1e298), (3, 4.09, 1e298), (3, 1e300, 96e-3)]
)
def test_a_closure_that_overflows_stops_the_run_naming_its_keys(layers, dilatancy, viscosity):
    """A finite drag (4.7e307 Pa s/m^2, below the validation's bound) or a dilatancy
    constant of 1e300 whose closure overflows: the run stops with a message naming the
    closure's keys, never a plugin blamed for the pressure it was given, never a halving
    loop on a NaN step (3 layers), and no numpy warning printed on the way."""
    viscous = MixtureConfig(
        fluid_density=1041.0,
        fluid_viscosity=viscosity,
        phi_critical=0.582,
        dilatancy=dilatancy,
        critical_shift=25.0,
    )
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=0.58)
    sim = mixture_run([entry], slope=10.0, layers=layers, cells=6, mixture=viscous)
    keys = r"fluid\.viscosity, material\.grain_diameter and mixture\.kozeny, and with mixture\.dilatancy"
    with (
        warnings.catch_warnings(record=True) as caught,
        pytest.raises(RunError, match=f"closure overflowed.*{keys}"),
    ):
        warnings.simplefilter("always")
        sim.step()
    assert not [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)]


def test_a_local_step_that_diverges_stops_without_blaming_the_rheology():
    """A trial excess pore pressure that is not finite (here the guess) stops the local step
    naming it and the column, before the rheology is handed a NaN pressure (measured: a
    loose column of 1 mm grains in water on 25 degrees, numerics.order 2, diverged at its
    second step and blamed dilatant_coulomb)."""
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=0.58)
    sim = mixture_run([entry], slope=10.0, cells=6)
    local = sim.mixture.local
    guess = np.full(sim.u.shape, np.nan)
    with pytest.raises(
        RunError,
        match=r"local step diverged: a trial excess pore pressure is not finite \(its Newton .*\(at x = ",
    ):
        local(sim.mixture.solid, sim.h, sim.u, 1e-3, pressure_guess=guess, x=sim.x)


@pytest.mark.slow
def test_a_local_step_that_fails_on_a_huge_closure_constant_names_the_constants(
    tmp_path, cli, write_scenario
):
    """``mixture.critical_shift: 1e100`` in three layers of Drucker-Prager (within the
    validation's bound of the closure): the Newton iteration does not converge at the first
    step, in any number of sub-steps (here allowed 10 iterations: with the default 200 it
    creeps for up to 201 in each of 9 numbers of sub-steps, 49 s on a busy machine); the run
    stops, exit 1, naming the closure's keys with their values, the initial state kept."""
    data = {
        **TINY_SCENARIO,
        "numerics": {"max_iterations": 10},
        "material": {"density": 1500.0, "grain_diameter": 1e-3, "particle_density": 2500.0},
        "fluid": {"density": 1000.0, "viscosity": 1e-3},
        "mixture": {"phi_critical": 0.58, "dilatancy": 4.0, "critical_shift": 1e100},
        "initial": [{**TINY_SCENARIO["initial"][0], "phi": 0.58}],
    }
    result = cli("run", write_scenario(data), "-o", tmp_path / "out", "-q")
    assert result.code == 1, result.err
    assert "Traceback" not in result.err
    assert "mixture.dilatancy = 4 and mixture.critical_shift = 1e+100)" in result.err, result.err
    assert open_result(tmp_path / "out").sizes["time"] == 1


@pytest.mark.parametrize(
    ("key", "value", "code"),
    [("fluid.viscosity", 1e300, 2), ("mixture.dilatancy", 1e300, 2), ("mixture.critical_shift", 1e300, 2),
     ("mixture.kozeny", 1e300, 2), ("fluid.viscosity", 1e3, 0), ("mixture.dilatancy", 1e3, 0)],
)  # fmt: skip
def test_a_closure_that_overflows_on_the_initial_column_is_refused_at_validation(
    tmp_path, cli, write_scenario, key, value, code
):
    """A fluid viscosity, a dilatancy constant or a Carman-Kozeny constant of 1e300: the
    closure's quadratic bounded on the initial column overflows, so ``validate`` and ``run``
    refuse it in one message naming the key (the Carman-Kozeny constant was blamed on
    ``mixture.critical_shift``) and what is accepted (exit 2, no output directory); 1e3
    validates (its run, stiff, takes a minute: the battery's round 35 keeps its control of
    ``validate``)."""
    data = {
        **TINY_SCENARIO,
        "material": {"density": 1500.0, "grain_diameter": 1e-3, "particle_density": 2500.0},
        "fluid": {"density": 1000.0, "viscosity": 1e-3},
        "mixture": {"phi_critical": 0.58, "dilatancy": 4.0, "critical_shift": 25.0},
        "initial": [{**TINY_SCENARIO["initial"][0], "phi": 0.58}],
    }
    section, name = key.split(".")
    data[section] = {**data[section], name: value}
    path = write_scenario(data)
    runs = (("validate", path), ("run", path, "-o", tmp_path / "out", "-q"))
    for argv in runs if code else runs[:1]:
        result = cli(*argv)
        assert result.code == code, result.err
        if code:
            assert f"{key}: the mixture's closure overflows on the initial column" in result.err
            assert "mixture.kozeny = " in result.err and "accepted: values of these keys" in result.err
            assert result.err.count("error") == 1 and "Traceback" not in result.err
    assert not (tmp_path / "out").exists()


def test_a_dry_scenario_refuses_phi():
    data = {k: v for k, v in SCENARIO.items() if k not in ("fluid", "mixture")}
    with pytest.raises(InputError, match=r"initial\.0\.phi"):
        multilayer.load(data)


@pytest.mark.parametrize(
    ("packings", "slope"),
    [((0.584,), 25.0), ((0.584,) * 3, 25.0), ((0.64,) * 19 + (0.57,), 32.0)],
    ids=["one layer", "three layers", "twenty layers, a loose top"],
)
def test_the_energy_of_the_layered_time_loop_does_not_grow(packings, slope):
    """The energy of ``engine/mixture/exchange.py`` (Notes) in the time loop, for the Lie splitting
    (``numerics.order: 1``) of a uniform column whose layers hold the packings ``packings``
    (bottom up): ``E = sum_a m_a v_a^2 / 2 + h P_bar - W`` with the solid each layer holds
    now (the exchange between the layers moves it) and ``W`` the work of the downslope
    buoyant weight, ``dt sum_a F_a v*_a`` over each step (``v*`` the velocities with the
    step's drive, ``F`` of the solid the step starts from), does not grow, step by step; the
    column's solid is kept to round-off.  Twenty layers, the top one loose (0.57) over dense
    ones (0.64), on a slope (32 deg) that only the top interface yields to, is the column
    whose energy grows when the layers keep their solid (the fixed fractions lift the whole
    column for the dilation of the top interface): the exchange moves solid down through the
    layers below it, and the energy falls.  The dilation then loosens the two layers beside
    the sheared interface, and the layers below them lose less than 5 % of the packing the
    fixed fractions alone would take off (measured after 3 steps: 8.0e-7 against 1.9e-5;
    the layer just below the interface 3.9e-5).  In one layer nothing is exchanged."""
    sim = mixture_run(
        [InitialEntry("layer", thickness=4.9e-3, phi=0.6)], layers=len(packings), cells=2,
        sides=("periodic", "periodic"), slope=slope, numerics=Numerics(order=1),
    )  # fmt: skip
    l = sim.mixture.fractions
    sim.mixture.solid[...] = (np.array(packings) * l)[:, None] * sim.h
    sim.mixture.reset(0)
    theta = math.radians(slope)
    rho_s, rho_f = GRAINS.particle_density, FLUID.fluid_density
    centre = np.cumsum(l) - l / 2  # of each layer, over h
    total = sim.mixture.solid[:, 0].sum()
    W = 0.0

    def energy(s: np.ndarray) -> float:
        h, v = float(sim.h[0]), sim.u[:, 0]
        mass = rho_s * s + rho_f * (l * h - s)
        return float(
            np.sum(mass * v * v) / 2.0 + h * np.sum((rho_s - rho_f) * 9.81 * math.cos(theta) * s * centre)
        )

    for _ in range(8 if len(l) < 20 else 3):
        s = sim.mixture.solid[:, 0].copy()
        before, v0, h0 = energy(s) - W, sim.u[:, 0].copy(), float(sim.h[0])
        F = (rho_s - rho_f) * 9.81 * math.sin(theta) * s
        dt = sim.step()
        W += dt * float(np.sum(F * (v0 + dt * F / (rho_s * s + rho_f * (l * h0 - s)))))
        after = energy(sim.mixture.solid[:, 0]) - W
        assert after - before < 0.0
        assert abs(sim.mixture.solid[:, 0].sum() - total) <= 4.0 * np.finfo(float).eps * total
        phi = sim.mixture.phi_layers(sim.h)[:, 0]
        assert np.all((phi > 0.0) & (phi < 1.0))
    if len(l) == 1:
        assert sim.mixture.solid[0, 0] == total
    if len(l) == 20:
        phi = sim.mixture.phi_layers(sim.h)[:, 0]
        fixed = 0.64 * (1.0 - 4.9e-3 / sim.h[0])  # what the fixed fractions alone would take off
        assert np.all(np.abs(phi[:-2] - 0.64) < 0.05 * abs(fixed))
        # the top layer slides; the solid it gives carries its momentum into the layer below
        assert sim.u[-1, 0] > 0.0 and np.all(np.abs(sim.u[:-1, 0]) < 1e-3 * sim.u[-1, 0])


def _local_step_terms(local, law, solid, h0, v0, dt):
    """One local step of the columns ``solid`` (L, n), ``h0`` (n,) from the velocities ``v0``
    (L, n) (the step's drive included), and the terms of its energy identity (``LocalStep``,
    Notes) with ``E = sum_a m_a v_a^2 / 2 + h P_bar``: the step, ``E'' - E``, ``K``, ``K_x``,
    ``D`` and its lower bound's parts, the friction ``sum_a (tan(delta) p_s,a + K1 eta_f
    gamma_a) |jump_a|`` and the Darcy term ``sum_c D_c h_c W_c^2`` (both (n,)), and per
    interface the velocity jump, the work rate of its stress, ``tan(psi)``, the effective
    pressure and the dilation rate at the end of the step, all at the solid it starts from."""
    l, G = local.l, local.buoyant_g_n
    step = local(solid, h0, v0, dt)
    h, v, u, moved = step.h, step.solved, step.u, step.solid
    centre = np.cumsum(l, axis=0) - l / 2
    gamma, p_s, dilation, p_e = local.closure(solid, h, v)
    cfg = local.config
    phi = solid / (l * h)
    state = MixtureState(phi, p_e, cfg.fluid_viscosity, cfg.phi_critical, cfg.dilatancy, cfg.critical_shift)
    stress = (
        law.mixture_yield_stress(p_s, state, GRAINS)
        + law.mixture_viscosity(gamma, p_s, state, GRAINS) * gamma
    )
    jump = np.abs(np.diff(v, axis=0, prepend=0.0))
    m0, m1, m2 = local.masses(solid, h0), local.masses(solid, h), local.masses(moved, h)
    kinetic = np.sum(m0 * (v - v0) ** 2, axis=0) / 2.0
    merge = np.sum(m1 * v * v - m2 * u * u, axis=0) / 2.0
    change = np.sum(m2 * u * u - m0 * v0 * v0, axis=0) / 2.0 + G * np.sum(
        (h * moved - h0 * solid) * centre, axis=0
    )
    weight = G * np.cumsum(solid[::-1], axis=0)[::-1]  # P_a
    rise = local.spacing * h * dilation  # R_a / dt
    D = np.sum(jump * stress, axis=0) - np.sum(rise * weight, axis=0)
    friction = np.sum(
        jump * (math.tan(math.radians(22.5)) * p_s + 90.5 * cfg.fluid_viscosity * gamma), axis=0
    )
    drag = local.drag(phi) / (1.0 - phi) ** 2
    darcy = np.sum(drag * l * h * np.cumsum(rise, axis=0) ** 2, axis=0)
    tan_psi = np.where(gamma > 0.0, dilation / np.where(gamma > 0.0, gamma, 1.0), 0.0)
    return step, change, kinetic, merge, D, friction, darcy, jump, jump * stress, tan_psi, p_s, dilation


@pytest.mark.parametrize("layers", [1, 3])
def test_the_energy_identity_of_the_local_step_on_random_columns(layers):
    """The identity of ``engine/mixture/exchange.py`` (Notes) ``E'' - E = -dt D - K - K_x`` with
    ``E = sum_a m_a v_a^2 / 2 + h P_bar``, on 48 random columns (packings 0.52-0.64,
    1-10 mm, layer velocity increments 1e-4 to 0.2 m/s, one step of 5 ms, no drive): to 1e-9
    of its terms (measured: 5.4e-13 or less), ``D >= 0`` and ``K_x >= 0`` in each column,
    dilating or contracting (one layer: 20 and 2 of the 22 that move).  One layer exchanges
    nothing: its solid is kept bit for bit."""
    rng = np.random.default_rng(2016)
    l, law = np.full(layers, 1.0 / layers), DilatantCoulomb(delta_deg=22.5, K1=90.5)
    local = LocalStep(FLUID, law, GRAINS, l, 9.81 * math.cos(math.radians(25.0)), 1e-10, 200)
    h0 = rng.uniform(1e-3, 1e-2, 48)
    solid = rng.uniform(0.52, 0.64, (layers, 48)) * l[:, None] * h0
    v0 = np.cumsum(10.0 ** rng.uniform(-4.0, -0.7, (layers, 48)), axis=0)
    dt = 5e-3
    step, change, kinetic, merge, D, _, _, jump, work, _, _, dilation = _local_step_terms(
        local, law, solid, h0, v0, dt
    )
    terms = dt * work.sum(axis=0) + np.abs(change) + kinetic
    assert np.all(np.abs(change + dt * D + kinetic + merge) <= 1e-9 * terms)
    assert np.all(D >= 0.0) and np.all(merge >= -1e-12 * terms)
    if layers == 1:
        moving = step.u[0] > 0.0
        assert np.array_equal(step.solid, solid) and np.array_equal(step.u, step.solved)
        assert np.any(moving & (dilation[0] > 0.0)) and np.any(moving & (dilation[0] < 0.0))


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


@pytest.mark.parametrize("packing", ["loose", "dense"])
@pytest.mark.parametrize("layers", [2, 3, 5, 8])
def test_the_energy_inequality_and_the_balances_of_the_local_step_in_two_to_eight_layers(layers, packing):
    """On 24 random columns of ``layers`` equal layers, loose (packings 0.52-0.575, below
    phi_c = 0.582) or dense (0.59-0.64), 1-10 mm, layer velocity increments 1e-4 to 0.2 m/s,
    one step of 5 ms: the identity ``E'' - E = -dt D - K - K_x`` of ``engine/mixture/exchange.py`` (Notes) to
    1e-9 of its terms (measured: 5.5e-13 or less); the inequality term by term, ``D`` at
    least the rate-independent and viscous friction plus the Darcy term ``sum_c D_c h_c
    W_c^2`` (to 1e-9 of the work; it is more only where the law cuts its yield stress at
    zero), and ``E'' < E`` in every moving column; the column's solid to round-off (4 eps;
    each layer's changes by the exchange); the packings in (0, 1); the fluid the column
    gains, ``h' - h``, the fluid its layers' dilation draws from the ambient fluid of the
    column, ``dt h' sum_a l_a Phi_a``, to round-off (64 eps of the thickness).  Loose columns
    dilate and contract, dense ones dilate."""
    rng = np.random.default_rng(2016 + 10 * layers + (packing == "dense"))
    l, law = np.full(layers, 1.0 / layers), DilatantCoulomb(delta_deg=22.5, K1=90.5)
    local = LocalStep(FLUID, law, GRAINS, l, 9.81 * math.cos(math.radians(25.0)), 1e-10, 200)
    h0 = rng.uniform(1e-3, 1e-2, 24)
    low, high = (0.52, 0.575) if packing == "loose" else (0.59, 0.64)
    solid = rng.uniform(low, high, (layers, 24)) * l[:, None] * h0
    v0 = np.cumsum(10.0 ** rng.uniform(-4.0, -0.7, (layers, 24)), axis=0)
    dt = 5e-3
    step, change, kinetic, merge, D, friction, darcy, jump, work, _, _, dilation = _local_step_terms(
        local, law, solid, h0, v0, dt
    )
    h, moving = step.h, np.any(step.u != 0.0, axis=0)
    terms = dt * work.sum(axis=0) + np.abs(change) + kinetic
    assert np.all(np.abs(change + dt * D + kinetic + merge) <= 1e-9 * terms)
    assert np.all(D - friction - darcy >= -1e-9 * work.sum(axis=0))
    assert np.all(darcy >= 0.0) and np.all(merge >= -1e-12 * terms)
    assert np.all(change[moving] < 0.0) and np.count_nonzero(moving) >= 12
    eps = np.finfo(float).eps
    assert np.all(np.abs(step.solid.sum(axis=0) - solid.sum(axis=0)) <= 4.0 * eps * solid.sum(axis=0))
    assert not np.array_equal(step.solid, solid)  # the layers exchange solid
    phi = step.solid / (l[:, None] * h)
    assert np.all((phi > 0.0) & (phi < 1.0))
    drawn = dt * h * np.sum(l[:, None] * dilation, axis=0)
    assert np.all(np.abs(h - h0 - drawn) <= 64.0 * eps * h0)
    assert np.any(dilation < 0.0) if packing == "loose" else np.any(dilation > 0.0)


@pytest.mark.parametrize("layers", [20, 40, pytest.param(80, marks=pytest.mark.slow)])
def test_the_top_interface_of_many_layers_dissipates_with_the_exchange(layers):
    """A column of ``layers`` equal layers sheared at its top interface only (Pailha et al.
    (2008)'s first fluid, 4.9 mm, 32 deg, the top layer 0.57 over dense ones 0.64, one step
    of 5 ms from the top layer moving at 1 mm/s, driven by its buoyant weight).  The stress of
    that interface pays a share ``c_max`` of ``P_bar |jump| tan(psi)``, the lift the fixed
    fractions charge for its dilation if each layer kept its solid, that falls like 1/L
    (``p_s`` of the top interface is about its layer's buoyant weight, ``P_bar`` half the
    column's; measured ``c_max`` = 0.84, 0.31, 0.14, ``L p_s / P_bar`` = 2.06, 1.89, 1.81 at
    20, 40, 80 layers): kept, the solid would make the energy grow.  The exchange charges the
    model's lift, the top layer's weight, and the step dissipates: the identity
    ``E'' - E = -dt D - K - K_x`` to 1e-9 of its terms, ``D`` at least the rate-independent
    and viscous friction plus the Darcy term (measured: ``D`` = 6.0e-6, 8.1e-7 and 1.0e-7
    W/m^2), the column's solid to round-off; the layers below the two beside the sheared
    interface lose less than 5 % of the packing the fixed fractions alone would take off
    (measured: 4 %)."""
    theta = math.radians(32.0)
    l, law = np.full(layers, 1.0 / layers), DilatantCoulomb(delta_deg=22.5, K1=90.5)
    local = LocalStep(FLUID, law, GRAINS, l, 9.81 * math.cos(theta), 1e-10, 200)
    h0 = np.array([4.9e-3])
    solid = (np.array((0.64,) * (layers - 1) + (0.57,)) * l)[:, None] * h0
    drive = (local.rho_s - local.rho_f) * 9.81 * math.sin(theta) * solid / local.masses(solid, h0)
    v0 = np.zeros((layers, 1))
    v0[-1] = 1e-3
    dt = 5e-3
    step, change, kinetic, merge, D, friction, darcy, jump, work, tan_psi, p_s, _ = _local_step_terms(
        local, law, solid, h0, v0 + dt * drive, dt
    )
    # only the top interface shears, and it dilates
    assert np.all(jump[:-1] == 0.0) and jump[-1, 0] > 0.0 and tan_psi[-1, 0] > 0.0
    mean_weight = local.buoyant_g_n * float(np.sum(solid[:, 0] * (np.cumsum(l) - l / 2)))
    share = float(work[-1, 0] / (jump[-1, 0] * tan_psi[-1, 0] * mean_weight))  # c_max
    assert share < {20: 0.9, 40: 0.35, 80: 0.15}[layers]
    assert 1.5 < layers * float(p_s[-1, 0] / mean_weight) < 2.5
    terms = dt * work.sum(axis=0) + np.abs(change) + kinetic
    assert np.all(np.abs(change + dt * D + kinetic + merge) <= 1e-9 * terms)
    assert D[0] - friction[0] - darcy[0] >= -1e-9 * work.sum() and D[0] > 0.0
    assert D[0] == pytest.approx({20: 6.0e-6, 40: 8.1e-7, 80: 1.0e-7}[layers], rel=0.05)
    assert abs(step.solid.sum() - solid.sum()) <= 4.0 * np.finfo(float).eps * solid.sum()
    fixed = 0.64 * (1.0 - h0[0] / step.h[0])  # what the fixed fractions alone would take off
    assert np.all(np.abs(step.solid[:-2, 0] / (l[:-2] * step.h[0]) - 0.64) < 0.05 * fixed)


def test_the_darcy_term_of_the_closure_in_layers_is_a_sum_of_squares():
    """``engine/mixture/exchange.py`` (Notes): with each interface's rise ``R_a = dt spacing_a h Phi_a`` and
    the closure's pore pressures, ``-sum_a p_e,a R_a / dt = sum_c D_c h_c W_c^2``,
    ``W_c = sum_(b <= c) R_b / dt``: two equal layers of one packing (one drag ``D``), the bed
    dilating at ``Phi`` and the upper layer contracting at ``-1.25 Phi``, give
    ``W_0 = h Phi / 4``, ``W_1 = -3 h Phi / 8``, ``p_e,1 = 3 D h^2 Phi / 16`` and
    ``13 D h^3 Phi^2 / 128 > 0``."""
    l = np.full(2, 0.5)
    local = LocalStep(FLUID, DilatantCoulomb(delta_deg=22.5, K1=90.5), GRAINS, l, 9.81, 1e-10, 200)
    h = np.array([4.9e-3])
    solid = 0.6 * l[:, None] * h
    D = float(local.drag(np.array(0.6)) / 0.4**2)
    dilation = np.array([[1.0], [-1.25]])
    pore_pressure = -np.einsum("abn,bn->an", local.darcy(solid, h), dilation)
    darcy = float(np.sum(-pore_pressure * local.spacing * h * dilation))
    assert pore_pressure[1, 0] == pytest.approx(3.0 / 16.0 * D * h[0] ** 2, rel=1e-12)
    assert darcy == pytest.approx(13.0 * D * h[0] ** 3 / 128.0, rel=1e-12)


def test_one_layer_runs_are_the_one_layer_step_bit_for_bit():
    """Regression pin: a loose and a dense collapse of one layer (the rectangle of
    :func:`test_a_start_in_the_last_local_step_redoes_the_step_as_the_finished_local_step_does`,
    10 degrees, 15 steps) end at the time, thickness, velocity, solid and pore pressure (their
    sums, bit for bit) of the one-layer step without the exchange between layers, which one
    layer does not have (``LocalStep``, Notes): the pins are that step's output."""
    pins = {
        0.56: ("0x1.4f59cf077ec6dp-3", "0x1.eb88cd029f11fp-5", "0x1.d98c0e7ffa537p-8",
               "0x1.13404ea4a8c15p-5", "0x1.235b0cbc4be04p+2"),
        0.6: ("0x1.4907414893009p-3", "0x1.eb883c858bd81p-5", "0x1.4cc7de1f0b7bdp-15",
              "0x1.26e978d4fdf3ap-5", "-0x1.5fc8837b7199dp+5"),
    }  # fmt: skip
    for phi, pinned in pins.items():
        sim = mixture_run(
            [InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=phi)], slope=10.0
        )
        for _ in range(15):
            sim.step()
        sums = [float(np.sum(a)) for a in (sim.h, sim.u, sim.mixture.solid, sim.mixture.pore_pressure)]
        assert [float(sim.t).hex(), *(value.hex() for value in sums)] == list(pinned)


def test_uniform_layers_sliding_as_a_plug_are_the_one_layer_run():
    """Without fluid (rho_f = eta_f = 0) but with dilatancy (K > 0), a uniform dense layer
    slides as a plug on the bed: the dilation of the sheared bottom layer, l_0 h Phi_0 =
    2 |u| K (phi - phi_c), is the one-layer column's, and the yield stresses of the interfaces
    are proportional to the weight above them, so three layers move as the single layer
    does, and their solid fractions stay equal: the same run to 1e-12 (the Newton iterations
    stop at numerics.tolerance = 1e-10 of the residual; measured: 3e-14)."""
    dry_dilatant = MixtureConfig(0.0, 0.0, 0.582, 4.09, 0.0)
    entry = InitialEntry("layer", thickness=4.9e-3, phi=0.59)
    one = mixture_run(
        [entry], layers=1, cells=2, sides=("periodic", "periodic"), mixture=dry_dilatant, slope=30.0
    )
    three = mixture_run(
        [entry], layers=3, cells=2, sides=("periodic", "periodic"), mixture=dry_dilatant, slope=30.0
    )
    solid0 = three.mixture.solid.copy()
    for _ in range(15):
        dt = one.step()
        assert three.step() == pytest.approx(dt, rel=1e-14)
        # the solid of each layer: the local step keeps it, the uniform transport moves none
        # (the local step bit for bit; the transport to the round-off of its face volumes,
        # recovered from the change of h: about an eps a step over these 15 steps, measured
        # up to 7.5 eps; 4 eps before the local step's iterates moved in their last bits)
        np.testing.assert_allclose(three.mixture.solid, solid0, rtol=16 * np.finfo(float).eps, atol=0.0)
        np.testing.assert_allclose(three.u, np.broadcast_to(one.u, three.u.shape), rtol=1e-12, atol=0.0)
        np.testing.assert_allclose(three.h, one.h, rtol=1e-12)
        phi = three.mixture.phi_layers(three.h)
        np.testing.assert_allclose(phi, np.broadcast_to(one.mixture.phi(one.h), phi.shape), rtol=1e-12)
    assert one.u.min() > 0.0 and one.mixture.phi(one.h)[0] < 0.59  # it slides and dilates


@pytest.mark.slow
def test_the_closure_of_several_layers_is_solved():
    """In a sheared dense column of four layers the effective pressures solve
    p_s = P + M Phi(p_s) (the pore pressures the dilation of every layer creates), and the
    local step converges in a few Newton iterations (counted: deterministic; a regression
    bound), at order 1, one local step per time step (at order 2 a time step has two, one
    after each transport stage: measured 14, then 6 = 3 + 3)."""
    sim = mixture_run(
        [InitialEntry("layer", thickness=4.9e-3, phi=0.588)],
        layers=4,
        cells=2,
        sides=("periodic", "periodic"),
        numerics=Numerics(order=1),
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
    # the pore pressure integrated from the top down, layer by layer, with the grains' rise
    # through layer c the sum of the rises of the interfaces at and below it
    thickness, phi = local.l * h, solid / (local.l * h)
    D = local.drag(phi) / (1.0 - phi) ** 2
    rise = np.cumsum(local.spacing * h * dilation, axis=0)  # W_c
    expected = np.zeros(5)
    for a in range(3, -1, -1):
        expected[a] = expected[a + 1] - D[a, 0] * thickness[a, 0] * rise[a, 0]
    np.testing.assert_allclose(pressure[:, 0], expected[:4], rtol=1e-12)
    assert pressure[0, 0] < 0.0
    steps = np.diff([0, *iterations])
    # measured: 6 at the onset from rest (where the search for the moving branch brackets
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


@pytest.mark.slow
def test_a_failure_front_sets_the_loose_deposit_moving_at_the_long_wave_speed():
    """docs/mixture.md, "Why the loose deposit does not stay at rest": on 480 cells the
    upstream edge of the loose deposit's moving zone runs up the resting deposit to the wall
    at the speed of the long waves ``sqrt(g' h)`` (measured: 0.288 m/s against 0.283 m/s,
    1.15 to 1.65 s); on 120 cells, where the force that sets the next column moving (it
    grows as 1/dx) is four times weaker, the front is arrested: none runs."""
    from multilayer.validation.cases.submarine_collapse import failure_fronts

    path = Path(__file__).resolve().parents[1] / "scenarios" / "submarine_collapse_loose.yaml"
    fronts = {
        n: failure_fronts(multilayer.run(multilayer.load(path, {"domain.cells": n, "time.end": 1.8})))
        for n in (120, 480)
    }
    assert fronts[120] == []
    ((begin, end, speed, wave, edge),) = fronts[480]
    assert edge < 0.01 and end - begin > 0.1, (begin, end, edge)  # to the wall (at x = 0)
    assert abs(speed / wave - 1.0) < 0.05, (speed, wave)


def dense_wedge_stop(cfl: float, order: int) -> tuple[float, float, float]:
    """The time the dense submarine column (the shipped file at 15 cells) stops (the last
    step after which some velocity is non-zero), the mean step until then and, in a run
    whose step is cut to land on ``FLOWING``, its centre of mass then."""
    path = Path(__file__).resolve().parents[1] / "scenarios" / "submarine_collapse_dense.yaml"
    scenario = multilayer.load(path, {"domain.cells": 15, "time.cfl": cfl, "numerics.order": order})
    sim, flowing = multilayer.Simulation(scenario), multilayer.Simulation(scenario)
    while flowing.t < FLOWING:
        flowing.step(FLOWING)
    stop, steps = 0.0, 0
    while sim.t < 2.0 and not (sim.t > stop + 0.2):
        sim.step(2.0)
        if np.any(sim.u != 0.0):
            stop, steps = sim.t, sim.steps
    assert sim.t < 2.0, "the column did not stop"
    return stop, stop / steps, float(np.sum(flowing.x * flowing.h) / np.sum(flowing.h))


#: a time (s) at which the dense wedge flows and none of its columns has stopped yet (the
#: first stops at 0.078 s at order 1, Courant 0.4, and after 0.10 s at order 2)
FLOWING = 0.06


@pytest.mark.slow
@pytest.mark.parametrize("order", [1, 2])
def test_dense_collapse_stop_time_converges_at_first_order_in_dt(order):
    """The stop time converges at first order in the step (Courant numbers 0.4, 0.2, 0.1,
    0.05): read at the step, it differs from one level to the next by a number of the
    coarser level's steps that does not grow, at most that of the coarsest pair or one
    step, the resolution of a stop read at the step (measured at order 1: 18.2, 9.1 and
    2.3 ms, 1, 1 and 0.5 steps; at order 2, with the friction felt within each stage: 0,
    4.5 and 4.5 ms, 0, 0.5 and 1 steps; with the friction after both stages only: 63, 54,
    39 ms, 3.5, 6.0 and 8.5 steps).

    The flow converges at first order: the centre of mass at ``FLOWING``, while every
    released column moves, moves from one level to the next by 0.113, 0.047 and 0.022 mm
    at order 1 (0.041, 0.0094, 0.0029 mm at order 2), the last move less than a third of
    the first (a quarter at first order).  The deposit's centre is no such measure on this
    mesh: its 4 moving columns of 2 cm stop one by one, each stop read at a step, and a
    column at rest beside one that stops feels its face's pressure drop from the HLL mean
    ``g_n (hL^2 + hR^2) / 4`` to ``g_n hL hR / 2`` (docs/model.md, "Rest"), by
    ``g_n (hL - hR)^2 / 4``: columns stop and start again (1 to 3 times a run), in a
    sequence that changes with the step.  The deposit's centre at Courant 0.4, 0.2, 0.1,
    0.05, 0.025, 0.0125 (order 1): 37.05, 37.01, 36.55, 36.27, 36.31, 36.26 mm; it
    converges, by moves that do not shrink by a fixed ratio (0.04, 0.46, 0.28, 0.03,
    0.05 mm).  With the product pressure at every face (no drop when a column stops; not
    the scheme: the HLL flux's own pressure is the mean) no column starts again and the
    deposit's moves are 0.58, 0.34, 0.17, 0.07 and 0.05 mm."""
    stops, steps, centres = np.array([dense_wedge_stop(cfl, order) for cfl in (0.4, 0.2, 0.1, 0.05)]).T
    # numbers of steps, to the round-off of the mean step (a whole step reads 1 + 2e-16)
    in_steps = np.round(np.abs(np.diff(stops)) / steps[:-1], 9)
    assert np.all(in_steps[1:] <= max(in_steps[0], 1.0)), (stops, steps)
    moves = np.abs(np.diff(centres))
    assert moves[-1] < moves[0] / 3.0, centres


@pytest.mark.slow
def test_the_shipped_submarine_collapses_as_shipped_meet_the_loose_dense_contrast():
    """Rondon, Pouliquen & Aussillous (2011): a loose column runs out further than a dense
    one and stops sooner.  The two shipped files, as shipped: the loose run-out at least 1.5
    times the dense one, the loose column at rest before the end of its file (5 s) and the
    dense one still moving at the end of its own (10 s), so the dense collapse lasts at least
    twice as long."""
    scenarios = Path(__file__).resolve().parents[1] / "scenarios"
    loose, dense = (
        multilayer.run(multilayer.load(scenarios / f"submarine_collapse_{n}.yaml"))
        for n in ("loose", "dense")
    )
    runout = {n: float(ds["front"][-1] - ds["front"][0]) for n, ds in (("loose", loose), ("dense", dense))}
    assert runout["loose"] >= 1.5 * runout["dense"], runout
    moving = np.abs(loose["u"]).max(dim=[d for d in loose["u"].dims if d != "time"]) > 0.0
    loose_stop = float(loose["time"][moving.values][-1])  # the last output time with motion
    assert np.abs(dense["u"].isel(time=-1)).max() > 0.0
    assert float(dense["time"][-1]) >= 2.0 * loose_stop, (loose_stop, float(dense["time"][-1]))


def test_a_watched_column_set_moving_stops_the_local_step_at_its_first_evaluation():
    """The local step's ``watch`` (engine/mixture/local_step.py): a watched column that the
    first evaluation, at the rest state (``p_e = 0``, ``h = h*``), leaves at rest has
    converged there, and the step is that of no watch, bit for bit; one that it sets moving
    stops the step there, after one iteration, with that evaluation's velocities, pore
    pressures (the closure's at them) and thickness."""
    sim = mixture_run(
        [InitialEntry("layer", thickness=5e-3, phi=0.56)], cells=2, sides=("periodic", "periodic")
    )
    local, solid, h = sim.mixture.local, sim.mixture.solid.copy(), sim.h.copy()
    ustar, dt = np.array([[0.0, 0.05]]), 1e-3  # column 0 has nothing to move it, column 1 slides
    full = local(solid, h, ustar, dt)
    assert full.u[0, 0] == 0.0 and full.u[0, 1] > 0.0 and full.iterations > 1
    held = local(solid, h, ustar, dt, watch=np.array([True, False]))
    for got, expected in zip(
        (held.u, held.h, held.pore_pressure, held.iterations),
        (full.u, full.h, full.pore_pressure, full.iterations),
        strict=True,
    ):
        assert np.array_equal(got, expected)
    stopped = local(solid, h, ustar, dt, watch=np.array([False, True]))
    assert stopped.iterations == 1 and stopped.u[0, 0] == 0.0 and stopped.u[0, 1] > 0.0
    _, _, dilation, pressure = local.closure(solid, h, stopped.u)
    np.testing.assert_array_equal(stopped.pore_pressure, pressure)
    np.testing.assert_array_equal(stopped.h, h / (1.0 - dt * np.sum(local.l * dilation, axis=0)))
    assert stopped.pore_pressure[0, 1] != full.pore_pressure[0, 1]  # not the converged step


def _finished(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every local step finished: the last one of a time step stops at no start."""
    original = Simulation._vertical_step
    monkeypatch.setattr(Simulation, "_vertical_step", lambda self, *args, last=False: original(self, *args))


def _same_run(a: Simulation, b: Simulation) -> None:
    assert (a.t, a.steps) == (b.t, b.steps)
    for name in ("h", "u"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    for name in ("solid", "pore_pressure"):
        np.testing.assert_array_equal(getattr(a.mixture, name), getattr(b.mixture, name))
    assert a.mixture.ambient_exchange == b.mixture.ambient_exchange


@pytest.mark.parametrize(("layers", "order"), [(1, 2), (1, 1), pytest.param(3, 2, marks=pytest.mark.slow)])
def test_a_start_in_the_last_local_step_redoes_the_step_as_the_finished_local_step_does(
    layers, order, monkeypatch
):
    """A column at rest that the first evaluation of the time step's last local step sets
    moving stops that local step, and the step is redone with the column moving
    (docs/mixture.md, "Columns set moving"): in a collapse released from rest, loose and
    dense, whose front sets columns moving, the run is that of finished local steps bit
    for bit (every column so started is one the finished step sets moving too), in fewer
    Newton iterations, the solid conserved and the fluid balanced (the state guard, at
    every step); at order 2 the last local step is the second stage's, at order 1 the
    only one."""
    runs = {}
    for phi in (0.56, 0.6):
        for finish in (False, True):
            with monkeypatch.context() as patch:
                if finish:
                    _finished(patch)
                entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=phi)
                sim = mixture_run([entry], slope=10.0, layers=layers, numerics=Numerics(order=order))
                for _ in range(15):
                    sim.step()
                    sim.check_state()
            runs[phi, finish] = sim
        _same_run(runs[phi, False], runs[phi, True])
        assert runs[phi, False].newton_iterations < runs[phi, True].newton_iterations
        sim = runs[phi, False]
        assert np.count_nonzero(sim.h > sim.dry) > 6  # the front advanced beyond the 6 columns released


@pytest.mark.slow
@pytest.mark.parametrize("name", ["submarine_collapse_loose", "submarine_collapse_dense"])
def test_the_shipped_collapses_with_the_stop_at_a_start_are_those_of_finished_local_steps(name, monkeypatch):
    """The shipped submarine collapses to 1.5 s: the stop of the last local step at a start
    changes nothing but the Newton iterations (measured over the whole files on 60 cells:
    the same states bit for bit at every output time, benchmarks/history/mixture_starts.json)."""
    path = Path(__file__).resolve().parents[1] / "scenarios" / f"{name}.yaml"
    scenario = multilayer.load(path, {"time.end": 1.5})
    stopped = multilayer.Simulation(scenario)
    stopped.advance(1.5)
    _finished(monkeypatch)
    finished = multilayer.Simulation(scenario)
    finished.advance(1.5)
    _same_run(stopped, finished)
    assert stopped.newton_iterations < finished.newton_iterations


# ---------------------------------------------------------------- a relaxing pore pressure


def test_the_local_step_relaxes_its_pore_pressure_by_backward_euler():
    """One layer: ``alpha (p_e' - p_e) / dt = -p_e' / M - Phi(P - p_e')`` at any velocities."""
    local = LocalStep(
        RELAXING, DilatantCoulomb(delta_deg=22.5, K1=90.5), GRAINS, np.array([1.0]), 9.81, 1e-12, 50
    )
    solid, h = np.array([[2.8e-3, 5.6e-3, 2.8e-3]]), np.array([5e-3, 1e-2, 5e-3])
    v, previous, dt = np.array([[1e-3, 2e-2, 0.0]]), np.array([[3.0, -20.0, 5.0]]), 0.01
    _, _, dilation, p_e = local.closure(solid, h, v, previous, 5e-5 / dt)
    M = local.darcy(solid, h)[0, 0]
    terms = np.stack([5e-5 * p_e[0] / dt, -5e-5 * previous[0] / dt, p_e[0] / M, dilation[0]])
    eps = np.finfo(float).eps
    assert np.all(np.abs(terms.sum(axis=0)) <= 16 * eps * np.abs(terms).sum(axis=0))
    assert p_e[0, 2] == pytest.approx(5.0 * 5e-5 * M[2] / (5e-5 * M[2] + dt), rel=4 * eps)  # at rest: decays


@pytest.mark.parametrize("alpha", [5e-5, 5e-6])
def test_the_local_step_of_one_layer_loses_the_volume_its_pore_pressure_drives_out(alpha):
    """One relaxing layer: the step changes the thickness by the Darcy outflow of its pore
    pressure, ``h' - h* = -dt h' p_e' / B'`` (George & Iverson 2014), to round-off (4 eps of
    ``h'``), in columns set moving, moving and at rest; at rest ``u == 0.0`` and the column
    consolidates (``p_e > 0``) or swells (``p_e < 0``) as its pore pressure decays."""
    local = LocalStep(
        dataclasses.replace(FLUID, compressibility=alpha), DilatantCoulomb(delta_deg=22.5, K1=90.5), GRAINS,
        np.array([1.0]), 9.81, 1e-12, 50,
    )  # fmt: skip
    solid, h = np.array([[2.8e-3, 5.8e-3, 2.9e-3, 3.0e-3]]), np.array([5e-3, 1e-2, 5e-3, 5e-3])
    ustar, previous, dt = np.array([[0.1, 0.2, 0.0, 0.0]]), np.array([[3.0, -20.0, 5.0, -5.0]]), 0.01
    result = local(solid, h, ustar, dt, previous=previous)
    B = local.darcy(solid, result.h)[0, 0]
    drained = dt * result.h * result.pore_pressure[0] / B
    assert np.all(np.abs(result.h - h + drained) <= 4 * np.finfo(float).eps * result.h)
    assert np.all(result.u[:, :2] != 0.0) and np.all(result.u[:, 2:] == 0.0)
    assert result.h[2] < h[2] and result.h[3] > h[3]


@pytest.mark.parametrize("alpha", [5e-5, 5e-8])
@pytest.mark.parametrize("layers", [2, 3, 5])
def test_the_local_step_relaxes_each_pore_pressure_of_its_layers_by_backward_euler(layers, alpha):
    """Random columns, loose and dense: each pore pressure solves its own backward Euler,
    ``alpha B_a (p_e,a' - p_e,a) / dt = -(p_e,a' + (M Phi')_a)``, ``B_a = sum_b M_ab``, with
    ``Phi'`` at the effective pressures ``P - p_e'``, to round-off (16 eps of the column's
    largest term and weight; measured, at most 7.6 eps: the coupled closure takes one Newton
    step past its tolerance); a column at rest has
    ``Phi = 0`` and each of its pore pressures decays over its own ``t_IG,a = alpha B_a``."""
    local = LocalStep(
        dataclasses.replace(FLUID, compressibility=alpha), DilatantCoulomb(delta_deg=22.5, K1=90.5), GRAINS,
        np.full(layers, 1.0 / layers), 9.81, 1e-12, 50,
    )  # fmt: skip
    rng = np.random.default_rng(layers)
    n = 12
    h = rng.uniform(3e-3, 1e-2, n)
    solid = rng.uniform(0.52, 0.64, (layers, n)) * h / layers
    v = np.cumsum(rng.uniform(0.0, 1e-2, (layers, n)), axis=0)
    v[:, -1] = 0.0
    previous, dt = rng.uniform(-20.0, 20.0, (layers, n)), 0.01
    _, _, dilation, p_e = local.closure(solid, h, v, previous, alpha / dt)
    M = local.darcy(solid, h)
    B = M.sum(axis=1)
    terms = np.stack(
        [alpha * B * p_e / dt, -alpha * B * previous / dt, p_e, np.einsum("abn,bn->an", M, dilation)]
    )
    weight = local.buoyant_g_n * np.cumsum(solid[::-1], axis=0)[::-1]
    eps = np.finfo(float).eps
    assert np.all(np.abs(terms.sum(axis=0)) <= 16 * eps * (np.abs(terms).max(axis=(0, 1)) + weight[0]))
    r = alpha * B[:, -1] / dt
    assert np.all(np.abs(p_e[:, -1] - previous[:, -1] * r / (1.0 + r)) <= 4 * eps * weight[:, -1])


@pytest.mark.parametrize(
    ("layers", "phi", "slope"),
    [(1, 0.56, 10.0), (1, 0.6, 25.0), (3, 0.56, 10.0), pytest.param(3, 0.6, 25.0, marks=pytest.mark.slow)],
)
def test_a_relaxing_collapse_conserves_the_solid_and_resumes_exactly(layers, phi, slope):
    """Loose and dense columns in one and three layers: solid to round-off, fluid balanced
    with the ambient exchange, the pore pressures carried with the mixture, a resumed run
    the same bit for bit."""
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=phi)
    first = mixture_run([entry], slope=slope, mixture=RELAXING, layers=layers)
    solid0, volume0 = first.mixture.solid.sum() * first.dx, first.h.sum() * first.dx
    for _ in range(10):
        first.step()
        first.check_state()
    saved = first.state_dict()
    for _ in range(10):
        first.step()
        first.check_state()
    assert np.any(first.u != 0.0)
    assert abs(first.mixture.solid.sum() * first.dx - solid0) <= 1e-14 * solid0
    fluid = (first.h.sum() - first.mixture.solid.sum()) * first.dx
    assert fluid - (volume0 - solid0) == pytest.approx(first.mixture.ambient_exchange, abs=1e-15)
    assert np.all(first.mixture.pore_pressure[:, first.h == 0.0] == 0.0)
    second = mixture_run([entry], slope=slope, mixture=RELAXING, layers=layers)
    second.load_state(saved)
    for _ in range(10):
        second.step()
    assert np.array_equal(first.u, second.u) and np.array_equal(first.h, second.h)
    assert np.array_equal(first.mixture.solid, second.mixture.solid)
    assert np.array_equal(first.mixture.pore_pressure, second.mixture.pore_pressure)


@pytest.mark.parametrize(
    ("layers", "phi", "slope", "alphas"),
    [
        (1, 0.56, 10.0, (1e-9, 1e-10, 1e-11)),
        (3, 0.56, 25.0, (1e-10, 1e-11, 1e-12)),
        pytest.param(3, 0.6, 30.0, (1e-10, 1e-11, 1e-12), marks=pytest.mark.slow),
    ],
)
def test_a_vanishing_compressibility_is_the_closure_in_the_time_loop(layers, phi, slope, alphas):
    """A loose and a dense (slow) collapse after 10 steps: the difference to the closure's
    run in the velocities and the pore pressures falls as alpha (measured in three layers:
    orders 0.99997 to 1.0002).  In layers the steps end at fixed times (0.005 s) and the
    Newton iteration stops at ``numerics.tolerance = 1e-13``: a front column a few microns
    thick can have two roots of its step 4e-4 Pa apart, and which one the iteration reaches
    depends on where it starts (the relaxing run starts a column at rest from
    ``p_e r / (1 + r)``, the closure's from its last pore pressure; docs/mixture.md).  The
    loose collapse has such a column on every slope tried (0 to 30 degrees; on 10 degrees
    the runs then differ by 7.2e-6 of the largest speed for every alpha from 1e-10 to
    1e-12), so in layers the differences are measured in the body, the columns thicker than
    1 mm (7 of them), where the root of the front's column is not felt after 10 steps.  The
    dense collapse is compared after 5 steps: at the sixth, in the run at 1e-11 only, one
    column's Newton iteration fails and its step is done in 2 sub-steps (the continuation
    in ``dt``), which moves that run by 2e-3 of the column's speed for one step."""
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=phi)
    numerics = Numerics() if layers == 1 else Numerics(tolerance=1e-13)

    def run(mixture: MixtureConfig) -> Simulation:
        sim = mixture_run([entry], slope=slope, mixture=mixture, layers=layers, numerics=numerics)
        for k in range(5 if phi > FLUID.phi_critical else 10):
            sim.step(np.inf if layers == 1 else (k + 1) * 0.005)
        return sim

    closure = run(FLUID)
    body = closure.h > (1e-3 if layers > 1 else 0.0)
    errors = []
    for alpha in alphas:
        sim = run(dataclasses.replace(FLUID, compressibility=alpha))
        assert sim.t == closure.t
        pressure = (sim.mixture.pore_pressure - closure.mixture.pore_pressure)[:, body]
        errors.append(
            [
                float(np.max(np.abs(sim.u - closure.u)[:, body])) / float(np.max(np.abs(closure.u))),
                float(np.max(np.abs(pressure))) / float(np.max(np.abs(closure.mixture.pore_pressure))),
            ]
        )
    rates = np.log10(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(rates - 1.0) < 0.1), (errors, rates)


@pytest.mark.parametrize(("layers", "phi"), [(1, 0.56), (1, 0.6), (3, 0.56), (3, 0.6)])
def test_a_relaxing_pore_pressure_below_the_column_has_the_sign_of_the_packing(layers, phi):
    """The published signs with ``alpha = 5e-5`` 1/Pa (``t_IG`` about 5 s at the bed of the
    1 cm column), the measure of the closure's test: averaged below the initial column, at
    its largest magnitude over the first second (measured: +13.9 and -6.4 Pa in one layer,
    +10.0 and -5.4 Pa in three; in three layers the loose column's is -4.0 Pa over the first
    0.3 s only, its pore pressure building over ``t_IG``)."""
    pressure = pressure_below_the_column(layers, phi, mixture=RELAXING)
    assert math.copysign(1.0, FLUID.phi_critical - phi) * pressure > 0.0


@pytest.mark.parametrize("layers", [1, 3])
def test_a_layered_relaxing_result_holds_the_pore_pressure_of_each_layer(tmp_path, layers):
    """``pore_pressure_layer(time, layer, x)`` with a relaxing pore pressure in layers, its
    first layer ``pore_pressure_excess``; not written for one layer; the file checked and
    the layers' pore pressures drawn in the mixture's figure."""
    from multilayer.app import runner
    from multilayer.io.plotting import mixture_figure
    from multilayer.io.result_check import check_result
    from multilayer.io.results import open_result

    path = Path(__file__).resolve().parents[1] / "scenarios" / "immersed_layer_loose.yaml"
    overrides = {
        "time.end": 0.05, "time.output_interval": 0.025, "domain.layers": layers, "domain.cells": 4,
        "fluid.compressibility": 5e-5,
    }  # fmt: skip
    runner.run(multilayer.load(path, overrides), tmp_path, quiet=True)
    check_result(tmp_path)
    ds = open_result(tmp_path)
    assert ("pore_pressure_layer" in ds) == (layers > 1)
    if layers > 1:
        layered = ds["pore_pressure_layer"]
        assert layered.dims == ("time", "layer", "x") and layered.attrs["units"] == "Pa"
        assert np.array_equal(layered.values[:, 0], ds["pore_pressure_excess"].values)
        assert np.all(layered.values[-1] > 0.0)  # loose: contracts in every layer
    labels = [ax.get_ylabel().split("\n")[0] for ax in mixture_figure(ds, "loose").axes]
    assert labels[3:] == (["phi per layer", "p_e at the bottom"] if layers > 1 else [])
    if layers > 1:
        assert len(mixture_figure(ds, "loose").axes[4].lines) == layers


@pytest.mark.parametrize("layers", [2, 5])
def test_the_exchange_between_the_layers_charges_each_interface_the_model_lift(layers):
    """``LocalStep.exchange`` on random columns (packings 0.52-0.64, layer velocities up to
    0.2 m/s, dilation rates of either sign up to 2 /s at every interface, one step of
    5 ms): the potential energy changes by ``sum_a (R_a P_a - T_a P_bar)`` (what the lift of
    the model needs beyond the fixed fractions') to round-off (1e-12 of the potential
    energy ``h P_bar``), the
    column's solid and momentum are kept to round-off, its kinetic energy does not grow,
    and the packings stay in (0, 1).  A dilation that would take from a layer more solid
    than it holds (the same rates over 20 s) is refused: the column is marked, its solid and
    velocities returned as given."""
    rng = np.random.default_rng(42 + layers)
    l, law = np.full(layers, 1.0 / layers), DilatantCoulomb(delta_deg=22.5, K1=90.5)
    local = LocalStep(FLUID, law, GRAINS, l, 9.81, 1e-10, 200)
    n = 64
    h = rng.uniform(1e-3, 1e-2, n)
    solid = rng.uniform(0.52, 0.64, (layers, n)) * l[:, None] * h
    v = np.cumsum(rng.uniform(0.0, 0.2 / layers, (layers, n)), axis=0)
    dilation = rng.uniform(-2.0, 2.0, (layers, n))
    dt, G = 5e-3, local.buoyant_g_n
    moved, u, fine = local.exchange(solid, h, v, dilation, dt)
    assert fine.all() and not np.array_equal(moved, solid)
    centre = np.cumsum(l) - l / 2
    weight = G * np.cumsum(solid[::-1], axis=0)[::-1]
    mean_weight = np.sum(G * solid * centre[:, None], axis=0)
    needed = np.sum(dt * h * dilation * (local.spacing * weight - l[:, None] * mean_weight), axis=0)
    change = G * h * np.sum((moved - solid) * centre[:, None], axis=0)
    assert np.all(np.abs(change - needed) <= 1e-12 * h * mean_weight)
    eps = np.finfo(float).eps
    assert np.all(np.abs(moved.sum(axis=0) - solid.sum(axis=0)) <= 4.0 * eps * solid.sum(axis=0))
    m0, m1 = local.masses(solid, h), local.masses(moved, h)
    momentum = np.sum(m0 * v, axis=0)
    assert np.all(np.abs(np.sum(m1 * u, axis=0) - momentum) <= 1e-12 * momentum)
    assert np.all(np.sum(m1 * u * u, axis=0) <= np.sum(m0 * v * v, axis=0) * (1.0 + 1e-12))
    phi = moved / (l[:, None] * h)
    assert np.all((phi > 0.0) & (phi < 1.0))
    again, w, fine = local.exchange(solid, h, v, dilation, 20.0)
    assert not fine.all()
    assert np.array_equal(again[:, ~fine], solid[:, ~fine]) and np.array_equal(w[:, ~fine], v[:, ~fine])


@pytest.mark.parametrize(("interface", "rate"), [(1, -2.0), (3, -2.0), (1, 2.0), (3, 2.0)])
def test_a_contracting_interface_gathers_solid_into_its_layer(interface, rate):
    """``LocalStep.exchange`` in a uniform column of four layers (``phi = 0.3``) whose only
    dilating interface is ``interface`` (1 low in the column, 3 high), one step of 5 ms: the
    model moves the grains away from an interface that dilates and towards one that
    contracts, so the layer above it (whose packing sets its rate) gains solid where it
    contracts and loses solid where it dilates, and the potential energy changes by
    ``Q_a`` (engine/mixture/exchange.py, "The side").  Carried on the other side, a
    contraction low in the column emptied its layer into the one below it: a loose column
    in water (the next test) stopped after two steps."""
    layers = 4
    l, law = np.full(layers, 1.0 / layers), DilatantCoulomb(delta_deg=22.5, K1=90.5)
    local = LocalStep(FLUID, law, GRAINS, l, 9.81, 1e-10, 200)
    h = np.array([5e-3])
    solid = 0.3 * l[:, None] * h
    v = np.arange(1, layers + 1, dtype=float)[:, None] * 1e-3
    dilation = np.zeros((layers, 1))
    dilation[interface] = rate
    moved, _, fine = local.exchange(solid, h, v, dilation, 5e-3)
    assert fine.all()
    change = moved[interface, 0] - solid[interface, 0]
    assert math.copysign(1.0, change) == -math.copysign(1.0, rate)
    G, centre = local.buoyant_g_n, np.cumsum(l) - l / 2
    weight = G * np.cumsum(solid[::-1], axis=0)[::-1]
    mean_weight = np.sum(G * solid * centre[:, None], axis=0)
    needed = np.sum(5e-3 * h * dilation * (local.spacing * weight - l[:, None] * mean_weight), axis=0)
    assert G * h * np.sum((moved - solid) * centre[:, None], axis=0) == pytest.approx(needed, rel=1e-12)


WATER = dataclasses.replace(FLUID, fluid_density=1000.0, fluid_viscosity=1e-3)
"""A water-like fluid (1000 kg/m^3, 1 mPa s) with the closure constants of :data:`FLUID`."""


@pytest.mark.parametrize(
    ("layers", "phi"),
    [(4, 0.12), pytest.param(9, 0.12, marks=pytest.mark.slow), pytest.param(6, 0.3, marks=pytest.mark.slow)],
)
def test_a_loose_layer_in_water_compacts_in_layers(layers, phi):
    """A uniform layer far looser than its critical state (4.9 mm at ``phi = 0.12`` or
    0.3, 10.9 degrees, periodic) in water, 40 steps of the Lie splitting (steps up to 0.4
    s: ``dt |Phi|`` of order one): it compacts, every layer towards the critical state
    together, and comes to rest.  The solid is kept to round-off and every packing stays
    in ``(0, 0.6)`` at every step.  With the contraction carried away from its
    interface the runs stopped within three steps, naming the exchange; with a layer
    allowed to give all its content, the packings of the nine layers swung between
    neighbours from step to step, to 0.2 and 0.93, and with half, one of four layers
    ended at 0.748 (measured, at a quarter: at most 0.566, 0.579 and 0.586 in nine, four
    and six layers; engine/mixture/exchange.py, "The bounds")."""
    sim = mixture_run(
        [InitialEntry("layer", thickness=4.9e-3, phi=phi)], layers=layers, cells=2,
        sides=("periodic", "periodic"), slope=10.9, numerics=Numerics(order=1), mixture=WATER,
    )  # fmt: skip
    total = sim.mixture.solid.sum()
    for _ in range(40):
        sim.step()
        packings = sim.mixture.phi_layers(sim.h)
        assert np.all((packings > 0.0) & (packings < 0.6))
        assert abs(sim.mixture.solid.sum() - total) <= 16 * np.finfo(float).eps * total
    assert np.all(packings > 0.5)
    assert np.all(sim.u == 0.0)


def test_a_column_wetted_behind_a_front_takes_the_packing_of_the_column_it_came_from():
    """``solid_transport.transport`` of a uniform column (``phi = 0.55`` in three layers,
    the top layers fastest) into a dry column, the face beyond it carrying the round-off
    volume of the running sum of ``face_volumes`` (-1.9e-19 m^2 here): the newly wet
    column holds 0.55 in every layer.  That face once made the empty column beyond the front
    the source of the wet one's packing, and the exchange between its layers carried no
    solid: its packings were those of the layers' shares of the discharge, 0.12 at the bed
    to 0.77 at the top in a collapse of nine layers, and 1.0 a few steps on."""
    from multilayer.engine.mixture.solid_transport import face_volumes, transport

    h_old, h_new = np.array([0.1, 0.2, 0.0, 0.0]), np.array([0.1 - 0.01 - 0.01, 0.2 + 0.01, 0.01, 0.0])
    dx, crossed = 0.01, np.zeros(2)
    assert face_volumes(h_old, h_new, 0.0, dx)[3] < 0.0 < face_volumes(h_old, h_new, 0.0, dx)[2]
    l = np.full(3, 1.0 / 3.0)
    solid = 0.55 * l[:, None] * h_old
    u = np.array([1.0, 2.0, 3.0])[:, None] * np.array([0.0, 1.0, 0.0, 0.0])
    new, _ = transport(solid, h_old, h_new, u, l, crossed, dx, periodic=False)
    np.testing.assert_allclose(new[:, 2] / (l * h_new[2]), 0.55, rtol=1e-12)


def test_a_column_without_pores_stops_the_step_naming_the_transport():
    """A column whose layers hold no fluid (packing 1) and are wet: the local step's Darcy
    drag is infinite there, and the run stopped with the closure's overflow, which blames the
    fluid's viscosity, the grain diameter and the closure constants (with a compressibility,
    a crash: numpy's "Singular matrix").  No exchange between its layers can give them pores
    (:func:`solid_transport.bound_packings` leaves it), so the step stops before the local
    step, naming the transport, the layer and the column.  ``load_state`` refuses such a
    state (a column beyond the densest packing), so it is set in place."""
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=0.58)
    sim = mixture_run([entry], slope=0.0, layers=3, cells=6, sides=("wall", "wall"))
    saved = sim.state_dict()
    saved["solid"][:, 0] = sim.mixture.fractions * sim.h[0]  # the first column: phi = 1
    with pytest.raises(InputError, match=r"in column 0, .* a packing of 1, beyond the densest packing"):
        sim.load_state(saved)
    sim.mixture._solid[:, 0] = saved["solid"][:, 0]
    with pytest.raises(
        RunError, match=r"transport of the solid .* left layer 1 .* packing of 1\.0, outside \[0, 1\)"
    ):
        sim.step()


def test_the_transport_keeps_each_layer_within_the_packings_its_column_allows():
    """A thin column at a front can be left by the layered transport with a layer holding
    less than no solid or more than the densest packing of spheres (docs/mixture.md,
    "Layers"; collapses of nine and sixteen layers stopped there).  The transport moves
    the deficit and the excess between the layers of the column: its solid is kept to
    round-off, every layer ends within ``[0, DENSEST_PACKING]``, and a column within the
    bounds is not touched (bit for bit).  A column whose mean packing is out of bounds is
    left for the checks."""
    room = np.array([[1.0, 1.0, 1.0, 1.0], [2.0, 2.0, 2.0, 2.0], [1.0, 1.0, 1.0, 1.0]]) * 1e-3
    packing = np.array([[0.55, -0.2, 0.95, 0.8], [0.6, 0.5, 0.4, 0.8], [0.57, 0.6, 0.7, 0.8]])
    solid = packing * room
    before = solid.copy()
    solid_transport.bound_packings(solid, room)
    np.testing.assert_array_equal(solid[:, 0], before[:, 0])  # within bounds: untouched
    np.testing.assert_array_equal(solid[:, 3], before[:, 3])  # its mean beyond them: left
    np.testing.assert_allclose(solid.sum(axis=0), before.sum(axis=0), rtol=4 * np.finfo(float).eps)
    bounded = solid[:, 1:3] / room[:, 1:3]
    assert np.all(bounded >= 0.0) and np.all(bounded <= DENSEST_PACKING)
    assert bounded[0, 0] == 0.0 and bounded[0, 1] == DENSEST_PACKING
    # in a run (one stage: Heun's average with this start would be out of bounds as the
    # start is): one layer of a wet column at packing 1, the others at 0.58
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=0.58)
    sim = mixture_run(
        [entry], slope=0.0, layers=3, cells=6, sides=("wall", "wall"), numerics=Numerics(order=1)
    )
    saved = sim.state_dict()
    saved["solid"][1, 0] = sim.mixture.fractions[1] * sim.h[0]
    total = float(np.sum(saved["solid"]))
    sim.load_state(saved)
    sim.step()
    assert float(np.sum(sim.mixture.solid)) == pytest.approx(total, rel=1e-12)
    wet = sim.h > 0.0
    phi = sim.mixture.solid[:, wet] / (sim.mixture.fractions[:, None] * sim.h[wet])
    assert np.all(phi > 0.0) and np.all(phi <= DENSEST_PACKING)


@pytest.mark.slow
def test_the_local_step_leaves_each_layer_within_the_densest_packing_its_column_allows():
    """A critical column (``phi = phi_c = 0.58``) of 1 mm grains in water collapsing in
    three layers on 25 degrees between walls, Heun's steps: the exchange of the local step
    gathered the top layer of the thin column at its front beyond the densest packing of
    spheres (0.81 after Heun's first stage, 0.79 at the start of the next step), and Heun's
    average of that start with the bounded second stage kept half of it, so that the run
    stopped at step 28 naming a packing of 0.757 "that no grains reach" (with a
    compressibility it completed and wrote a result file of 0.7502 that its own check
    refused).  The local step's exchange now moves such an excess to the other layers of
    its column, as the transport does: at the end of every step every layer of a wet column
    holds a packing within ``[0, DENSEST_PACKING]``, the solid conserved to round-off."""
    water = MixtureConfig(
        fluid_density=1000.0, fluid_viscosity=1e-3, phi_critical=0.58, dilatancy=4.0, critical_shift=25.0
    )
    config = SimulationConfig(
        x_min=0.0, x_max=0.5, cells=40, fractions=(1.0 / 3.0,) * 3, slope_deg=25.0, left="wall", right="wall",
        material=Material(density=1500.0, grain_diameter=1e-3, particle_density=2500.0), mixture=water,
        initial=(InitialEntry("rectangle", x_min=0.0, x_max=0.1, height=0.05, phi=0.58),),
    )  # fmt: skip
    sim = Simulation(config, DilatantCoulomb(delta_deg=22.5, K1=90.5))
    total = sim.mixture.solid.sum()
    for _ in range(30):
        sim.step()
        wet = sim.h > config.numerics.dry_threshold
        packings = sim.mixture.solid[:, wet] / (sim.mixture.fractions[:, None] * sim.h[wet])
        assert np.all(packings >= 0.0) and np.all(packings <= DENSEST_PACKING * (1.0 + 1e-12))
        assert abs(sim.mixture.solid.sum() - total) <= 1e-13 * total
    assert sim.t > 0.195


def test_a_state_of_no_solid_in_a_wet_column_is_refused_on_loading():
    """A state to restore whose column thicker than the dry threshold holds no solid (a
    packing of 0, where the closure is not defined) is refused by ``load_state`` naming
    the column: it was refused only at the next step, the closure's constants blamed.  A
    layer emptied in a column that holds solid (as the bounds of the packings leave a thin
    layer at a front) is loaded."""
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=0.58)
    sim = mixture_run([entry], slope=0.0, layers=3, cells=6, sides=("wall", "wall"))
    saved = sim.state_dict()
    saved["solid"][:, 1] = 0.0
    with pytest.raises(InputError, match=r"solid holds 0 m in column 1, [0-9.]+ m thick .* a packing of 0"):
        sim.load_state(saved)
    saved = sim.state_dict()
    saved["solid"][2, 1] = 0.0
    sim.load_state(saved)


def test_a_column_beyond_the_densest_packing_stops_the_step_naming_it():
    """A column gathered beyond the densest packing of spheres (0.7405), which the exchanges
    between the layers of a column can do over many steps (docs/mixture.md, "Layers"):
    no packing of the grains is that dense, so the step stops before the local step, naming
    the layer, the column and the densest packing; just below it the step runs.  A state
    to restore that dense is refused by ``load_state`` (a checkpoint's solid 1.5 times its
    own was loaded and failed at its first step), so the gathered state is set in place."""
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.03, height=0.01, phi=0.58)
    for packing, stops in ((0.745, True), (0.735, False)):
        sim = mixture_run([entry], slope=0.0, layers=3, cells=6, sides=("wall", "wall"))
        saved = sim.state_dict()
        saved["solid"][:, 1] = packing * sim.mixture.fractions * sim.h[1]
        if stops:
            with pytest.raises(
                InputError,
                match=r"in column 1, .* a packing of 0\.745, beyond the densest packing of spheres",
            ):
                sim.load_state(saved)
            sim.mixture._solid[:, 1] = saved["solid"][:, 1]
        else:
            sim.load_state(saved)
        if stops:
            with pytest.raises(
                RunError,
                match=r"layer 1 .* packing of 0\.74\d*, beyond the densest packing of spheres, 0\.7405",
            ):
                sim.step()
        else:
            sim.step()


@pytest.mark.parametrize(
    ("changes", "named"),
    [
        ({"mixture.dilatancy": 1e10}, "mixture.dilatancy = 1e+10"),
        (
            {
                "fluid.compressibility": 1.0,
                "domain.layers": 1,
                "rheology": {"name": "dilatant_coulomb", "delta_deg": 25.0, "K1": 0.0},
            },
            "with the relaxation of fluid.compressibility = 1 1/Pa",
        ),
    ],
    ids=["closure not converging", "compressibility 1"],
)
def test_a_local_step_that_fails_names_the_closures_keys(changes, named):
    """A local step whose closure does not converge (a dilatancy constant of 1e10) said only
    "the mixture's closure did not converge", and one whose Newton iteration under a
    compressibility of 1 1/Pa (the dilatant law in one layer) did not converge named the
    closure's constants without the compressibility: the message names the keys the Newton
    steps scale with, as given."""
    data = {
        **TINY_SCENARIO,
        "material": {"density": 1500.0, "grain_diameter": 1e-3, "particle_density": 2500.0},
        "fluid": {"density": 1000.0, "viscosity": 1e-3},
        "mixture": {"phi_critical": 0.58, "dilatancy": 4.0, "critical_shift": 25.0},
        "initial": [{**TINY_SCENARIO["initial"][0], "phi": 0.58}],
    }
    sim = multilayer.Simulation(multilayer.load(data, changes))
    with pytest.raises(RunError, match="did not converge") as failed:
        sim.advance(0.2)
    assert named in str(failed.value) and "mixture.kozeny = 150" in str(failed.value)
