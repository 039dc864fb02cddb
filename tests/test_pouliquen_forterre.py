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
from multilayer.engine.vertical import forms, newton
from multilayer.engine.vertical.coefficients import yield_law_of
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


def layer(theta, h, layers=8, speed=0.0, compiled=True, **extra):
    """A uniform glass-bead layer of thickness ``h`` on the slope ``theta`` (4 periodic
    columns), at rest or moving as a plug at ``speed``; ``extra`` parameters of the law;
    the compiled vertical step, or with ``compiled=False`` the numpy iteration."""
    initial = {"shape": "layer", "thickness": h}
    if speed:
        initial["velocity"] = {"profile": "plug", "speed": speed}
    sim = simulation(
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
    assert sim.vertical.compiled.laws() is not None  # the law has compiled forms
    if not compiled:
        sim.vertical.compiled = None
    return sim


def test_beta_of_the_law_is_the_flow_rule_s():
    assert pouliquen_beta(I_0, LENGTH, GRAIN, PACKING) == pytest.approx(BETA, rel=1e-14)
    law = PouliquenForterre(mu_1=MU_1, mu_2=MU_2, L=LENGTH, I_0=I_0)
    for theta in (21.5, 25.0, 31.0):
        h_stop = pouliquen_h_stop(theta, MU_1, MU_2, LENGTH)
        assert law.mu_stop(h_stop) == pytest.approx(math.tan(math.radians(theta)), rel=1e-14)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "numpy"])
@pytest.mark.parametrize("theta", [22.0, 25.0, 28.0])
def test_h_stop_is_exact(theta, compiled):
    """A layer 0.1 % thinner than h_stop(theta) stays exactly at rest (u == 0.0); one 0.1 %
    thicker flows; on both paths of the vertical step."""
    h_stop = pouliquen_h_stop(theta, MU_1, MU_2, LENGTH)
    below, above = (
        layer(theta, 0.999 * h_stop, compiled=compiled),
        layer(theta, 1.001 * h_stop, compiled=compiled),
    )
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


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "numpy"])
def test_a_layer_thinner_than_h_stop_launched_stops_exactly(compiled):
    """0.8 h_stop(25 deg) launched at 5 cm/s decelerates through the kink of mu at I_c and
    comes exactly to rest (u == 0.0), and stays there."""
    sim = layer(25.0, 0.8 * pouliquen_h_stop(25.0, MU_1, MU_2, LENGTH), speed=0.05, compiled=compiled)
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


def test_the_law_is_given_the_column_thickness():
    """Every call gets ``thickness`` = the column's h (broadcast like the pressure)."""
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


def _random_columns(seed, n=400):
    """Shear rates (0 and 1e-9 among them), pressures (negative and 0 among them) and column
    thicknesses (h_stop(25 deg) 0.999 and 1.001 times among them) over decades."""
    rng = np.random.default_rng(seed)
    h_stop = pouliquen_h_stop(25.0, MU_1, MU_2, LENGTH)
    rate = np.concatenate([[0.0, 1e-9, 1.0, 1.0], 10.0 ** rng.uniform(-6, 3, n)])
    pressure = np.concatenate([[0.0, -1.0, 30.0, 30.0], 10.0 ** rng.uniform(-3, 4, n)])
    h = np.concatenate([[1e-3, 1e-3, 0.999 * h_stop, 1.001 * h_stop], 10.0 ** rng.uniform(-4, -0.5, n)])
    return rate, pressure, h


def _compiled_law():
    law = PouliquenForterre(mu_1=MU_1, mu_2=MU_2, L=LENGTH, I_0=I_0, mu_3=0.40)
    form, params = law_of(law, MATERIAL)
    assert form == forms.FORMS["inertial_plateau"].code
    return law, form, tuple(params)  # a tuple, as the kernels hand them to the forms (forms.as_tuple)


def _pressure_part(form, params, p, h):
    """(factor, offset) of the compiled form's pressure parts at the pressure ``p``."""
    factor, offset = np.empty(1), np.empty(1)
    forms._pressure_parts(form, params, np.array([p]), h, factor, offset, 0)
    return factor[0], offset[0]


