"""The measures of a collapse deposit and its duration (io/observables.py), each checked
against the exact value on a profile or a front history where that value is known."""

import math

import numpy as np
import pytest

from multilayer.io import observables

D = 0.7e-3  # grain diameter (m)


def cell_centres(x0: float, dx: float, n: int) -> np.ndarray:
    return x0 + dx * (np.arange(n) + 0.5)


def test_the_tip_of_a_linear_wedge_is_where_it_is_n_diameters_thick():
    # h = s (x_e - x): the interpolant through the cell centres is the wedge itself, so the
    # point where it is n d thick, x_e - n d / s, is found exactly
    x = cell_centres(0.0, 1e-3, 300)
    s, x_e = 0.05, 0.2513
    wedge = np.maximum(s * (x_e - x), 0.0)
    for n in (1.0, 3.0, 5.0):
        assert observables.tip(x, wedge, D, n) == pytest.approx(x_e - n * D / s, rel=1e-12)
    assert observables.tip(x, wedge, D) == pytest.approx(x_e - observables.TIP_DIAMETERS * D / s, rel=1e-12)
    # on an erodible bed of 3 mm the tip is measured above the bed
    on_bed = observables.tip(x, 0.003 + wedge, D, 3.0, base=0.003)
    assert on_bed == pytest.approx(x_e - 3.0 * D / s, rel=1e-12)
    assert math.isnan(observables.tip(x, np.full_like(x, 1e-3), D, 3.0))  # nothing 2.1 mm thick


def test_the_mass_front_of_a_rectangle_holds_95_percent_of_it():
    x = cell_centres(-0.1, 0.01, 60)  # faces at -0.1, -0.09, ..., 0.5
    h = np.where((x > 0.0) & (x < 0.2), 0.14, 0.0)  # a block on [0, 0.2], edges on faces
    assert observables.mass_front(x, h) == pytest.approx(0.95 * 0.2, abs=1e-15)
    assert observables.mass_front(x, h, 0.5) == pytest.approx(0.1, abs=1e-15)
    # on an erodible bed the material above the bed counts; a scour below it does not
    bed = 0.005
    eroded = np.where((x > 0.3) & (x < 0.4), 0.001, bed)
    assert observables.mass_front(x, eroded + h, base=bed) == pytest.approx(0.19, abs=1e-15)
    assert math.isnan(observables.mass_front(x, np.full_like(x, bed), base=bed))


def test_the_mass_front_of_a_triangle_is_its_exact_quantile():
    # h = H (1 - x/L) on [0, L] holds 1 - (1 - x/L)^2 of its mass upslope of x: 95 % at
    # x_95 = L (1 - sqrt(0.05)).  Cell averages of the exact profile make the cumulative
    # mass exact at the cell edges; the grid puts an edge at x_95.
    H, L = 0.1, 1.0
    x95 = L * (1.0 - math.sqrt(0.05))
    dx = x95 / 7
    edges = dx * np.arange(0, 11)  # the last edge beyond L

    def mass_upto(xe: np.ndarray) -> np.ndarray:
        xe = np.minimum(xe, L)
        return H * (xe - xe**2 / (2 * L))

    h = np.diff(mass_upto(edges)) / dx
    x = 0.5 * (edges[1:] + edges[:-1])
    assert observables.mass_front(x, h) == pytest.approx(x95, rel=1e-13)


def test_stop_time_of_a_uniformly_decelerating_front():
    # x_f = V t - A t^2 / 2 until it stops at t_s = V/A: its finite difference over an
    # interval is its speed at the midpoint, so the time at which the speed is v,
    # (V - v)/A, is recovered exactly when it falls between midpoints before t_s
    V, A = 2.0, 2.5  # m/s, m/s^2: stops at 0.8 s, 0.8 m downslope
    t = np.linspace(0.0, 2.0, 201)
    front = np.where(t < V / A, V * t - 0.5 * A * t**2, V**2 / (2 * A))
    assert observables.front_stop_time(t, front, 0.5) == pytest.approx((V - 0.5) / A, rel=1e-12)
    assert observables.front_stop_time(t, front, 1.0) == pytest.approx(0.4, rel=1e-12)
    assert math.isnan(observables.front_stop_time(t, 0.1 * t, 0.01))  # still moving at the end
    assert observables.front_stop_time(t, np.zeros_like(t), 0.01) == 0.0  # never moved


def test_time_to_95_percent_of_a_front_that_moves_at_constant_speed_then_stops():
    T = 0.73
    t = np.linspace(0.0, 2.0, 41)
    front = 0.05 + 1.2 * np.minimum(t, T)
    assert observables.time_to_fraction(t, front) == pytest.approx(observables.MASS_FRACTION * T, rel=1e-12)
    assert observables.time_to_fraction(t, front, 0.5) == pytest.approx(0.5 * T, rel=1e-12)
