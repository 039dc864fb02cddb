"""The linear stability of the one-layer mixture about a uniform loose layer sliding on the
falling branch of its basal stress (multilayer/reference/mixture_stability.py,
docs/mixture.md "Well-posedness of the closure"): the dispersion relation's limits, its
bound as k -> infinity, the cut-offs of the relaxing and of the laterally drained pore
pressure, and the growth rates the time loop measures on periodic meshes against it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from multilayer.reference.mixture_stability import (
    SHEAR,
    cutoff,
    deposit_state,
    lateral_drainage,
    measured_growth,
    stress_slope,
)


def test_long_waves_grow_at_the_uniform_slide_rate():
    """At k -> 0 the fastest mode is the uniform slide's, ``-(d tau / d u) / (rho_m h)``
    with ``d tau / d u = SHEAR / h d tau / d gamma`` (the other unknowns drift at the
    compaction rate, ~1e-2 1/s)."""
    state = deposit_state()
    slope, viscous = stress_slope(state)
    assert slope < -50.0 * viscous  # velocity weakening, as docs/mixture.md's table says
    expected = -SHEAR * slope / (state.density(state.phi) * state.h**2)
    assert state.growth(1e-3)[0] == pytest.approx(expected, rel=1e-3)


def test_growth_is_bounded_and_positive_at_short_waves():
    """Well posed in Hadamard's sense: the growth rate tends to the short-wave limit of the
    projected source Jacobian, about half the long-wave rate, and stays there over four
    decades of k: bounded, but positive (no cut-off) in the closure."""
    state = deposit_state()
    rates = state.growth(np.geomspace(1e6, 1e10, 5))
    limit = state.short_wave_limit()
    assert limit > 0.0
    np.testing.assert_allclose(rates, limit, rtol=1e-4)
    assert limit == pytest.approx(0.5 * state.growth(1e-3)[0], rel=0.01)
    assert math.isinf(cutoff(state))


@pytest.mark.parametrize(
    ("changes", "low", "high"),
    [
        ({"alpha": 5e-6}, 800.0, 1400.0),  # lambda_c ~ 6 mm
        ({"alpha": 5e-5}, 150.0, 300.0),  # ~ 3 cm
        ({"drainage": True}, 1500.0, 3000.0),  # ~ 3 mm
        ({"nu": 1e-4}, 3000.0, 7000.0),
    ],
)
def test_relaxation_drainage_and_viscosity_cut_the_short_waves(changes, low, high):
    """A relaxing pore pressure, a lateral drainage or an in-plane viscosity makes the short
    waves decay: a finite cut-off wavenumber, the long waves still unstable."""
    state = deposit_state(**changes)
    k_c = cutoff(state)
    assert low < k_c < high
    assert state.growth(0.5 * k_c)[0] > 0.0
    assert np.all(state.growth(np.geomspace(2.0 * k_c, 1e10, 9)) < 0.0)


def test_lateral_drainage_factor():
    """``F(kh) = 2 (1 - sech kh) / (kh)^2``: 1 at long waves, ``2 / (kh)^2`` at short ones."""
    assert lateral_drainage(0.0) == 1.0
    assert lateral_drainage(1e-3) == pytest.approx(1.0 - 5e-6 / 12.0, rel=1e-12)
    assert lateral_drainage(100.0) == pytest.approx(2e-4, rel=1e-12)


def test_time_loop_growth_converges_to_the_dispersion_relation():
    """A 2 mm mode (k h = 50, between the long-wave and short-wave rates) of the uniform
    loose layer in the time loop, 8 and 16 cells per wavelength, steps of 5 us: the measured
    rate approaches the dispersion relation's (measured 7.0 % and 1.1 % below it)."""
    coarse, fine = (measured_growth(deposit_state(), 0.002, n, 5e-6, e_folds=3.0) for n in (8, 16))
    errors = [abs(m.rate - m.predicted) / m.predicted for m in (coarse, fine)]
    assert errors[1] < errors[0] / 3.0
    assert errors[1] < 0.02


@pytest.mark.slow
@pytest.mark.parametrize(
    ("alpha", "wavelength", "dt"),
    [
        (0.0, 0.02, 2.5e-6),
        (0.0, 0.002, 2.5e-6),
        (0.0, 0.0005, 2.5e-6),
        (5e-6, 0.05, 2.5e-5),
        (5e-6, 0.02, 2.5e-5),
    ],
)
def test_time_loop_growth_table(alpha, wavelength, dt):
    """8, 16, 32 cells per wavelength (the closure at long, middle and short waves, k h =
    5, 50, 200; the relaxing pore pressure at 5 and 2 cm): within 3 % of the dispersion
    relation at 32 cells, and the error falls with the mesh, but where all three are within
    the backward-Euler error of the local step, ``Re lambda dt / 2`` (0.3 % at 2 cm)
    (measured at 32 cells: +0.27, -0.06, -2.6, +0.12, -0.01 %; benchmarks/mixture_stability.py)."""
    runs = [measured_growth(deposit_state(alpha), wavelength, n, dt) for n in (8, 16, 32)]
    errors = [abs(m.rate - m.predicted) / m.predicted for m in runs]
    step_error = runs[0].predicted * dt / 2.0
    assert errors[2] < 0.03
    assert errors[2] < errors[0] or max(errors) < step_error
