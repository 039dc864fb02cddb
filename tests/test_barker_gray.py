"""The partially regularised mu(I) of Barker & Gray (2017), a research law of the validation
package: its well-posedness window, its two branches, and its steady uniform flow."""

from __future__ import annotations

import math

import numpy as np
import pytest

from multilayer.plugins import host
from multilayer.plugins.contract import Material
from multilayer.reference import exact
from multilayer.validation.barker_gray import (
    I_FLOOR,
    PartialRegularisation,
    ill_posedness,
    jop_friction,
    well_posed_window,
)

BEADS = (0.4770, 0.7265, 0.279)  # tan 25.5 deg, tan 36 deg, I_0 (the inclined-channel beads)
MATERIAL = Material(density=1550.0, grain_diameter=0.7e-3, particle_density=2500.0)


def test_window_is_where_the_criterion_is_negative():
    """C(I) vanishes at both roots, is negative between them, positive outside, and tends
    to mu_s^2 as I -> 0 (Jop's law is ill posed at low and at high I)."""
    lo, hi = well_posed_window(*BEADS)
    assert 0.0 < lo < hi
    scale = np.abs(ill_posedness(np.array([lo, hi]) * 1.01, *BEADS)).max()
    assert np.abs(ill_posedness(np.array([lo, hi]), *BEADS)).max() < 1e-12 * max(scale, 1.0)
    inside = np.geomspace(lo, hi, 50)[1:-1]
    assert np.all(ill_posedness(inside, *BEADS) < 0.0)
    assert np.all(ill_posedness(np.array([lo / 2, lo / 100, hi * 2]), *BEADS) > 0.0)
    assert ill_posedness(np.array([1e-12]), *BEADS)[0] == pytest.approx(BEADS[0] ** 2, rel=1e-9)


def test_branches_meet_and_the_low_branch_is_well_posed():
    """mu is continuous at I_1, increasing, 0 at I = 0; below I_1 its own C(I) (with
    nu = I mu'/mu = mu^2 / (2 alpha) for mu = sqrt(alpha / ln(A/I))) is negative down to
    I -> 0: the regularisation removes the low-I ill-posedness; above I_1 it is Jop's law
    with the high-I term, growing like mu_inf I."""
    law = PartialRegularisation(*BEADS)
    below, above = law.friction(np.array([law.I_1 * (1 - 1e-12), law.I_1]))
    assert below == pytest.approx(above, rel=1e-9)
    grid = np.geomspace(1e-15, 1e3, 2000)
    mu = law.friction(grid)
    assert np.all(np.diff(mu) > 0.0)
    assert law.friction(np.array([0.0]))[0] == 0.0
    low = grid[grid < law.I_1]
    m = law.friction(low)
    nu = m * m / (2.0 * law.alpha)
    # nu from the branch itself: I d(mu)/dI / mu by a centred difference
    step = 1e-6
    numeric = (np.log(law.friction(low * (1 + step))) - np.log(law.friction(low * (1 - step)))) / (2 * step)
    np.testing.assert_allclose(numeric, nu, rtol=1e-6)
    assert np.all(4 * nu**2 - 4 * nu + m**2 * (1 - nu / 2) ** 2 < 0.0)
    high = np.array([1e3])
    assert law.friction(high)[0] == pytest.approx(float(jop_friction(high, *BEADS, law.mu_inf)[0]), rel=1e-12)


def test_stress_is_mu_p_without_yield():
    """tau = eta |gamma| = mu(I) p above the floor; no yield stress; eta finite at rest and 0 at p = 0."""
    law = PartialRegularisation(*BEADS)
    p = np.array([50.0, 200.0, 800.0])
    rate = np.array([0.1, 5.0, 40.0])
    inertial = MATERIAL.grain_diameter * rate / np.sqrt(p / MATERIAL.particle_density)
    tau = law.viscosity(rate, p, MATERIAL) * rate
    np.testing.assert_allclose(tau, law.friction(inertial) * p, rtol=1e-12)
    assert np.all(law.yield_stress(p, MATERIAL) == 0.0)
    at_rest = law.viscosity(np.zeros(3), p, MATERIAL)
    assert np.all(np.isfinite(at_rest)) and np.all(at_rest > 0.0)
    floor_rate = I_FLOOR * np.sqrt(p / MATERIAL.particle_density) / MATERIAL.grain_diameter
    np.testing.assert_allclose(at_rest * floor_rate, law.friction(np.full(3, I_FLOOR)) * p, rtol=1e-12)
    assert law.viscosity(np.array([1.0]), np.array([0.0]), MATERIAL)[0] == 0.0


def test_steady_inertial_number_of_the_low_branch():
    """On a slope with tan(theta) < mu(I_1) the steady uniform flow has
    I_theta = A exp(-alpha / tan^2 theta) (the low branch inverted); above, Jop's closed form
    with the high-I term."""
    law = PartialRegularisation(*BEADS)
    low_theta = 26.0
    tan = math.tan(math.radians(low_theta))
    assert tan < law.friction(np.array([law.I_1]))[0]
    found = exact.inertial_number_for_slope(exact.friction_coefficient(law, MATERIAL), low_theta)
    assert found == pytest.approx(law.A * math.exp(-law.alpha / tan**2), rel=1e-8)
    found = exact.inertial_number_for_slope(exact.friction_coefficient(law, MATERIAL), 30.0)
    assert found == pytest.approx(exact.jop_inertial_number(30.0, *BEADS, mu_inf=law.mu_inf), rel=1e-8)


def test_it_is_not_a_registered_plugin():
    """A law without a yield stress creeps: it is never offered to scenario files."""
    assert PartialRegularisation.name not in host.registry()
