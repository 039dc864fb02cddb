"""The exact solutions of multilayer.reference.exact against hand values, limits and the
equations they solve."""

import math

import numpy as np
import pytest

from multilayer.engine.initial_state import bagnold_shape
from multilayer.plugins.builtins.jop_mu_i import JopMuI
from multilayer.plugins.builtins.power_law_mu_i import PowerLawMuI
from multilayer.plugins.contract import Material
from multilayer.reference.exact import (
    BagnoldFlow,
    InviscidSimpleShear,
    StokerDamBreak,
    bagnold_depth,
    coulomb_dam_break,
    friction_coefficient,
    inertial_number_for_slope,
    jop_inertial_number,
    power_law_inertial_number,
    ritter,
)

G = 9.81
MATERIAL = Material(density=1500.0, grain_diameter=0.5e-3, particle_density=2500.0)


def test_ritter_by_hand():
    """h0 behind the rarefaction edge -c0 t, 4/9 h0 at the dam, dry beyond 2 c0 t."""
    c0 = math.sqrt(G * 2.0)
    t = 0.5
    x = np.array([-c0 * t - 1e-9, 3.0, 3.0 + c0 * t, 3.0 + 2 * c0 * t + 1e-9])
    h = ritter(x, t, 2.0, x0=3.0)
    np.testing.assert_allclose(h, [2.0, 8.0 / 9.0, 2.0 / 9.0, 0.0])


def test_ritter_conserves_mass_and_is_continuous():
    x = np.linspace(-10.0, 10.0, 400001)
    h = ritter(x, 1.0, 1.0)
    assert np.trapezoid(h, x) == pytest.approx(10.0, rel=1e-6)
    assert np.abs(np.diff(h)).max() < 1e-4


def test_coulomb_dam_break_by_hand():
    """theta = 30, delta = 20 deg: the fan moves with a = g (sin 30 - cos 30 tan 20) = 1.8128 m/s^2,
    and is Ritter's fan with g cos(theta) in that frame."""
    t, h0 = 0.8, 0.1
    a = G * (0.5 - math.cos(math.radians(30)) * math.tan(math.radians(20)))
    assert a == pytest.approx(1.8128, abs=1e-4)
    x = np.linspace(-3.0, 3.0, 1201)
    h = coulomb_dam_break(x, t, h0, 30.0, 20.0)
    moved = ritter(x - a * t * t / 2, t, h0, gravity=G * math.cos(math.radians(30)))
    np.testing.assert_allclose(h, moved, rtol=1e-12, atol=1e-15)
    assert coulomb_dam_break(np.array(a * t * t / 2), t, h0, 30.0, 20.0) == pytest.approx(4 * h0 / 9)


def test_coulomb_dam_break_without_slope_and_friction_is_ritter():
    x = np.linspace(-5.0, 5.0, 101)
    np.testing.assert_array_equal(coulomb_dam_break(x, 0.3, 1.0, 0.0, 0.0, x0=0.5), ritter(x, 0.3, 1.0, 0.5))


def test_coulomb_dam_break_conserves_mass_in_the_accelerated_frame():
    """The mass ahead of x = -10 m + a t^2 / 2 (the reservoir's moving back) stays 10 m^2."""
    a = G * (0.5 - math.cos(math.radians(30)) * math.tan(math.radians(20)))
    x = np.linspace(-10.0, 10.0, 400001) + a / 2
    h = coulomb_dam_break(x, 1.0, 1.0, 30.0, 20.0)
    assert np.trapezoid(h, x) == pytest.approx(10.0, rel=1e-6)


SHEAR = InviscidSimpleShear(
    theta_deg=22.0, mu_s=math.tan(math.radians(26.0)), depth=0.02, b0=0.005, shear=70.0
)


def test_stoker_satisfies_the_shock_conditions_and_the_fan_invariant():
    """Mass and momentum are conserved across the shock (Rankine-Hugoniot:
    ``s [h] = [h u]``, ``s [h u] = [h u^2 + g h^2 / 2]``), the fan's Riemann invariant
    ``u + 2 c`` keeps its value ``2 c_l`` up to the middle state, and the solution is
    continuous at both edges of the fan."""
    dam = StokerDamBreak(1.0, 0.1, x0=5.0)
    hm, um = dam.middle
    s, hr = dam.shock_speed, 0.1
    assert s * (hm - hr) == pytest.approx(hm * um, rel=1e-12)
    assert s * hm * um == pytest.approx(hm * um**2 + G * (hm**2 - hr**2) / 2, rel=1e-12)
    assert um + 2 * math.sqrt(G * hm) == pytest.approx(2 * math.sqrt(G), rel=1e-12)
    t = 0.6
    tail = um - math.sqrt(G * hm)
    edges = 5.0 + t * np.array([-math.sqrt(G), tail])
    for edge, (h_out, u_out) in zip(edges, ((1.0, 0.0), (hm, um)), strict=True):
        h, u = dam.solution(np.array([edge - 1e-9, edge + 1e-9]), t)
        assert h == pytest.approx([h_out, h_out], rel=1e-7) and u == pytest.approx([u_out, u_out], abs=1e-7)


