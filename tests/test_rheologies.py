"""Built-in rheologies against hand-computed values (docs/model.md, "Rheologies").

Common test point: rho = 1500 kg/m^3, d = 1 mm, rho_p = 2500 kg/m^3, p = 1000 Pa,
|gamma| = 10 1/s, so I = d |gamma| / sqrt(p / rho_p) = 0.01 / sqrt(0.4) = 0.0158113883.
"""

from __future__ import annotations

import numpy as np
import pytest

from multilayer import Material
from multilayer.plugins import host as plugins
from multilayer.plugins.builtins import DruckerPrager, JopMuI, PowerLawMuI, WallFriction

MATERIAL = Material(density=1500.0, grain_diameter=1e-3, particle_density=2500.0)
P, GAMMA, I = 1000.0, 10.0, 0.0158113883008419


def stress_ratio(law, shear_rate, pressure):
    """mu = tau / p with tau = kappa + eta |gamma| (the effective friction coefficient)."""
    tau = law.yield_stress(pressure, MATERIAL) + law.viscosity(shear_rate, pressure, MATERIAL) * shear_rate
    return tau / pressure


def test_builtins_are_registered_through_the_entry_point():
    catalogue = plugins.catalogue()
    expected = {
        "drucker_prager": "bulk",
        "jop_mu_i": "bulk",
        "pouliquen_forterre": "bulk",
        "power_law_mu_i": "bulk",
        "wall_friction": "walls",
    }
    for name, applies_to in expected.items():
        item = catalogue.rheologies[name]
        assert item.cls.applies_to == applies_to
        assert "entry point builtins = multilayer.plugins.builtins" in item.source


def test_drucker_prager():
    law = DruckerPrager(mu_s=0.5, nu=0.01)
    np.testing.assert_array_equal(
        law.yield_stress(np.array([-10.0, 0.0, 200.0]), MATERIAL), [0.0, 0.0, 100.0]
    )
    # eta = rho nu = 1500 * 0.01 = 15 Pa s whatever the shear rate and pressure
    eta = law.viscosity(np.array([[0.0, 1e-9, 30.0]]), np.array([[0.0, -5.0, 1e4]]), MATERIAL)
    np.testing.assert_array_equal(eta, np.full((1, 3), 15.0))


def test_jop_mu_i_hand_computed():
    law = JopMuI(mu_s=0.38, mu_2=0.64, I_0=0.279)
    assert law.yield_stress(P, MATERIAL) == pytest.approx(380.0)
    # eta = (mu_2 - mu_s) p I / ((I_0 + I) |gamma|) = 0.26 * 1000 * I / (0.294811 * 10)
    assert law.viscosity(GAMMA, P, MATERIAL) == pytest.approx(1.39443764, rel=1e-8)
    assert law.viscosity(-GAMMA, P, MATERIAL) == pytest.approx(1.39443764, rel=1e-8)


def test_jop_mu_i_limits():
    law = JopMuI(mu_s=0.38, mu_2=0.64, I_0=0.279)
    # gamma -> 0: eta -> (mu_2 - mu_s) d sqrt(rho_p p) / I_0 = 0.26e-3 * 1581.1388 / 0.279
    eta0 = law.viscosity(np.array([0.0, 1e-12]), P, MATERIAL)
    np.testing.assert_allclose(eta0, 1.47346271, rtol=1e-8)
    # p -> 0 (and p < 0, clamped): no yield stress, no viscosity, no nan
    for gamma in (0.0, 1e-12, 10.0):
        eta = law.viscosity(gamma, np.array([-1.0, 0.0, 1e-300]), MATERIAL)
        assert np.all(np.isfinite(eta)) and np.max(eta) < 1e-150
    np.testing.assert_array_equal(law.yield_stress(np.array([-1.0, 0.0]), MATERIAL), [0.0, 0.0])
    # mu(I): mu_s at I -> 0, (mu_s + mu_2)/2 at I = I_0, mu_2 at I -> infinity
    gamma_at_I0 = 0.279 * np.sqrt(P / 2500.0) / 1e-3
    mu = stress_ratio(law, np.array([1e-12, gamma_at_I0, 1e12]), P)
    np.testing.assert_allclose(mu, [0.38, 0.51, 0.64], rtol=1e-9)


def test_jop_mu_i_high_i_term():
    """mu_inf adds mu_inf I^2 / (I_0 + I) to mu(I) (Barker & Gray 2017): mu = mu_s at rest,
    mu_s + 0.13 + 0.05 I_0 / 2 at I = I_0, growing like mu_inf I; mu_inf = 0 is Jop's law
    bit for bit, with its compiled form."""
    jop, zero = JopMuI(mu_s=0.38, mu_2=0.64, I_0=0.279), JopMuI(mu_s=0.38, mu_2=0.64, I_0=0.279, mu_inf=0.0)
    law = JopMuI(mu_s=0.38, mu_2=0.64, I_0=0.279, mu_inf=0.05)
    gamma = np.array([0.0, 1e-12, 3.0, 30.0, 3e5])
    np.testing.assert_array_equal(zero.viscosity(gamma, P, MATERIAL), jop.viscosity(gamma, P, MATERIAL))
    assert zero.viscosity_kernel(MATERIAL) == jop.viscosity_kernel(MATERIAL)
    inertial = gamma[1:] * 1e-3 / np.sqrt(P / 2500.0)
    expected = 0.38 + (0.26 * inertial + 0.05 * inertial**2) / (0.279 + inertial)
    np.testing.assert_allclose(stress_ratio(law, gamma[1:], P), expected, rtol=1e-12)
    assert law.viscosity_kernel(MATERIAL)[0] == "inertial_quadratic"