def test_the_compiled_viscosity_is_the_plugin_viscosity():
    """The inertial_plateau form against the law's numpy viscosity on random columns: the
    viscous stress eta |gamma| to 1e-12 of mu_2 p (round-off of the difference mu_J - mu_stop),
    and exactly 0 on the same side of the kink I_c(h) but within round-off of it."""
    law, form, params = _compiled_law()
    rate, pressure, h = _random_columns(0)
    parts = [_pressure_part(form, params, p, hj) for p, hj in zip(pressure, h)]
    got = (
        np.array([forms._viscosity_and_slope(form, params, r, *part)[0] for r, part in zip(rate, parts)])
        * rate
    )
    ref = law.viscosity(rate, pressure, MATERIAL, thickness=h) * rate
    scale = MU_2 * np.maximum(pressure, 0.0)
    assert np.all(np.abs(got - ref) <= 1e-12 * scale)
    assert np.all((got == 0.0) == (ref == 0.0) | (np.abs(ref) <= 1e-12 * scale))
    assert (got == 0.0).sum() > 10 and (got > 0.0).sum() > 100  # both branches sampled


def test_the_compiled_slope_is_the_derivative_of_the_plugin_stress():
    """d(eta gamma)/d gamma of the form against a centred difference of the law's stress,
    away from the kink at I_c(h)."""
    law, form, params = _compiled_law()
    rate, pressure, h = _random_columns(1)
    rate, pressure, h = rate[4:], pressure[4:], h[4:]
    step = 1e-6 * rate

    def stress(r):
        return law.viscosity(r, pressure, MATERIAL, thickness=h) * r

    below, above = stress(rate - step), stress(rate + step)
    smooth = (below > 0.0) | (above == 0.0)  # not across the kink
    centred = (above - below) / (2.0 * step)
    parts = [_pressure_part(form, params, p, hj) for p, hj in zip(pressure, h)]
    got = np.array([forms._viscosity_and_slope(form, params, r, *part)[1] for r, part in zip(rate, parts)])
    np.testing.assert_allclose(got[smooth], centred[smooth], rtol=1e-6, atol=1e-9 * np.abs(centred).max())
    assert smooth.sum() > 390


def test_the_compiled_yield_stresses_are_the_plugin_s_to_the_bit():
    """frictional_thickness: (mu_1 + D / (1 + h / L)) max(p, 0), and mu_3 for the static one."""
    law, _, _ = _compiled_law()
    assert yield_law_of(law, MATERIAL) == (MU_1, 0.40, MU_2 - MU_1, LENGTH)
    # a law that declares the thickness forms without using the thickness, or uses it with
    # forms that take none, stays on the numpy path
    plain = PouliquenForterre(mu_1=MU_1, mu_2=MU_2, L=LENGTH, I_0=I_0)
    plain.uses = ()
    assert law_of(plain, MATERIAL) is None and yield_law_of(plain, MATERIAL) is None


def test_the_compiled_step_is_the_numpy_iteration_on_a_collapse():
    """A glass-bead column collapsing on a 22 deg slope in a channel with side walls, on both
    paths: the same velocities to twice the Newton threshold per step, the same thicknesses,
    and exactly the same layers at rest (the deposit's tail thinner than h_stop(22 deg)
    stops)."""
    runs = []
    for compiled in (False, True):
        sim = simulation(
            slope_deg=22.0,
            domain={"x_min": 0.0, "x_max": 0.2, "cells": 25, "layers": 6, "width": 0.1},
            material={
                "density": PACKING * GRAIN_DENSITY,
                "grain_diameter": GRAIN,
                "particle_density": GRAIN_DENSITY,
            },
            rheology={"name": "pouliquen_forterre", "mu_1": MU_1, "mu_2": MU_2, "L": LENGTH, "I_0": I_0},
            walls={"name": "wall_friction", "mu_w": 0.1853},
            base=[{"condition": "no_slip"}],
            initial=[{"shape": "rectangle", "x_min": 0.0, "x_max": 0.04, "height": 0.03}],
            boundaries={"left": "wall", "right": "outflow"},
        )
        assert sim.vertical.compiled.laws() is not None
        if not compiled:
            sim.vertical.compiled = None
        for _ in range(50):
            sim.step()
        runs.append(sim)
    ref, got = runs
    threshold = ref.numerics.tolerance * ref.vertical.velocity_scale
    # regression: measured 317 against 306 iterations (3.6 %) over the 50 steps' 100
    # vertical steps (within 2 % with one vertical step per time step)
    assert abs(got.newton_iterations - ref.newton_iterations) <= 0.04 * ref.newton_iterations
    np.testing.assert_allclose(got.h, ref.h, rtol=100 * threshold / ref.vertical.velocity_scale, atol=0.0)
    np.testing.assert_allclose(got.u, ref.u, rtol=0.0, atol=2 * threshold)
    assert np.array_equal(got.u == 0.0, ref.u == 0.0)
    wet = ref.h > 0
    assert (ref.u[:, wet] == 0.0).any() and (ref.u != 0.0).any()  # both static and moving layers


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