def test_stoker_tends_to_ritter_on_a_drying_bed():
    """As the depth ahead vanishes the shock weakens into Ritter's dry front: the middle
    state thins and speeds towards ``2 c_l``, and h approaches Ritter's in L1."""
    x = np.linspace(0.0, 10.0, 2001)
    errors = []
    for hr in (1e-2, 1e-4, 1e-6):
        h, _ = StokerDamBreak(1.0, hr, x0=5.0).solution(x, 0.6)
        errors.append(np.abs(h - ritter(x, 0.6, 1.0, 5.0)).sum() * (x[1] - x[0]))
    assert errors[0] > errors[1] > errors[2] and errors[2] < 2e-3, errors


def test_stoker_refuses_a_dry_or_reversed_dam():
    with pytest.raises(ValueError, match="0 < h_right < h_left"):
        StokerDamBreak(1.0, 0.0)
    with pytest.raises(ValueError, match="0 < h_right < h_left"):
        StokerDamBreak(0.1, 1.0)


def test_inviscid_simple_shear_by_hand():
    """S = 9.81 cos 22 (tan 26 - tan 22) = 0.76137 m/s^2; stop at 70 x 0.015 / S = 1.379 s."""
    assert SHEAR.deceleration == pytest.approx(0.76137, abs=1e-5)
    assert SHEAR.stop_time == pytest.approx(1.3791, abs=1e-4)
    assert SHEAR.velocity(np.array([0.0, 0.005, 0.02]), 0.0).tolist() == [0.0, 0.0, pytest.approx(1.05)]
    assert SHEAR.velocity(np.array(0.02), SHEAR.stop_time) == pytest.approx(0.0, abs=1e-15)


def test_inviscid_simple_shear_decelerates_uniformly_above_the_interface():
    """dU/dt = -S where the material flows, U = 0 below b(t), and U0(b(t)) = S t."""
    z = np.linspace(0.0, SHEAR.depth, 2001)
    for t in (0.2, 0.7, 1.2):
        b = SHEAR.interface(t)
        rate = (SHEAR.velocity(z, t + 1e-6) - SHEAR.velocity(z, t)) / 1e-6
        flowing = z > b + 1e-4
        np.testing.assert_allclose(rate[flowing], -SHEAR.deceleration, rtol=1e-6)
        assert np.all(SHEAR.velocity(z[z <= b], t) == 0.0)
        assert SHEAR.velocity(np.array(b), 0.0) == pytest.approx(SHEAR.deceleration * t)
    assert SHEAR.interface(2 * SHEAR.stop_time) == SHEAR.depth


def test_jop_inverse_by_hand_and_against_the_plugin():
    """I_theta = I_0 (tan - mu_s) / (mu_2 - tan), and mu(I_theta) = tan(theta) for the built-in law."""
    mu_s, mu_2, i_0 = math.tan(math.radians(20.9)), math.tan(math.radians(32.76)), 0.279
    tan = math.tan(math.radians(25.0))
    closed = jop_inertial_number(25.0, mu_s, mu_2, i_0)
    assert closed == pytest.approx(i_0 * (tan - mu_s) / (mu_2 - tan), rel=1e-15)
    mu = friction_coefficient(JopMuI(mu_s=mu_s, mu_2=mu_2, I_0=i_0), MATERIAL)
    assert mu(closed) == pytest.approx(tan, rel=1e-12)
    assert inertial_number_for_slope(mu, 25.0) == pytest.approx(closed, rel=1e-9)
    for theta in (15.0, 35.0):
        with pytest.raises(ValueError, match="no steady flow"):
            jop_inertial_number(theta, mu_s, mu_2, i_0)
    with pytest.raises(ValueError, match="no steady flow"):
        inertial_number_for_slope(mu, 15.0)


def test_power_law_inverse_by_hand_and_against_the_plugin():
    """I_theta = ((tan - mu_s) / m)^(1/alpha): 0.25^(1/0.5) = 0.0625 for tan - mu_s = 0.1, m = 0.4."""
    tan = math.tan(math.radians(20.0))
    assert power_law_inertial_number(20.0, tan - 0.1, 0.4, 0.5) == pytest.approx(0.0625, rel=1e-12)
    law = PowerLawMuI(mu_s=0.2, m=0.56, alpha=0.34)
    closed = power_law_inertial_number(16.0, 0.2, 0.56, 0.34)
    mu = friction_coefficient(law, MATERIAL)
    assert mu(closed) == pytest.approx(math.tan(math.radians(16.0)), rel=1e-12)
    assert inertial_number_for_slope(mu, 16.0) == pytest.approx(closed, rel=1e-9)
    with pytest.raises(ValueError, match="no steady flow"):
        power_law_inertial_number(10.0, 0.2, 0.56, 0.34)