def test_power_law_mu_i_hand_computed():
    law = PowerLawMuI(mu_s=0.0, m=0.56, alpha=0.34)
    # eta |gamma| = m p I^alpha = 0.56 * 1000 * I**0.34 = 136.72 Pa
    assert law.viscosity(GAMMA, P, MATERIAL) == pytest.approx(13.6721819, rel=1e-8)
    # alpha = 1: eta = m d sqrt(rho_p p), independent of the shear rate
    linear = PowerLawMuI(mu_s=0.2, m=0.56, alpha=1.0)
    np.testing.assert_allclose(
        linear.viscosity(np.array([0.0, 1.0, 100.0]), P, MATERIAL), 0.885437745, rtol=1e-8
    )
    np.testing.assert_allclose(stress_ratio(linear, GAMMA, P), 0.2 + 0.56 * I, rtol=1e-12)


def test_power_law_mu_i_limits():
    law = PowerLawMuI(mu_s=0.3, m=0.56, alpha=0.34, shear_rate_floor=1e-6)
    # alpha < 1: eta ~ |gamma|^(alpha - 1) is capped at its value at the floor, stress -> 0
    eta = law.viscosity(np.array([0.0, 1e-9, 1e-6]), P, MATERIAL)
    assert np.all(np.isfinite(eta)) and eta[0] == eta[1] == eta[2]
    assert eta[2] == pytest.approx(0.56 * 1000 * (1e-6 * 1e-3 / np.sqrt(0.4)) ** 0.34 / 1e-6)
    assert stress_ratio(law, 1e-12, P) == pytest.approx(0.3, abs=1e-6)
    # p -> 0: eta ~ p^(1 - alpha/2) -> 0
    eta_p = law.viscosity(GAMMA, np.array([-3.0, 0.0, 1e-12]), MATERIAL)
    assert np.all(np.isfinite(eta_p)) and eta_p[0] == eta_p[1] == 0.0 and eta_p[2] < 1e-8


def test_wall_friction():
    law = WallFriction(mu_w=0.185)
    np.testing.assert_allclose(law.yield_stress(np.array([-1.0, 0.0, 1000.0]), MATERIAL), [0.0, 0.0, 185.0])
    np.testing.assert_array_equal(law.viscosity(np.ones((2, 3)), np.ones(3), MATERIAL), np.zeros((2, 3)))


@pytest.mark.parametrize(
    "law",
    [DruckerPrager(0.4, 1e-3), JopMuI(0.38, 0.64, 0.279), PowerLawMuI(0.38, 0.56, 0.34), WallFriction(0.2)],
    ids=lambda law: law.name,
)
def test_vectorised_shapes(law):
    pressure = np.linspace(-10.0, 1e3, 12).reshape(3, 4)
    shear = np.linspace(-5.0, 5.0, 12).reshape(3, 4)
    kappa = law.yield_stress(pressure, MATERIAL)
    eta = law.viscosity(shear, pressure, MATERIAL)
    assert kappa.shape == eta.shape == (3, 4)
    assert np.all(np.isfinite(eta)) and np.all(eta >= 0) and np.all(kappa >= 0)


@pytest.mark.parametrize(
    "make, needle",
    [
        (lambda: DruckerPrager(mu_s=-0.1, nu=0.0), "mu_s"),
        (lambda: DruckerPrager(mu_s=0.4, nu=-1.0), "nu"),
        (lambda: JopMuI(mu_s=0.5, mu_2=0.4, I_0=0.3), "mu_2"),
        (lambda: JopMuI(mu_s=0.3, mu_2=0.6, I_0=0.0), "I_0"),
        (lambda: PowerLawMuI(mu_s=0.3, m=0.5, alpha=2.0), "alpha"),
        (lambda: PowerLawMuI(mu_s=0.3, m=0.5, alpha=0.0), "alpha"),
        (lambda: WallFriction(mu_w=-0.2), "mu_w"),
    ],
)
def test_invalid_parameters_raise_value_error(make, needle):
    with pytest.raises(ValueError, match=needle):
        make()


def test_a_viscosity_too_small_for_double_precision_is_refused_naming_nu():
    """Below about 1e-90 m^2/s the vertical step's products underflow to NaN (found by the
    property tests): 0 < nu < 1e-30 is refused with the key named; 0 and 1e-30 are accepted."""
    from engine import scenario

    from multilayer.errors import InputError

    for nu in (0.0, 1e-30):
        scenario(rheology={"name": "drucker_prager", "mu_s": 0.5, "nu": nu})
    with pytest.raises(InputError, match="rheology: drucker_prager: nu must be 0 or at least 1e-30"):
        scenario(rheology={"name": "drucker_prager", "mu_s": 0.5, "nu": 1e-100})
