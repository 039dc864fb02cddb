"""The uniform immersed layer with a relaxing excess pore pressure (the skeleton's
compressibility ``alpha``, George & Iverson 2014; Bouchut et al. 2016): the closure as
``alpha -> 0``, the backward-Euler step against Radau IIA, rest, signs and energy."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from multilayer.engine.mixture.closure import basal_closure
from multilayer.engine.mixture.uniform_layer import LayerState
from multilayer.errors import InputError
from multilayer.reference.immersed_layer import pailha_2008_layer
from multilayer.validation.cases.immersed_layer import ode_met, step_errors
from multilayer.validation.mesh_study import MeshStudy

EPS = np.finfo(float).eps


def test_the_relaxed_step_solves_its_backward_euler_equation():
    """``alpha (p_e' - p_e) / dt = -p_e' / B - Phi(P - p_e')`` at the closure's trial values."""
    layer = pailha_2008_layer(0.562, compressibility=5e-6)
    mat, dt, previous = layer.material, 0.01, 3.0
    for speed in (0.0, 1e-4, 1e-2):
        cl = basal_closure(mat, layer.solid, layer.weight, 5e-3, speed, 5e-6 / dt, previous)
        B = 0.5 * cl.beta * 5e-3**2 / (1.0 - cl.phi) ** 2
        terms = (5e-6 * cl.p_e / dt, -5e-6 * previous / dt, cl.p_e / B, cl.dilation)
        assert abs(sum(terms)) <= 16 * EPS * sum(abs(q) for q in terms)


@pytest.mark.parametrize(("phi0", "t_end", "steps"), [(0.562, 60.0, 160), (0.592, 400.0, 80)])
def test_a_vanishing_compressibility_converges_to_the_closure_at_order_one(phi0, t_end, steps):
    """At a fixed step the relaxed run differs from the closure's by O(alpha B / dt)."""
    closure = pailha_2008_layer(phi0).run(t_end, t_end / steps)
    alphas = (5e-9, 5e-10, 5e-11)
    errors = []
    for alpha in alphas:
        run = pailha_2008_layer(phi0, compressibility=alpha).run(t_end, t_end / steps)
        errors.append(
            max(
                float(np.max(np.abs(run.v - closure.v))) / float(np.max(np.abs(closure.v))),
                float(np.max(np.abs(run.p_e - closure.p_e))) / pailha_2008_layer(phi0).weight,
            )
        )
    rates = np.log10(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(rates - 1.0) < 0.1), (errors, rates)


@pytest.mark.parametrize(("phi0", "t_end"), [(0.562, 60.0), (0.592, 400.0)])
def test_the_relaxation_converges_at_order_one_to_the_tight_ode_solution(phi0, t_end):
    """alpha = 5e-5 1/Pa (t_IG 1.3 and 1.7 s): errors in v, h and p_e against Radau IIA."""
    steps = (40, 80, 160)
    layer = pailha_2008_layer(phi0, compressibility=5e-5)
    errors = step_errors(layer, t_end, steps, fields=("v", "h", "p_e"))
    rates = MeshStudy(steps, tuple(errors)).orders()
    assert ode_met(rates), (errors, rates)


def _outflow(layer, h: float, p_e: float, dt: float) -> float:
    """``dt h p_e / B`` (m): the Darcy outflow of a step ending at ``h`` with the pore pressure
    ``p_e``, ``B = beta h^2 / (2 (1 - phi)^2)``."""
    phi = layer.solid / h
    return dt * h * p_e / (0.5 * layer.material.drag(phi) * h * h / (1.0 - phi) ** 2)


@pytest.mark.parametrize("fraction", [0.08, -0.2])
def test_a_layer_held_at_rest_consolidates_as_its_pore_pressure_decays(fraction):
    """Held: ``v == 0.0`` and ``u == 0.0`` at every step, ``p_e' = p_e t_IG' / (t_IG' + dt)``
    (``t_IG'`` at the new thickness) and the thickness changes by the Darcy outflow alone,
    ``h' - h = -dt h' p_e' / B'``: a positive pore pressure drains and the packing
    consolidates, a negative one draws fluid in and it swells, as the pore pressure decays
    (George & Iverson 2014).  Half the weight carried unlocks the layer."""
    layer = dataclasses.replace(pailha_2008_layer(0.60, compressibility=5e-5), slope_deg=24.0)
    dt, s = 0.3, LayerState(0.0, layer.h0, 0.0, 0.0, 0.0, fraction * layer.weight)
    outflow = 0.0
    for _ in range(50):
        new = layer.step(s, dt)
        assert new.v == 0.0 and new.u == 0.0
        t_ig = layer.relaxation_time(new.h)
        assert new.p_e == pytest.approx(s.p_e * t_ig / (t_ig + dt), rel=4 * EPS)
        drained = _outflow(layer, new.h, new.p_e, dt)
        assert abs(new.h - s.h + drained) <= 4 * EPS * new.h
        assert np.sign(s.h - new.h) == np.sign(fraction)  # consolidates (p_e > 0) or swells (p_e < 0)
        outflow += drained
        s = new
    assert abs(layer.h0 - s.h - outflow) <= 64 * EPS * layer.h0
    assert abs(s.p_e) < 0.01 * abs(fraction) * layer.weight  # 50 steps of 0.3 s: about 10 t_IG
    start = layer.step(LayerState(0.0, layer.h0, 0.0, 0.0, 0.0, 0.5 * layer.weight), dt)
    assert start.v > 0.0


def test_a_layer_at_rest_without_a_pore_pressure_is_exact():
    """Held with ``p_e = 0``: the state is kept bit for bit (``h``, ``v == 0.0``, ``p_e == 0.0``)."""
    layer = dataclasses.replace(pailha_2008_layer(0.60, compressibility=5e-5), slope_deg=24.0)
    s = LayerState(0.0, layer.h0, 0.0, 0.0, 0.0, 0.0)
    for _ in range(20):
        new = layer.step(s, 0.3)
        assert new.h == layer.h0 and new.v == 0.0 and new.u == 0.0 and new.p_e == 0.0
        s = new


@pytest.mark.parametrize("alpha", [5e-8, 5e-6, 5e-5])
def test_signs_of_the_pore_pressure_and_the_discrete_energy_identity(alpha):
    """Loose p_e > 0, dense p_e < 0, and the discrete energy identity of
    ``E + alpha h p_e^2 / 6`` (:meth:`UniformLayer.energy`) to round-off,
    ``E' - E = -dt D' - alpha dt h' Phi' (p_e'^2 - p_e^2) / 6 - (numerical terms)
    + (P / 2 + alpha p_e^2 / 6) alpha h' (p_e' - p_e)``: the last term is the work of the
    elastic part of the volume change, ``h' - h - dt h' Phi' = alpha h' (p_e' - p_e)``, against
    the grains' weight and the pore energy, of either sign, so no energy inequality follows;
    in these runs the energy decreases at every step (measured)."""
    for phi0, dt, sign in ((0.562, 0.05, 1.0), (0.592, 5.0, -1.0)):
        layer = pailha_2008_layer(phi0, compressibility=alpha)
        mat, s = layer.material, layer.initial_state()
        for _ in range(60):
            new = layer.step(s, dt)
            assert new.p_e * sign > 0.0
            cl = layer.state_closure(new)
            terms = (
                layer.energy(new),
                -layer.energy(s),
                dt * layer.dissipation(new),
                alpha * dt * new.h * cl.dilation * (new.p_e**2 - s.p_e**2) / 6.0,
                0.5 * mat.rho_s * layer.solid * (new.v - s.v) ** 2,
                0.5 * mat.rho_f * (s.h - layer.solid) * (new.u - s.u) ** 2,
                alpha * new.h * (new.p_e - s.p_e) ** 2 / 6.0,
                -(0.5 * layer.weight + alpha * s.p_e**2 / 6.0) * alpha * new.h * (new.p_e - s.p_e),
            )
            assert abs(sum(terms)) <= 64 * EPS * sum(abs(q) for q in terms)
            assert layer.energy(new) <= layer.energy(s)
            s = new


def test_a_bad_compressibility_is_named():
    for bad in (0.0, -1e-6, float("nan"), float("inf")):
        with pytest.raises(InputError, match="compressibility"):
            pailha_2008_layer(0.58, compressibility=bad)


@pytest.mark.parametrize("alpha", [5e-6, 5e-5])
def test_the_mixture_loses_the_volume_its_pore_pressure_drives_out(alpha):
    """The volume balance of George & Iverson (2014): each step changes the thickness by the
    Darcy outflow of its pore pressure, ``h' - h = -dt h' p_e' / B'``, to round-off, and a
    loose layer set moving (0.5 s) loses over the run exactly the sum of its outflows; the
    dilatancy's part ``dt h' Phi'`` differs from it by the skeleton's elastic change
    ``h' alpha (p_e' - p_e)``."""
    layer = pailha_2008_layer(0.562, compressibility=alpha)
    dt = 0.01
    run = layer.run(t_end=0.5, dt=dt)
    outflow = 0.0
    for i in range(1, run.t.size):
        h, p_e = float(run.h[i]), float(run.p_e[i])
        drained = _outflow(layer, h, p_e, dt)
        assert abs(h - float(run.h[i - 1]) + drained) <= 4 * EPS * h
        outflow += drained
        cl = layer.state_closure(LayerState(float(run.t[i]), h, float(run.v[i]), float(run.u[i]), 0.0, p_e))
        elastic = h * alpha * (p_e - float(run.p_e[i - 1]))
        terms = (-drained, -dt * h * cl.dilation, -elastic)
        assert abs(sum(terms)) <= 64 * EPS * (max(abs(q) for q in terms) + h)
    assert float(run.v[-1]) > 0.0 and outflow > 0.0
    assert abs(float(run.h[0] - run.h[-1]) - outflow) <= 64 * EPS * float(run.h[0])
