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


def test_a_layer_at_rest_keeps_its_state_while_its_pore_pressure_relaxes():
    """Held: v == 0.0, h and u bit for bit, p_e' = p_e t_IG / (t_IG + dt) at each step."""
    layer = dataclasses.replace(pailha_2008_layer(0.60, compressibility=5e-5), slope_deg=24.0)
    dt, s = 0.3, LayerState(0.0, layer.h0, 0.0, 0.0, 0.0, -4.0)
    t_ig = layer.relaxation_time(layer.h0)
    for _ in range(50):
        new = layer.step(s, dt)
        assert new.v == 0.0 and new.u == 0.0 and new.h == layer.h0
        assert new.p_e == pytest.approx(s.p_e * t_ig / (t_ig + dt), rel=4 * EPS)
        s = new
    start = layer.step(LayerState(0.0, layer.h0, 0.0, 0.0, 0.0, 0.5 * layer.weight), dt)
    assert start.v > 0.0  # a pore pressure carrying half the weight unlocks it


@pytest.mark.parametrize("alpha", [5e-8, 5e-6, 5e-5])
def test_signs_of_the_pore_pressure_and_the_discrete_energy_identity(alpha):
    """Loose p_e > 0, dense p_e < 0, and ``E^{n+1} - E^n = -dt D^{n+1} - (numerical terms)`` with
    the energy of the compressed pores ``alpha h p_e^2 / 6`` (its relaxing part with the old
    ``p_e``: ``alpha dt h' Phi' (p_e'^2 - p_e^2) / 6`` corrects ``D^{n+1}``)."""
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
            )
            assert abs(sum(terms)) <= 64 * EPS * sum(abs(q) for q in terms)
            assert layer.energy(new) <= layer.energy(s)
            s = new


def test_a_bad_compressibility_is_named():
    for bad in (0.0, -1e-6, float("nan"), float("inf")):
        with pytest.raises(InputError, match="compressibility"):
            pailha_2008_layer(0.58, compressibility=bad)


@pytest.mark.parametrize("alpha", [5e-6, 5e-5])
def test_the_step_changes_the_volume_by_the_dilatancy_not_by_the_darcy_outflow_alone(alpha):
    """As built (docs/mixture.md, "The volume the relaxation changes") the step changes the
    thickness by the dilatancy, ``h' - h = dt h' Phi'``, so by the Darcy outflow of its pore
    pressure plus the skeleton's elastic change that George & Iverson (2014) count in their
    dilation rate: ``h' - h = -dt h' p_e' / B' - h' alpha (p_e' - p_e)``; a loose layer that
    starts moving contracts ahead of its drainage (by 0.1 s its packing gains more than
    twice what the outflow allows at ``alpha = 5e-5``)."""
    layer = pailha_2008_layer(0.562, compressibility=alpha)
    dt = 0.01
    run = layer.run(t_end=0.5, dt=dt)
    outflow = 0.0  # m: the Darcy outflow of the first 10 steps (0.1 s)
    for i in range(1, run.t.size):
        h, phi, p_e = float(run.h[i]), float(run.phi[i]), float(run.p_e[i])
        B = 0.5 * layer.material.drag(phi) * h * h / (1.0 - phi) ** 2
        terms = (h - float(run.h[i - 1]), dt * h * p_e / B, h * alpha * (p_e - float(run.p_e[i - 1])))
        assert abs(sum(terms)) <= 64 * EPS * max(abs(q) for q in terms) + 64 * EPS * h
        if i <= 10:
            outflow += terms[1]
    if alpha == 5e-5:
        assert float(run.h[0] - run.h[10]) > 2.0 * outflow
