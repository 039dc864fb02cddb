"""The uniform immersed layer (multilayer.engine.mixture): the closure, exact rest and steady
states, conservation, the discrete energy identity, the dry limit, the loose/dense behaviour
and first-order convergence to a tight-tolerance ODE solution (Radau IIA, rtol 1e-10)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from multilayer.engine.mixture.closure import MixtureMaterial, basal_closure
from multilayer.engine.mixture.uniform_layer import LayerState, UniformLayer, onset_time
from multilayer.errors import InputError, RunError
from multilayer.reference.exact import InviscidSimpleShear
from multilayer.reference.immersed_layer import (
    creeping_pore_pressure,
    flowing_pore_pressure,
    pailha_2008_layer,
    steady_flow,
    time_scales,
)
from multilayer.validation.cases import immersed_layer
from multilayer.validation.mesh_study import MeshStudy

EPS = np.finfo(float).eps


def test_the_effective_pressure_solves_the_implicit_closure():
    """p_s is the root of p_s = P - p_e with p_e = -B Phi and Phi depending on p_s (through
    phi_eq), for dense, loose and liquefied (a < 0) states; p_e < 0 when dilating, > 0 when
    contracting."""
    layer = pailha_2008_layer(0.58)
    mat, solid, weight = layer.material, layer.solid, layer.weight
    for phi, speed in ((0.592, 1e-5), (0.562, 1e-4), (0.50, 1e-2), (0.60, 1e-3)):
        h = solid / phi
        cl = basal_closure(mat, solid, weight, h, speed)
        B = 0.5 * cl.beta * h * h / (1.0 - phi) ** 2
        assert cl.p_s > 0.0
        assert cl.p_e == pytest.approx(-B * cl.dilation, rel=1e-12, abs=1e-12 * weight)
        phi_eq = mat.phi_c - mat.K2 * mat.eta_f * cl.gamma / cl.p_s
        assert cl.tan_psi == pytest.approx(mat.K * (phi - phi_eq), rel=1e-13)
        assert math.copysign(1.0, cl.p_e) == -math.copysign(1.0, phi - phi_eq)
    liquefied = basal_closure(mat, solid, weight, solid / 0.50, 1e-4)  # a < 0: the viscous root
    assert liquefied.p_e > 0.9 * weight  # the pore fluid carries 90 % of the grains' weight


def test_a_layer_below_its_static_friction_stays_exactly_at_rest():
    """tan(theta) <= tan(delta) + K (phi - phi_c): v == 0.0, h and u unchanged bit for bit."""
    layer = dataclasses.replace(pailha_2008_layer(0.60), slope_deg=24.0)
    assert layer.held_at_rest()
    run = layer.run(1000.0, 7.0)
    assert np.all(run.v == 0.0) and np.all(run.u == 0.0) and np.all(run.h == layer.h0)
    assert np.all(run.p_e == 0.0)
    moving = dataclasses.replace(layer, slope_deg=27.0)
    assert not moving.held_at_rest() and moving.step(moving.initial_state(), 1.0).v > 0.0


@pytest.mark.parametrize("k_b", [0.0, 200.0])
def test_the_steady_flow_is_kept(k_b):
    """From the steady uniform flow, steps of 10 s (2000 t_crit) stay on it to round-off."""
    layer = pailha_2008_layer(0.575, k_b=k_b)
    steady = steady_flow(layer)
    assert steady is not None
    run = layer.run(2000.0, 10.0, state=steady)
    assert np.max(np.abs(run.v / steady.v - 1.0)) <= 64 * EPS
    assert np.max(np.abs(run.u / steady.u - 1.0)) <= 64 * EPS
    assert np.max(np.abs(run.h / steady.h - 1.0)) <= 64 * EPS
    assert np.max(np.abs(run.p_e)) <= 64 * EPS * layer.weight


def test_solid_and_fluid_volumes_are_conserved():
    """phi h = M and (h - M) + h_f = const: the solid volume is a constant of the state and
    the fluid the mixture gains is the fluid the layer above loses."""
    layer = pailha_2008_layer(0.592)
    run = layer.run(400.0, 5.0)
    assert np.max(np.abs(run.phi * run.h / layer.solid - 1.0)) <= 2 * EPS
    assert run.h[-1] > 1.01 * layer.h0  # the dense layer has dilated by more than 1 %


@pytest.mark.parametrize(("phi0", "k_b", "dt"), [(0.562, 0.0, 0.5), (0.592, 0.0, 5.0), (0.592, 50.0, 5.0)])
def test_the_discrete_energy_identity(phi0, k_b, dt):
    """E^{n+1} - E^n = -dt D^{n+1} - rho_s M (dv)^2/2 - m_f^n (du)^2/2 to round-off, and D >= 0."""
    layer = pailha_2008_layer(phi0, k_b=k_b)
    mat, s = layer.material, layer.initial_state()
    for _ in range(60):
        new = layer.step(s, dt)
        terms = (
            layer.energy(new),
            -layer.energy(s),
            dt * layer.dissipation(new),
            0.5 * mat.rho_s * layer.solid * (new.v - s.v) ** 2,
            0.5 * mat.rho_f * (s.h - layer.solid) * (new.u - s.u) ** 2,
        )
        assert abs(sum(terms)) <= 64 * EPS * sum(abs(q) for q in terms)
        assert layer.dissipation(new) >= 0.0
        s = new


def test_without_fluid_and_dilatancy_the_layer_is_the_dry_coulomb_block():
    """rho_f = eta_f = K = 0: the dry model's basal Coulomb friction, i.e. the inviscid
    deceleration U(t) = max(U0 - S t, 0) of Bouchut, Ionescu & Mangeney (2016, Prop. 2.2),
    stopping exactly; on a steeper slope the constant acceleration g (sin - tan(delta) cos)."""
    dry = MixtureMaterial(
        rho_s=2500.0, d=1e-3, rho_f=0.0, eta_f=0.0, delta_deg=25.0, phi_c=0.6, K=0.0, K1=0.0, K2=0.0
    )
    layer = UniformLayer(dry, slope_deg=20.0, h0=0.01, phi0=0.6)
    v0 = 0.5
    exact = InviscidSimpleShear(theta_deg=20.0, mu_s=dry.tan_delta, depth=0.01, b0=0.0, shear=v0 / 0.01)
    run = layer.run(0.8, 1e-3, state=LayerState(0.0, 0.01, v0, 0.0))
    assert np.max(np.abs(run.v - exact.velocity(np.array([0.01]), run.t))) <= 1e-12
    stopped = run.t[run.v == 0.0]
    assert stopped[0] == pytest.approx(exact.stop_time, abs=1e-3) and np.all(
        run.v[run.t >= stopped[0]] == 0.0
    )
    steep = dataclasses.replace(layer, slope_deg=30.0)
    run = steep.run(0.2, 1e-2)
    th, mu = math.radians(30.0), dry.tan_delta
    assert np.max(np.abs(run.v - 9.81 * (math.sin(th) - mu * math.cos(th)) * run.t)) <= 1e-13


def test_loose_layers_start_at_once_with_positive_pore_pressure_dense_ones_late_with_negative():
    """Pailha et al. (2008) viscous fluid: phi0 = 0.562 moves from the first seconds with
    p_e > 0; phi0 = 0.592 creeps, held by p_e < 0, and reaches 0.1 mm/s only after 200 s."""
    loose, dense = pailha_2008_layer(0.562).run(500.0, 2.0), pailha_2008_layer(0.592).run(500.0, 2.0)
    assert loose.p_e[1] > 0.0 and dense.p_e[1] < 0.0
    assert loose.v[5] > 100.0 * dense.v[5]  # at 10 s
    assert onset_time(loose.t, loose.v, 1e-4) < 1.0 < 200.0 < onset_time(dense.t, dense.v, 1e-4) < 500.0
    assert dense.v[-1] > 1e-4  # ... and then flows


@pytest.mark.parametrize(
    ("phi0", "t_end", "limit", "tolerance"),
    [
        (0.562, 20.0, flowing_pore_pressure, 0.03),
        (0.571, 20.0, flowing_pore_pressure, 0.04),
        (0.592, 100.0, creeping_pore_pressure, 0.04),
    ],
)
def test_the_pore_pressure_magnitudes_are_quasi_static_balances(phi0, t_end, limit, tolerance):
    """Pailha et al. (2008) viscous fluid: the Darcy drag is stiff, so from 1 s on a loose
    layer flows with the pore pressure that keeps it at its critical state and a dense one
    creeps with the suction that holds it at its static threshold, each at the present
    packing (measured: within 1.9 %, 3.1 % and 3.6 %).  The distance to the limit falls at
    least at first order in the inverse drag (Carman-Kozeny constant 75, 150, 300: ratios
    2.0 and 2.1, 1.9 and 1.9, 3.1 and 2.3), and a flowing layer's pressure does not depend on
    the dilatancy constant (K halved: 0.8 % and 1.3 % at 10 s)."""
    layer = pailha_2008_layer(phi0)

    def distance(**change: float) -> tuple[float, float]:
        other = dataclasses.replace(layer, material=dataclasses.replace(layer.material, **change))
        run = other.run(t_end, 0.5)
        later = run.t >= 1.0
        expected = np.array([limit(other, phi) for phi in run.phi[later]])
        return float(np.abs(run.p_e[later] / expected - 1.0).max()), float(np.interp(10.0, run.t, run.p_e))

    (soft, _), (base, at_10), (stiff, _) = (distance(kozeny=k) for k in (75.0, 150.0, 300.0))
    assert base <= tolerance
    assert soft / base >= 1.8 and base / stiff >= 1.8
    if limit is flowing_pore_pressure:
        assert distance(K=layer.material.K / 2.0)[1] == pytest.approx(at_10, rel=0.02)


@pytest.mark.parametrize("phi0", list(immersed_layer.ODE_CASES))
def test_backward_euler_converges_at_order_one_to_the_tight_ode_solution(phi0):
    """Errors in v and h against Radau IIA at rtol 1e-10 over 40, 80 and 160 steps, by the
    function that writes them in docs/validation.md (section immersed_layer)."""
    errors, rates = immersed_layer.ode_study(phi0)
    assert immersed_layer.ode_met(rates), (errors, rates)


def test_time_scales_of_the_laboratory_layers():
    """The water case of Pailha et al. (2008) has the orders of magnitude of the time scales
    quoted for Bouchut et al.'s (2016) model, t_crit ~ 0.2 s, t_visc ~ 4e-2 s, t_rel ~ 5e-5 s
    (computed: 0.17 s, 0.035 s, 5.4e-5 s); the drag relaxes 1e5 times faster than the flow
    approaches its critical state in the viscous fluid."""
    water = time_scales(pailha_2008_layer(0.58, "water"))
    for name, quoted in (("t_crit", 0.2), ("t_visc", 4e-2), ("t_rel", 5e-5)):
        assert round(math.log10(water[name])) == round(math.log10(quoted)), (name, water[name])
    viscous = time_scales(pailha_2008_layer(0.58, "viscous"))
    assert viscous["t_crit"] / viscous["t_rel"] > 1e5


def test_bad_parameters_are_named():
    with pytest.raises(InputError, match="rho_f"):
        MixtureMaterial(
            rho_s=2500.0, d=1e-4, rho_f=3000.0, eta_f=1e-3, delta_deg=20.0, phi_c=0.58, K=1.0, K1=1.0, K2=1.0
        )
    with pytest.raises(InputError, match="eta_f"):
        MixtureMaterial(
            rho_s=2500.0,
            d=1e-4,
            rho_f=1000.0,
            eta_f=math.nan,
            delta_deg=20.0,
            phi_c=0.58,
            K=1.0,
            K1=1.0,
            K2=1.0,
        )
    with pytest.raises(InputError, match="phi0"):
        pailha_2008_layer(1.2)
    with pytest.raises(RunError, match="dt"):
        pailha_2008_layer(0.58).step(LayerState(0.0, 4.9e-3, 0.0, 0.0), math.nan)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("phi0", "t_end", "steps"), [(0.592, 20.0, (4000, 8000, 16000)), (0.562, 0.2, (3200, 6400, 12800))]
)
def test_the_water_case_converges_at_order_one(phi0, t_end, steps):
    """The water-like fluid of Pailha et al. (2008), t_rel = rho_s / beta = 5.4e-5 s.  The
    dense layer creeps: steps of 25 to 100 t_rel converge at order one to the Radau IIA
    solution.  The loose layer accelerates from rest within t_visc = 0.035 s, while the
    drag drags the pore fluid along within t_rel: with steps above t_rel the backward-Euler
    step leaves an error of about 1e-5 of the speed from that initial layer (docs/mixture.md),
    and the order one shows once the steps resolve it (1.2 to 0.3 t_rel here)."""
    errors = immersed_layer.step_errors(pailha_2008_layer(phi0, "water"), t_end, steps, fields=("v",))
    rates = MeshStudy(steps, tuple(errors)).orders()
    assert immersed_layer.ode_met(rates), (errors, rates)


@pytest.mark.parametrize(("phi", "h"), [(0.552, 0.016), (0.56, 0.014), (0.55, 0.001), (0.575, 0.016)])
def test_a_loose_packing_weakens_with_the_shear_rate_at_the_analytic_rate(phi, h):
    """Near rest the closure's root is ``p_s = P - B K (phi_c - phi) gamma + O(gamma^2)``, so
    ``d tau / d gamma (0+) = (K1 + K K2) eta_f - (tan(delta) + K (phi - phi_c)) B K (phi_c - phi)``
    (docs/mixture.md, "Why the loose deposit does not stay at rest"): negative (the stress
    falls with the rate) for the loose submarine deposit, 16 mm at 0.552, and nearly zero at
    1 mm, where the viscous part balances the pore pressure."""
    mat = MixtureMaterial(
        rho_s=2500.0,
        d=225e-6,
        rho_f=1010.0,
        eta_f=0.0121,
        delta_deg=22.5,
        phi_c=0.582,
        K=4.09,
        K1=90.5,
        K2=25.0,
    )
    weight = phi * (mat.rho_s - mat.rho_f) * 9.81 * h
    B = 0.5 * mat.drag(phi) * h * h / (1.0 - phi) ** 2
    viscous = (mat.K1 + mat.K * mat.K2) * mat.eta_f
    exact = viscous - mat.static_friction(phi) * B * mat.K * (mat.phi_c - phi)
    speed = 1e-10  # m/s: gamma = 3 speed / h, the O(gamma^2) term below 1e-6 of the slope
    rest, moving = (basal_closure(mat, phi * h, weight, h, v).tau_b for v in (0.0, speed))
    slope = (moving - rest) / (3.0 * speed / h)
    assert slope == pytest.approx(exact, rel=1e-5, abs=1e-3)
    if h > 0.01:  # the pore pressure's part outweighs the viscous one 94 to 239 times
        assert exact < -50.0 * viscous
    else:
        assert abs(exact) < viscous


@pytest.mark.parametrize("phi0", [0.562, 0.592])
def test_the_volume_the_step_loses_is_the_fluid_its_pore_pressure_drives_out(phi0):
    """With the closure each backward-Euler step changes the mixture thickness by exactly the
    Darcy outflow of its pore pressure, ``h' - h = -dt h' p_e' / B'`` (``p_e = -B Phi``): the
    layer compacts or dilates only as fast as its pore fluid flows."""
    layer = pailha_2008_layer(phi0)
    dt = 0.5
    run = layer.run(t_end=20.0, dt=dt)
    for i in range(1, run.t.size):
        h, phi = float(run.h[i]), float(run.phi[i])
        B = 0.5 * layer.material.drag(phi) * h * h / (1.0 - phi) ** 2
        outflow = -dt * h * float(run.p_e[i]) / B
        change = h - float(run.h[i - 1])
        assert change == pytest.approx(outflow, rel=1e-9, abs=64 * EPS * h)