def test_bagnold_profile_satisfies_mu_of_i_everywhere():
    """du/dz from the profile gives I = I_theta at every depth, zero shear at the surface."""
    depth, inertial, d, theta, ratio = 0.02, 0.2, 0.7e-3, 24.0, 0.62
    z = np.linspace(0.0, depth, 20001)
    flow = BagnoldFlow(depth, inertial, d, theta, density_ratio=ratio)
    u = flow.velocity(z)
    rate = np.gradient(u, z)
    pressure_over_rho_p = ratio * 9.81 * np.cos(np.radians(theta)) * (depth - z)
    local_i = d * rate[:-100] / np.sqrt(pressure_over_rho_p[:-100])
    np.testing.assert_allclose(local_i, inertial, rtol=1e-4)
    assert u[0] == 0.0 and rate[-1] == pytest.approx(0.0, abs=rate.max() * 2e-2)
    mean = np.trapezoid(u, z) / depth
    assert flow.mean_velocity == pytest.approx(mean, rel=1e-6)
    assert mean == pytest.approx(0.6 * u[-1], rel=1e-6)
    assert flow.surface_velocity == u[-1]
    np.testing.assert_allclose(u, u[-1] * bagnold_shape(z / depth), rtol=1e-12, atol=1e-15)


def test_bagnold_shape_and_layer_means():
    """The shape is 0 at the bed, 1 at the surface, 1 - 0.5^1.5 half way; layer means are
    the averages of the profile (one layer: the depth mean)."""
    np.testing.assert_allclose(bagnold_shape(np.array([0.0, 0.5, 1.0, 1.2])), [0, 1 - 0.5**1.5, 1, 1])
    flow = BagnoldFlow(0.01, 0.1, 0.5e-3, 25.0)
    one = flow.layer_means(np.array([0.0, 0.01]))
    assert one[0] == pytest.approx(flow.mean_velocity, rel=1e-12)
    edges = np.linspace(0.0, 0.01, 5)
    fine = [np.mean(flow.velocity(np.linspace(a, b, 100001))) for a, b in zip(edges[:-1], edges[1:])]
    np.testing.assert_allclose(flow.layer_means(edges), fine, rtol=1e-6)


def test_bagnold_layer_means_when_the_summed_layers_overshoot_the_depth():
    """Edges summed from layer fractions may end a round-off above h: the top layer's mean
    is then that of the layer up to h (finite), not nan."""
    flow = BagnoldFlow(0.01, 0.1, 0.5e-3, 25.0)
    edges = np.cumsum(np.r_[0.0, np.full(20, 0.05)]) * 0.01
    assert edges[-1] > 0.01
    exact_edges = np.linspace(0, 0.01, 21)
    np.testing.assert_allclose(flow.layer_means(edges), flow.layer_means(exact_edges), rtol=1e-9)


def test_simple_shear_layer_means_are_the_averages_of_the_profile():
    """Over layers below, across and above the kink at b(t), and at once over several columns."""
    t = 0.3
    edges = np.linspace(0.0, SHEAR.depth, 9)
    z = [np.linspace(a, b, 200001) for a, b in zip(edges[:-1], edges[1:])]
    fine = [np.trapezoid(SHEAR.velocity(zz, t), zz) / (zz[-1] - zz[0]) for zz in z]
    np.testing.assert_allclose(SHEAR.layer_means(edges, t), fine, rtol=1e-9, atol=1e-12)
    assert SHEAR.layer_means(edges, t)[0] == 0.0  # static below b(t)
    columns = np.stack([edges, edges], axis=1)
    np.testing.assert_array_equal(
        SHEAR.layer_means(columns, t), np.stack([SHEAR.layer_means(edges, t)] * 2, 1)
    )
    assert np.all(SHEAR.layer_means(edges, 1.01 * SHEAR.stop_time) == 0.0)


def test_bagnold_depth_carries_the_flux_and_by_hand():
    """h_Bag of eq. 4.3 (Tsang et al. 2019) is the depth whose Bagnold flow carries q; for the
    shipped chute (q = 0.05 m x 2.75 m/s, power law m = 0.56, alpha = 0.34, 16 deg, d = 1 mm)
    it is 5.775 cm by hand."""
    i_theta = power_law_inertial_number(16.0, 0.0, 0.56, 0.34)
    depth = bagnold_depth(0.1375, i_theta, 1e-3, 16.0, gravity=9.81)
    flow = BagnoldFlow(depth, i_theta, 1e-3, 16.0, 9.81)
    assert flow.mean_velocity * depth == pytest.approx(0.1375, rel=1e-12)
    i_by_hand = (math.tan(math.radians(16)) / 0.56) ** (1 / 0.34)
    by_hand = (5 * 1e-3 * 0.1375 / (2 * i_by_hand * math.sqrt(9.81 * math.cos(math.radians(16))))) ** 0.4
    assert depth == pytest.approx(by_hand, rel=1e-12) and depth == pytest.approx(0.05775, abs=1e-5)
