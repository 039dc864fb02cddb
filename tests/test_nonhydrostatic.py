"""The non-hydrostatic multilayer model (docs/nonhydrostatic.md) against its references:
Airy's linear dispersion, the Rayleigh solitary wave, the hydrostatic limit of thin flows,
exact rest, and the discrete projection's own identities."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import TINY_SCENARIO
from engine import simulation
from test_rest import held
from test_vertical import simple_shear

import multilayer
from multilayer.engine.pressure.non_hydrostatic import banded
from multilayer.engine.pressure.non_hydrostatic import constraint as assembly
from multilayer.engine.pressure.non_hydrostatic import projection as nonhydrostatic
from multilayer.errors import RunError
from multilayer.validation.runs import Run

G = 9.81
FRICTIONLESS = {
    "rheology": {"name": "drucker_prager", "mu_s": 0.0, "nu": 0.0},
    "base": [{"condition": "free_slip"}],
}


def non_hydrostatic(pressure_layers: int | None = None) -> dict:
    """The ``model`` mapping of the non-hydrostatic option (pressure layers: the default)."""
    model: dict = {"pressure": "non_hydrostatic"}
    if pressure_layers is not None:
        model["pressure_layers"] = pressure_layers
    return model


def standing_wave_error(
    kh: float,
    layers: int,
    cells: int = 20,
    pressure: str = "non_hydrostatic",
    pressure_layers: int | None = None,
) -> float:
    """Relative error of the phase speed of the gravest standing wave of a basin of depth
    1 m and length pi / k (walls), amplitude 1 mm, against Airy's c^2 = (g/k) tanh(kh),
    with the pressure on ``pressure_layers`` (default: every layer).  The period is twice
    the time between the two zero crossings of the mode amplitude."""
    k = kh
    length = math.pi / k
    model = {"pressure": pressure}
    if pressure == "non_hydrostatic":
        model = non_hydrostatic(layers if pressure_layers is None else pressure_layers)
    sim = simulation(
        domain={"x_min": 0.0, "x_max": length, "cells": cells, "layers": layers},
        initial=[{"shape": "layer", "thickness": 1.0}],
        model=model,
        **FRICTIONLESS,
    )
    mode = np.cos(k * sim.x)
    sim.h[...] = 1.0 + 1e-3 * mode
    c_airy = math.sqrt(G / k * math.tanh(kh))
    times, amplitude = [0.0], [1e-3]
    while sim.t < 0.8 * 2 * length / c_airy:
        sim.step()
        times.append(sim.t)
        amplitude.append(float(np.sum((sim.h - 1.0) * mode) / np.sum(mode**2)))
    t, a = np.array(times), np.array(amplitude)
    n = np.flatnonzero(a[:-1] * a[1:] < 0)
    crossings = t[n] - a[n] * (t[n + 1] - t[n]) / (a[n + 1] - a[n])
    assert crossings.size == 2
    period = 2 * (crossings[1] - crossings[0])
    return (2 * length / period) / c_airy - 1.0


@pytest.mark.parametrize("velocity_layers", [None, 8])
def test_linear_dispersion_approaches_airy_as_layers_are_added(velocity_layers):
    """kh = 2, 20 cells per half wavelength: the error falls with the pressure layers and is
    below 1 % with 5 layers (a pressure on every layer: +2.3, +1.0, +0.5 %), and with 4
    pressure layers on 8 velocity layers (1, 2, 4: +9.2, +2.7, +0.9 %; the tables for
    kh = 0.1-3 are in docs/nonhydrostatic.md); the hydrostatic model is 44 % too fast."""
    counts = (1, 2, 5) if velocity_layers is None else (1, 2, 4)
    errors = [
        standing_wave_error(2.0, n if velocity_layers is None else velocity_layers, pressure_layers=n)
        for n in counts
    ]
    assert abs(errors[0]) > abs(errors[1]) > abs(errors[2])
    assert abs(errors[2]) < 0.01
    if velocity_layers is None:
        assert standing_wave_error(2.0, 1, pressure="hydrostatic") > 0.4


@pytest.mark.parametrize(("layers", "pressure_layers"), [(2, 2), (8, 1), (8, 4)])
def test_long_waves_keep_the_shallow_water_speed(layers, pressure_layers):
    """kh = 0.1: the speed is sqrt(g h) up to (kh)^2 / 6 = 0.17 % and the scheme's error."""
    assert abs(standing_wave_error(0.1, layers, pressure_layers=pressure_layers)) < 0.003


def solitary(
    pressure: str,
    layers: int = 2,
    cells: int = 200,
    amplitude: float = 0.1,
    t_end: float = 3.0,
    pressure_layers: int | None = None,
):
    """Rayleigh's solitary wave eta = A sech^2(kappa (x - c t)), kappa^2 = 3 A / (4 H^2 (H + A)),
    c^2 = g (H + A), on a periodic 40 m channel of depth H = 1 m, depth-uniform u = c eta / h
    and w = -z d_x u.  Returns the relative errors of the speed and of the amplitude, and
    the largest deviation from the translated profile over the amplitude."""
    kappa = math.sqrt(3 * amplitude / (4 * (1 + amplitude)))
    c = math.sqrt(G * (1 + amplitude))
    sim = simulation(
        domain={"x_min": 0.0, "x_max": 40.0, "cells": cells, "layers": layers},
        initial=[{"shape": "layer", "thickness": 1.0}],
        boundaries={"left": "periodic", "right": "periodic"},
        model=non_hydrostatic(pressure_layers) if pressure == "non_hydrostatic" else {"pressure": pressure},
        **FRICTIONLESS,
    )
    x0 = 10.0
    eta = amplitude / np.cosh(kappa * (sim.x - x0)) ** 2
    sim.h[...] = 1.0 + eta
    sim.u[...] = c * eta / sim.h
    sim.w[...] = -(sim.sigma[:, None] * sim.h) * np.gradient(sim.u[0], sim.dx)
    sim.advance(t_end)
    e = sim.h - 1.0
    i = int(np.argmax(e))
    a, b, d = e[i - 1], e[i], e[i + 1]
    offset = 0.5 * (a - d) / (a - 2 * b + d)  # parabola through the three largest values
    peak_x, peak = sim.x[i] + offset * sim.dx, b - 0.25 * (a - d) * offset
    shape = np.abs(e - amplitude / np.cosh(kappa * (sim.x - peak_x)) ** 2).max() / amplitude
    return (peak_x - x0) / t_end / c - 1.0, peak / amplitude - 1.0, shape


@pytest.mark.slow
@pytest.mark.parametrize(("layers", "pressure_layers"), [(2, None), (8, 2)])
def test_solitary_wave_keeps_its_shape_and_speed(layers, pressure_layers):
    """A/H = 0.1 over 3 s (10 m, about 2.6 wave lengths), dx = H/5: speed within 2.5 %,
    amplitude within 2 %, profile within 5 % of the amplitude (2 layers: 1.9 %, -1.1 % and
    3.6 % here, 1.2 %, -0.2 % and 2.0 % with dx = H/10; 8 velocity layers on 2 pressure
    layers: 2.1 %, -1.1 %, 3.9 %).  The hydrostatic model steepens the wave: 6.5 % too fast
    and 9.4 % off."""
    speed, peak, shape = solitary("non_hydrostatic", layers=layers, pressure_layers=pressure_layers)
    assert abs(speed) < 0.025
    assert abs(peak) < 0.02
    assert shape < 0.05
    hydro_speed, _, hydro_shape = solitary("hydrostatic")
    assert hydro_speed > 2 * speed and hydro_shape > 2 * shape


def thin_dam_break(
    aspect: float, pressure: str, layers: int = 2, pressure_layers: int | None = None
) -> np.ndarray:
    """A frictionless dam break of depth aspect x 10 m released over half of a 10 m basin,
    h / h0 at t = 1.5 / sqrt(g h0) x 10 m (self-similar in the hydrostatic model)."""
    h0 = 10.0 * aspect
    sim = simulation(
        domain={"x_min": 0.0, "x_max": 10.0, "cells": 100, "layers": layers},
        initial=[{"shape": "rectangle", "x_min": 0.0, "x_max": 5.0, "height": h0}],
        model=non_hydrostatic(pressure_layers) if pressure == "non_hydrostatic" else {"pressure": pressure},
        **FRICTIONLESS,
    )
    sim.advance(1.5 / math.sqrt(G * h0))
    return sim.h / h0


@pytest.mark.parametrize(("layers", "pressure_layers"), [(2, None), (8, 2)])
def test_thin_dam_breaks_recover_the_hydrostatic_solution(layers, pressure_layers):
    """The mean |h_nh - h_hydro| / h0 falls by 3.2-3.3 when the aspect ratio halves from 0.02
    to 0.01 (second order would be 4): the non-hydrostatic pressure is O(aspect^2)."""
    differences = [
        np.abs(
            thin_dam_break(a, "non_hydrostatic", layers, pressure_layers)
            - thin_dam_break(a, "hydrostatic", layers)
        ).mean()
        for a in (0.02, 0.01)
    ]
    assert differences[1] < 1e-3
    assert differences[0] / differences[1] > 2.8


@pytest.mark.parametrize("pressure_layers", [None, 40])
def test_uniform_simple_shear_is_unchanged_bit_for_bit(pressure_layers):
    """Prop. 2.2 (and any flow uniform in x) satisfies the constraint: lam = 0 exactly, with
    the pressure on every layer and on the default 4."""
    runs = {
        "hydrostatic": simple_shear(nu=0.0, layers=40, model={"pressure": "hydrostatic"}),
        "non_hydrostatic": simple_shear(nu=0.0, layers=40, model=non_hydrostatic(pressure_layers)),
    }
    for sim in runs.values():
        sim.advance(0.2)
    assert np.array_equal(runs["hydrostatic"].u, runs["non_hydrostatic"].u)
    assert np.all(runs["non_hydrostatic"].q == 0.0)


def heap_below_repose(model: dict) -> multilayer.Simulation:
    """A heap with flanks of slope 0.1 on a 10 degree plane, mu_s = tan 26 deg (4 layers)."""
    return simulation(
        slope_deg=10.0,
        domain={"x_min": -0.5, "x_max": 2.5, "cells": 60, "layers": 4},
        material={"density": 1550.0, "grain_diameter": 0.7e-3},
        rheology={"name": "drucker_prager", "mu_s": math.tan(math.radians(26.0)), "nu": 0.0},
        base=[{"condition": "no_slip"}],
        initial=[{"shape": "profile", "points": [[0.0, 0.0], [1.0, 0.1], [2.0, 0.0]]}],
        model=model,
    )


@pytest.mark.parametrize("pressure_layers", [None, 2])
def test_heap_below_repose_stays_exactly_at_rest(pressure_layers):
    sim = heap_below_repose(non_hydrostatic(pressure_layers))
    max_u, max_dh = held(sim, 300)
    assert max_u == 0.0 and max_dh == 0.0
    assert np.all(sim.w == 0.0) and np.all(sim.q == 0.0)


def random_state(seed: int, layers: int = 4, cells: int = 12):
    rng = np.random.default_rng(seed)
    fractions = rng.uniform(0.5, 1.5, layers)
    fractions /= fractions.sum()
    h = rng.uniform(0.2, 1.0, cells)
    bed = rng.uniform(-0.3, 0.3, cells)
    u = rng.normal(size=(layers, cells))
    u[:, 3] = 0.0  # a column at rest
    u[:2, 7] = 0.0  # a static base under a flowing top
    w = rng.normal(size=(layers, cells))
    return h, u, w, bed, fractions


@pytest.mark.parametrize("pressure_layers", [4, 2])
@pytest.mark.parametrize("periodic", [False, True])
def test_projection_satisfies_the_constraint_and_never_adds_energy(periodic, pressure_layers):
    """On sloping interfaces, uneven layers and partly static columns: the projected face
    velocities satisfy E V = 0 (with fewer pressure layers the reduced P^T E V = 0) on the
    moving cells to round-off, the kinetic energy 1/2 V^T M V does not grow, and
    A = E M^-1 E^T is symmetric."""
    h, u, w, bed, fractions = random_state(1)
    moving = u != 0.0
    nodes = interpolation = None
    if pressure_layers < u.shape[0]:
        nodes = assembly.pressure_nodes(fractions, pressure_layers)
        interpolation = assembly.pressure_interpolation(fractions, nodes)
    cons = assembly.constraint(h, bed, fractions, 0.1, periodic, interpolation)
    V_star, dV, free = nonhydrostatic.correction(cons, moving, u, w, nodes=nodes)
    V = V_star + dV
    rows = np.flatnonzero((moving if nodes is None else moving[nodes]).ravel())
    E = cons.E[rows][:, np.flatnonzero(free)]
    assert np.abs(E @ V[free]).max() < 1e-12 * np.abs(E @ V_star[free]).max()
    energy = lambda v: 0.5 * np.sum(cons.mass[free] * v[free] ** 2)  # noqa: E731
    assert energy(V) <= energy(V_star)
    A = (E @ np.diag(1.0 / cons.mass[free]) @ E.T.toarray()).astype(float)
    assert np.abs(A - A.T).max() < 1e-12 * np.abs(A).max()
    assert np.all(dV[~free] == 0.0)


@pytest.mark.parametrize(
    ("layers", "pressure_layers", "columns"), [(6, 6, 12), (6, 3, 12), (32, 4, 12), (6, 3, 1)]
)
@pytest.mark.parametrize("periodic", [False, True])
def test_normal_equations_added_up_as_stored_equal_the_sparse_product(
    periodic, layers, pressure_layers, columns
):
    """The band of A and r, added up as the constraint is stored (unknown by unknown, or
    summed over the layers of the faces and columns whose layers all move), equal
    E M^-1 E^T and E V* of the stored constraint as a sparse matrix (moving rows and free
    unknowns only) to round-off, on sloping interfaces, uneven layers, partly static
    columns and a dry edge, and in a single column (r the same bits as without the band);
    the band is as narrow as A (its last diagonal not all zero)."""
    h, u, w, bed, fractions = random_state(11, layers=layers)
    if columns == 1:  # no faces: the wbar alone (u and w contiguous, as the engine's)
        h, u, w, bed = h[:1], np.ascontiguousarray(u[:, :1]), np.ascontiguousarray(w[:, :1]), bed[:1]
    else:
        h[-2:], u[:, -2:] = 0.0, 0.0  # dry cells at the edge (beside the first column if periodic)
    nodes, P = assembly.layering(tuple(fractions), pressure_layers)
    cons = assembly.constraint(h, bed, fractions, 0.1, periodic, P)
    moving = u != 0.0
    K, N = cons.mass.size, u.shape[1]
    free, V_star = np.empty(K, np.bool_), np.empty(K)
    row_of, rows = np.empty(nodes.size * N, np.int64), np.empty(nodes.size * N, np.int64)
    n = assembly.unknowns(
        cons.mass, cons.left, cons.right, moving, u, w, 0, nodes, free, V_star, row_of, rows, True
    )
    arrays = (
        np.empty(K + 1, np.int64),
        np.empty(cons.cells.size, np.int64),
        np.empty(cons.cells.size),
        np.empty(K),
    )
    band, r = assembly.normal_equations(*cons.geometry, free, row_of, n, V_star, np.empty(0), arrays)
    E = cons.E[rows[:n]][:, np.flatnonzero(free)].toarray()
    A = E @ np.diag(1.0 / cons.mass[free]) @ E.T
    dense = np.zeros((n, n))
    for d in range(band.shape[1]):
        dense[np.arange(n - d), np.arange(d, n)] = dense[np.arange(d, n), np.arange(n - d)] = band[: n - d, d]
    assert np.abs(dense - A).max() <= 1e-13 * np.abs(A).max()
    assert np.abs(r - E @ V_star[free]).max() <= 1e-13 * np.abs(r).max()
    assert np.any(band[:, -1] != 0.0)
    r_only = np.zeros(n)  # r alone (no band): the same bits
    assembly.entries(*cons.geometry, free, row_of, *arrays, V_star, np.empty((0, 1)), r_only)
    assert np.array_equal(r_only, r)


def test_pressure_interfaces_group_whole_layers_and_interpolate_linearly():
    """Pressure layers: groups of whole layers whose bottom interfaces are the nearest to
    sigma = g / L_p; the interpolation is the identity with a pressure on every layer and
    reproduces exactly a pressure linear in depth and zero at the surface (hydrostatic-like)."""
    uniform = np.full(8, 1 / 8)
    assert assembly.pressure_nodes(uniform, 4).tolist() == [0, 2, 4, 6]
    assert assembly.pressure_nodes(uniform, 3).tolist() == [0, 3, 5]  # sigma 0, 3/8, 5/8
    assert np.array_equal(assembly.pressure_interpolation(uniform, np.arange(8)), np.eye(8))
    fractions = np.array([0.05, 0.05, 0.1, 0.1, 0.2, 0.5])  # thin layers at the bed
    nodes = assembly.pressure_nodes(fractions, 3)
    assert nodes.tolist() == [0, 4, 5]  # sigma 0, 0.3, 0.5 for the targets 0, 1/3, 2/3
    assert assembly.pressure_nodes(fractions, 6).tolist() == list(range(6))
    P = assembly.pressure_interpolation(fractions, nodes)
    sigma = np.concatenate([[0.0], np.cumsum(fractions)[:-1]])
    assert np.allclose(P @ (1.0 - sigma[nodes]), 1.0 - sigma, rtol=0, atol=1e-15)
    assert np.all((P >= 0.0) & (P <= 1.0))


@pytest.mark.parametrize("pressure_layers", [1, 2, 3])
@pytest.mark.parametrize("periodic", [False, True])
def test_reduced_rows_are_the_interpolation_transpose_times_the_layer_rows(periodic, pressure_layers):
    """On sloping interfaces and uneven layers the assembled reduced constraint is P^T E,
    E the constraint of every layer (P from cell a * N + i to g * N + i)."""
    h, _, _, bed, fractions = random_state(9, layers=6)
    nodes = assembly.pressure_nodes(fractions, pressure_layers)
    P = assembly.pressure_interpolation(fractions, nodes)
    reduced = assembly.constraint(h, bed, fractions, 0.1, periodic, P).E.toarray()
    full = assembly.constraint(h, bed, fractions, 0.1, periodic).E.toarray()
    expected = np.kron(P.T, np.eye(h.size)) @ full
    assert np.abs(reduced - expected).max() <= 1e-13 * np.abs(expected).max()


@pytest.mark.slow
@pytest.mark.parametrize("pressure_layers", [None, 2])
def test_static_cells_are_not_touched(pressure_layers):
    h, u, w, bed, fractions = random_state(2)
    u_new, w_new, q = nonhydrostatic.project(
        h, u, w, bed, fractions, dx=0.1, dt=0.01, pressure_layers=pressure_layers
    )
    assert np.all(u_new[u == 0.0] == 0.0) and np.all(w_new[u == 0.0] == 0.0)
    assert np.all(u_new[u != 0.0] != u[u != 0.0])
    assert np.all(np.isfinite(q))


@pytest.mark.parametrize("pressure_layers", [6, 3, 2, 1])
@pytest.mark.parametrize("periodic", [False, True])
def test_fast_path_equals_the_fipy_reference_on_flat_interfaces(periodic, pressure_layers):
    """Uneven layers, every cell moving, uniform h on a flat bed: u, w and q agree to
    round-off with the FiPy formulation of the same elliptic problem, with the pressure on
    every layer and on fewer (the reduced problem P^T A P)."""
    from multilayer.reference import nonhydrostatic_fipy

    rng = np.random.default_rng(3)
    L, N = 6, 9
    fractions = rng.uniform(0.5, 1.5, L)
    fractions /= fractions.sum()
    u, w = rng.normal(size=(L, N)), rng.normal(size=(L, N))
    h = np.full(N, 0.7)
    fast = nonhydrostatic.project(
        h, u, w, np.zeros(N), fractions, dx=0.2, dt=0.01, periodic=periodic, pressure_layers=pressure_layers
    )
    nodes = None if pressure_layers == L else assembly.pressure_nodes(fractions, pressure_layers)
    ref = nonhydrostatic_fipy.project(
        0.7, u, w, fractions, dx=0.2, dt=0.01, periodic=periodic, pressure_nodes=nodes
    )
    for a, b in zip(fast, ref):
        assert np.abs(a - b).max() <= 1e-12 * max(np.abs(b).max(), 1.0)


@pytest.mark.parametrize("pressure_layers", [None, 2])
def test_total_pressure_is_never_negative(pressure_layers):
    """Granular matter takes no tension: with the bound, g cos(theta) (h - z) + q >= 0 in every
    moving cell, where the unbounded projection of the same state has tension.  With fewer
    pressure layers the bound at the pressure interfaces holds on every interface (both
    sides linear in sigma between them)."""
    h, u, w, bed, fractions = random_state(4, layers=4 if pressure_layers is None else 6)
    options = {"pressure_layers": pressure_layers}
    w *= 20.0  # strong vertical motion: the unbounded pressure goes negative
    depth = (1.0 - np.concatenate([[0.0], np.cumsum(fractions)[:-1]]))[:, None] * h
    g_n, dt = 9.81, 0.01
    _, _, q_free = nonhydrostatic.project(h, u, w, bed, fractions, dx=0.1, dt=dt, **options)
    moving = u != 0.0
    assert (g_n * depth + q_free)[moving].min() < 0.0
    _, _, q = nonhydrostatic.project(h, u, w, bed, fractions, dx=0.1, dt=dt, g_n=g_n, **options)
    total = (g_n * depth + q)[moving]
    assert total.min() >= -1e-12 * g_n * h.max()
    assert np.any(np.abs(total) <= 1e-12 * g_n * h.max())  # the bound is active somewhere
    # the active-set guess changes the iterations, not the answer: the answer's own set,
    # the cells in tension without the bound, every moving cell, none
    for previous in (q, q_free, np.full_like(q, -1e9), np.zeros_like(q)):
        guess = nonhydrostatic.tension_free(previous, h, fractions, g_n)
        again = nonhydrostatic.project(
            h, u, w, bed, fractions, dx=0.1, dt=dt, g_n=g_n, tension_free=guess, **options
        )
        assert np.allclose(again[2], q, rtol=0, atol=1e-12 * np.abs(q).max())


@pytest.mark.parametrize("g_n", [None, G])
def test_the_pressure_is_that_of_the_update_whatever_the_step(g_n):
    """From a start ``V0`` that violates the constraint (rows that join, the residual of
    the approximate projection) and ``V* = V0 + dt a``, the velocities are those of the
    projection of ``V*`` (bit for bit), but the pressure is the projection of the update
    (Almgren, Bell & Crutchfield 2000): it does not depend on dt from 1e-3 to 1e-8 s (with
    the bound too: both sides of it scale with dt), where the pressure of the projection of
    ``V*`` grows as 1/dt; a step that changes nothing (``a = 0``) leaves no pressure."""
    h, u0, w0, bed, fractions = random_state(5, layers=6)
    rng = np.random.default_rng(6)
    a_u, a_w = rng.normal(size=u0.shape), rng.normal(size=w0.shape)
    options = {"dx": 0.1, "g_n": g_n, "pressure_layers": 3}
    pressures, alone = [], []
    for dt in (1e-3, 1e-5, 1e-8):
        u, w = np.where(u0 != 0.0, u0 + dt * a_u, 0.0), w0 + dt * a_w
        got = nonhydrostatic.project(h, u, w, bed, fractions, dt=dt, start=(h, u0, w0), **options)
        without = nonhydrostatic.project(h, u, w, bed, fractions, dt=dt, **options)
        np.testing.assert_array_equal(got[0], without[0])
        np.testing.assert_array_equal(got[1], without[1])
        pressures.append(got[2])
        alone.append(np.abs(without[2]).max())
    scale = np.abs(pressures[0]).max()
    assert 0.0 < scale < 100.0
    for q in pressures[1:]:
        assert np.abs(q - pressures[0]).max() <= 1e-6 * scale
    assert alone[-1] > 1e4 * scale
    still = nonhydrostatic.project(h, u0, w0, bed, fractions, dt=1e-3, start=(h, u0, w0), **options)
    assert np.all(still[2] == 0.0) and np.any(still[0] != u0)


def cut_short(cfl: float) -> tuple[multilayer.Simulation, multilayer.Simulation]:
    """The channel collapse of a 0.1 m column on 60 cells of 4 mm at ``time.cfl``, to 0.05 s
    then 0.06 s, without and with its step to 0.05 s cut to land on 0.05 - 1e-8 s and a step
    of 1e-8 s: the two runs at 0.06 s, the pressure after the short step checked against the
    largest |q| of the last 10 normal steps."""
    runs = [
        multilayer.Simulation(
            Run(
                "cut", "column_collapse_channel", ("domain.cells=60", "domain.x_max=0.24", f"time.cfl={cfl}")
            ).load()
        )
        for _ in range(2)
    ]
    whole, cut = runs
    normal = []
    while whole.t < 0.05:
        whole.step(0.05)
        normal.append(float(np.abs(whole.q).max()))
    cut.advance(0.05 - 1e-8)
    assert cut.step(0.05) < 1.1e-8
    assert np.abs(cut.q).max() <= 1.5 * max(normal[-10:]) <= G * 0.1
    for sim in runs:
        sim.advance(0.06)
    return whole, cut


def test_a_step_cut_short_leaves_the_pressure_of_a_normal_step():
    """A step cut to 1e-8 s (to land on an output time) leaves a pressure of the order of
    the normal steps' (below g H0 ~ 1 m^2/s^2), not an impulse divided by 1e-8 s (3e3
    m^2/s^2 with the pressure of the projection of V*), and the state 0.01 s later differs
    from the run's without the cut by the first-order error of the step: 2e-4 of h and 2e-3
    of u with the default step, less with half of it (with the pressure of the projection of
    V*: 7 % and 90 %, whatever the step)."""
    differences = []
    for cfl in (0.45, 0.225):
        whole, cut = cut_short(cfl)
        differences.append(
            (
                np.abs(cut.h - whole.h).max() / whole.h.max(),
                np.abs(cut.u - whole.u).max() / np.abs(whole.u).max(),
            )
        )
    (h, u), (h_half, u_half) = differences
    assert h <= 1e-3 and u <= 1e-2
    assert h_half <= 0.7 * h and u_half <= 0.7 * u


def test_the_window_of_moving_columns_gives_the_whole_domain_answer():
    """Columns at rest beyond the moving ones take no part: the projection computed on the
    window equals the one assembled over the whole domain."""
    h, u, w, bed, fractions = random_state(5, cells=14)
    u[:, :3] = u[:, -4:] = 0.0
    fast = nonhydrostatic.project(h, u, w, bed, fractions, dx=0.1, dt=0.01)
    cons = assembly.constraint(h, bed, fractions, 0.1, False)
    _, dV, _ = nonhydrostatic.correction(cons, u != 0.0, u, w)
    L, F = u.shape[0], cons.left.size
    dv = dV[: L * F].reshape(L, F)
    du = np.zeros_like(u)
    np.add.at(du, (slice(None), cons.left), 0.5 * dv)
    np.add.at(du, (slice(None), cons.right), 0.5 * dv)
    assert np.allclose(fast[0], np.where(u != 0.0, u + du, 0.0), rtol=0, atol=1e-13)
    assert np.allclose(fast[1][u != 0.0], (w + dV[L * F :].reshape(u.shape))[u != 0.0], rtol=0, atol=1e-13)


def test_the_simulation_projection_reuses_its_arrays_without_carrying_anything_over():
    """``Projection`` (the simulation's step: w advected, then projected into arrays reused
    from step to step, written over the columns holding material only) gives the answer of
    ``project`` on the whole domain, bit for bit, for a wide then a narrow then an empty
    set of moving columns; its yield gravity is g cos(theta) + q / (h - z) (>= 0) where q
    is non-zero and g cos(theta) elsewhere."""
    h, u, w, bed, fractions = random_state(10, layers=6, cells=16)
    g_n, dt, dx = 9.81, 0.01, 0.1
    projection = nonhydrostatic.Projection(
        fractions, bed, dx=dx, periodic=False, dry=0.0, g_n=g_n, pressure_layers=3
    )
    q_before, h_before, u_before = np.zeros_like(u), h.copy(), 0.9 * u
    for lo, hi in ((0, 16), (6, 11), (9, 9)):
        h_now, u_now = h.copy(), u.copy()
        h_now[:lo] = h_now[hi:] = 0.0  # material in lo .. hi-1 only
        u_now[:, :lo] = u_now[:, hi:] = 0.0
        got = [a.copy() for a in projection(h_now, u_now, (h_before, u_before, w, q_before), dt, (0, 16))]
        w_star = np.zeros_like(w)
        nonhydrostatic._advect(w, u_now, dx, dt, False, 0, 16, w_star)
        guess = nonhydrostatic.tension_free(q_before, h_before, fractions, g_n)
        expected = nonhydrostatic.project(
            h_now, u_now, w_star, bed, fractions, dx=dx, dt=dt, g_n=g_n, tension_free=guess,
            pressure_layers=3, start=(h_before, u_before, w),
        )  # fmt: skip
        for a, b in zip(got, expected):
            np.testing.assert_array_equal(a, b)
        gravity = projection.yield_gravity(expected[2], h_now, (lo, hi))
        depth = nonhydrostatic.depth_below(h_now, fractions)
        with np.errstate(divide="ignore", invalid="ignore"):
            full = np.maximum(g_n + np.where(depth > 0.0, expected[2] / depth, 0.0), 0.0)
        np.testing.assert_array_equal(gravity, full)
        q_before, h_before, u_before = expected[2], h_now, expected[0]


def _projected_as_project(
    projection: nonhydrostatic.Projection, h: np.ndarray, u: np.ndarray, start: tuple, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The answer of ``projection`` (a simulation's, its arrays reused) on ``h``, ``u`` from
    ``start`` (h, u, w, q), asserted to be that of ``project`` (new arrays) bit for bit,
    which it returns."""
    h_before, u_before, w_before, q_before = start
    got = [a.copy() for a in projection(h, u, start, dt, (0, h.size))]
    w_star = np.zeros_like(w_before)
    nonhydrostatic._advect(w_before, u, projection.dx, dt, projection.periodic, 0, h.size, w_star)
    guess = nonhydrostatic.tension_free(q_before, h_before, projection.fractions, projection.g_n)
    expected = nonhydrostatic.project(
        h, u, w_star, projection.bed, projection.fractions, dx=projection.dx, dt=dt,
        periodic=projection.periodic, g_n=projection.g_n, tension_free=guess,
        pressure_layers=projection.pressure_layers, start=(h_before, u_before, w_before),
    )  # fmt: skip
    for a, b in zip(got, expected):
        np.testing.assert_array_equal(a, b)
    return expected


@pytest.mark.parametrize("pressure_layers", [3, 6])
def test_the_start_constraint_reused_from_the_last_projection_is_the_assembled_one(
    pressure_layers, monkeypatch
):
    """``E^n V^n`` of a step's start added up from the constraint the last projection
    stored (it ended on the thickness the step starts from, on the same window and free
    unknowns) equals the one assembled afresh, bit for bit; a start on another thickness or
    a changed window assembles it afresh.  ``Projection`` answers as ``project`` (new arrays)
    bit for bit either way."""
    h, u, w, bed, fractions = random_state(12, layers=6, cells=16)
    nodes, P = assembly.layering(tuple(fractions), pressure_layers)
    # the product of stored entries against the r-only assembly, on a window of moving cells
    left, right = assembly.faces(16, False)
    face_mass = (fractions[:, None] * 0.5 * (h[left] + h[right])).ravel()
    K = face_mass.size + u.size
    free, V0, row_of, rows = (
        np.empty(K, np.bool_),
        np.empty(K),
        np.empty(6 * 16, np.int64),
        np.empty(6 * 16, np.int64),
    )
    n = assembly.unknowns(face_mass, left, right, u != 0.0, u, w, 0, nodes, free, V0, row_of, rows, True)
    stored = (np.empty(K + 1, np.int64), np.empty(4000, np.int64), np.empty(4000), np.empty(K))
    geometry = (h, bed, fractions, 0.1, left, right, P)
    fresh, reused = np.zeros(n), np.zeros(n)
    assembly.entries(*geometry, free, row_of, *stored, V0, nonhydrostatic._NO_BAND, fresh)
    assembly.product(*stored[:3], free, V0, reused)
    assert np.any(fresh != 0.0)
    np.testing.assert_array_equal(fresh, reused)
    # the simulation's projection: reused where it applies only
    g_n, dt, dx = 9.81, 0.01, 0.1
    projection = nonhydrostatic.Projection(
        fractions, bed, dx=dx, periodic=False, dry=0.0, g_n=g_n, pressure_layers=pressure_layers
    )
    taken = []  # whether the projection's arrays held the start's constraint, call by call
    assembled_on = nonhydrostatic.Buffers.assembled_on

    def spied(buffers, *args):
        held = assembled_on(buffers, *args)
        if buffers is projection._buffers:
            taken.append(held)
        return held

    monkeypatch.setattr(nonhydrostatic.Buffers, "assembled_on", spied)
    q_before, h_before, u_before, w_before = np.zeros_like(u), 1.1 * h, 0.9 * u, w
    for lo, hi, change in ((0, 16, 1.0), (0, 16, 1.01), (0, 16, 0.99), (2, 16, 1.0), (2, 16, 1.02)):
        h_now, u_now = change * h, change * u
        h_now[:lo] = h_now[hi:] = 0.0  # material in lo .. hi-1 only
        u_now[:, :lo] = u_now[:, hi:] = 0.0
        expected = _projected_as_project(
            projection, h_now, u_now, (h_before, u_before, w_before, q_before), dt
        )
        assert np.any(expected[2] != 0.0)
        h_before, (u_before, w_before, q_before) = h_now, expected
    # the first start is on another thickness; then reused, reused, a new window, reused
    assert taken == [False, True, True, False, True]


@pytest.mark.parametrize("periodic", [False, True])
@pytest.mark.parametrize("pressure_layers", [3, 6])
def test_the_start_constraint_carried_over_to_another_window_is_the_assembled_one(
    periodic, pressure_layers, monkeypatch
):
    """``E^n V^n`` of a step's start where the window of moving columns moved or cells
    stopped since the last projection: the stored entries of the unknowns whose columns
    kept their thickness, bed and pressure rows, the others' assembled afresh, added up
    unknown by unknown, equal the whole assembly bit for bit (``Projection`` answers as
    ``project``, new arrays), with some unknowns of each kind."""
    h, u, w, bed, fractions = random_state(14, layers=6, cells=16)
    g_n, dt, dx = 9.81, 0.01, 0.1
    projection = nonhydrostatic.Projection(
        fractions, bed, dx=dx, periodic=periodic, dry=0.0, g_n=g_n, pressure_layers=pressure_layers
    )
    carried = []  # (carried over, fresh unknowns, free unknowns), call by call
    carried_over = nonhydrostatic.Buffers.carried_over

    def spied(buffers, key, geometry, free, *args):
        held = carried_over(buffers, key, geometry, free, *args)
        if buffers is projection._buffers:
            carried.append((held, int(buffers.fresh[: free.size].sum()) if held else 0, int(free.sum())))
        return held

    monkeypatch.setattr(nonhydrostatic.Buffers, "carried_over", spied)
    q_before, h_before, u_before, w_before = np.zeros_like(u), 1.1 * h, 0.9 * u, w
    # the same window with cells stopped; the window's ends moved (not periodic: a new window)
    for lo, hi, stopped in ((0, 16, None), (0, 16, 10), (2, 16, 5), (2, 13, None), (1, 13, 8)):
        h_now, u_now = h.copy(), u.copy()
        h_now[:lo] = h_now[hi:] = 0.0  # material in lo .. hi-1 only
        u_now[:, :lo] = u_now[:, hi:] = 0.0
        if stopped is not None:
            u_now[:3, stopped] = 0.0  # the lower layers of a column stop: its bottom rows leave
        expected = _projected_as_project(
            projection, h_now, u_now, (h_before, u_before, w_before, q_before), dt
        )
        h_before, (u_before, w_before, q_before) = h_now, expected
    # carried over (not periodic: also to another window) with unknowns reused and assembled
    assert sum(held and 0 < fresh < free for held, fresh, free in carried) >= (2 if periodic else 3)


def test_cholesky_refactored_from_a_row_equals_the_whole_factorisation():
    """The active-set iteration refactors only from the first row whose bound status
    changed: the factor equals a fresh one, and solves A' x = b (A' = A with the fixed rows
    and columns replaced by the identity)."""
    rng = np.random.default_rng(6)
    n, w = 60, 7
    dense = np.zeros((n, n))
    for d in range(w + 1):
        dense += np.diag(rng.normal(size=n - d), d)
    dense = dense @ dense.T + n * np.eye(n)  # symmetric positive definite, half-width 2w
    width = 2 * w
    band = np.array([[dense[i, i + d] if i + d < n else 0.0 for d in range(width + 1)] for i in range(n)])
    before = rng.random(n) < 0.2
    after = before.copy()
    after[35:] = rng.random(n - 35) < 0.5
    after[35] = not before[35]
    U = np.zeros(band.shape)
    banded.factor(band, before, U, 0)
    banded.factor(band, after, U, 35)
    fresh = np.zeros(band.shape)
    banded.factor(band, after, fresh, 0)
    assert np.abs(U - fresh).max() < 1e-12 * np.abs(fresh).max()
    fixed = np.where(after[:, None] | after[None, :], 0.0, dense) + np.diag(after.astype(float))
    b = rng.normal(size=n)
    assert np.allclose(fixed @ banded.substitute(U, b), b, rtol=0, atol=1e-10)


@pytest.mark.parametrize(("n", "w", "start"), [(61, 5, 0), (60, 5, 33), (9, 1, 4), (8, 0, 3), (1, 0, 0)])
def test_cholesky_two_rows_at_a_time_equals_the_dense_factor(n, w, start):
    """The banded factor (rows eliminated in pairs, refactored from ``start``) equals the
    dense Cholesky factor of A' (A with the fixed rows and columns replaced by the identity)
    to round-off, for odd and even sizes, starts and half-widths down to 0."""
    rng = np.random.default_rng(7)
    dense = np.zeros((n, n))
    for d in range(w + 1):
        dense += np.diag(rng.normal(size=n - d), d)
    dense = dense + dense.T + 4 * (w + 1) * np.eye(n)  # diagonally dominant, half-width w
    band = np.array([[dense[i, i + d] if i + d < n else 0.0 for d in range(w + 1)] for i in range(n)])
    fixed = rng.random(n) < 0.25
    U = np.zeros(band.shape)
    # first the factor of a set that differs from ``start`` on, then refactored from there
    banded.factor(band, np.where(np.arange(n) < start, fixed, ~fixed), U, 0)
    banded.factor(band, fixed, U, start)
    reduced = np.where(fixed[:, None] | fixed[None, :], 0.0, dense) + np.diag(fixed.astype(float))
    upper = np.linalg.cholesky(reduced).T
    expected = np.array([[upper[i, i + d] if i + d < n else 0.0 for d in range(w + 1)] for i in range(n)])
    assert np.abs(U - expected).max() <= 1e-14 * np.abs(expected).max() * n


def test_bounded_solve_equals_the_dense_solution_of_its_active_set():
    """The active-set iteration (partial refactorisations, forward solves restarted at the
    changed rows) ends on the minimiser of 1/2 x^T A x - r^T x subject to x <= bound: equal
    to round-off to the dense solve with its final active set, which satisfies the KKT
    conditions (x <= bound off the set, multiplier r - A x >= 0 on it)."""
    rng = np.random.default_rng(8)
    n, w = 90, 6
    dense = np.zeros((n, n))
    for d in range(1, w + 1):
        dense += np.diag(rng.normal(size=n - d), d)
    dense = dense + dense.T + 4 * (w + 1) * np.eye(n)
    band = np.array([[dense[i, i + d] if i + d < n else 0.0 for d in range(w + 1)] for i in range(n)])
    r = rng.normal(size=n) * 10.0
    bound = np.abs(rng.normal(size=n))
    settled = np.zeros(n, dtype=bool)
    banded.bounded(band, r, bound, settled, 100, np.empty(band.shape), 0)
    # a guess wrong from row 60 on: the solves after the first restart there
    active = settled.copy()
    active[60:] = rng.random(n - 60) < 0.5
    x, iterations = banded.bounded(band, r, bound, active, 100, np.empty(band.shape), 0)
    assert iterations >= 2 and 0 < active.sum() < n and np.array_equal(active, settled)
    free = ~active
    expected = bound.copy()
    expected[free] = np.linalg.solve(
        dense[np.ix_(free, free)], r[free] - dense[np.ix_(free, active)] @ bound[active]
    )
    assert np.abs(x - expected).max() <= 1e-13 * np.abs(expected).max()
    assert np.all(x[free] <= bound[free]) and np.all((r - dense @ x)[active] >= 0.0)


def test_the_step_whose_newton_iteration_did_not_converge_now_converges_from_its_seed(monkeypatch):
    """In this collapse (a = 10, 16 layers, steps cut at 0.01 s) the Newton iteration of the
    vertical step did not converge at t = 0.03 s from either seed (the unprojected velocities
    of the step before, then u): the dynamic programme returned the top velocities of one
    column with lost digits (test_column_kernel.py, "far out"), so no iterate satisfied the
    momentum balance.  Every step now converges from its first seed."""
    from pathlib import Path

    from multilayer.app.simulation import Simulation
    from multilayer.engine.vertical import newton as vertical_step
    from multilayer.scenario import load

    failures = []
    solve = vertical_step.implicit_step

    def recording(*args, **kwargs):
        try:
            return solve(*args, **kwargs)
        except RunError:
            failures.append(sim.t)
            raise

    monkeypatch.setattr(vertical_step, "implicit_step", recording)
    scenario = Path(__file__).resolve().parents[1] / "scenarios" / "column_collapse.yaml"
    overrides = ["initial.0.height=0.5", "domain.x_max=2.0", "domain.cells=500", "domain.layers=16"]
    pressure = ["model.pressure=non_hydrostatic", "model.pressure_layers=16"]  # (with 4 it completes)
    sim = Simulation(load(scenario, [*overrides, *pressure]))
    for k in range(1, 4):
        sim.advance(0.01 * k)
    sim.step()
    assert sim.t > 0.03 and np.isfinite(sim.u).all()
    assert failures == []


def test_the_pressure_bound_that_stopped_a_sheared_collapse_is_settled():
    """The bounded solve that stopped the channel collapse at a = 10 on 0.5 mm cells with
    ``model.vertical_shear`` (step 200, t = 0.019 s: the pressure of the update, 647 rows,
    from the final set of the projection of ``V*``, 293 bound rows), saved: from that set
    the iteration releases a line of bound interfaces one column per iteration and settles
    in 101 iterations (14 bound rows), no set repeated; the cap of 100 stopped it.  Its
    answer satisfies the KKT conditions: ``lam <= lam_max`` (p >= 0), the constraint
    ``A lam = r`` on the free rows, the multiplier ``r - A lam >= 0`` on the bound ones
    (complementarity: ``lam = lam_max`` exactly there)."""
    from pathlib import Path

    d = np.load(Path(__file__).parent / "data" / "pressure_bound_release.npz")
    band, r, bound, start = d["band"], d["r"], d["lam_max"], d["active"]
    n = band.shape[0]
    assert banded.bounded(band, r, bound, start.copy(), 100, np.empty(band.shape), 0)[1] == -1
    active = start.copy()
    cap = banded.iteration_cap(n)
    iterations = banded.bounded(band, r, bound, active, cap, np.empty(band.shape), 0)[1]
    assert iterations == 101 and start.sum() == 293 and active.sum() == 14  # regression: this system's
    active = start.copy()
    lam = banded.multipliers(band, r, np.arange(n), bound, active)[0]
    _assert_kkt(band, r, bound, lam, active)


def _assert_kkt(band, r, bound, lam, active):
    """The KKT conditions of ``min 1/2 lam^T A lam - r^T lam`` subject to ``lam <= bound``
    (``A`` in band storage) at ``lam`` with the active set ``active``: ``lam <= bound``,
    ``A lam = r`` on the free rows to round-off, ``lam = bound`` exactly and the multiplier
    ``r - A lam >= 0`` on the active ones."""
    n, w = band.shape[0], band.shape[1] - 1
    dense = np.zeros((n, n))
    for d in range(w + 1):
        dense += np.diag(band[: n - d, d], d)
    dense = dense + np.triu(dense, 1).T
    mu, free = r - dense @ lam, ~active
    assert np.all(lam <= bound)
    assert np.array_equal(lam[active], bound[active]) and np.all(mu[active] >= 0.0)
    assert np.abs(mu[free]).max() <= 1e-12 * np.abs(r).max()


def test_a_warm_started_bounded_solve_ends_on_the_answer_of_the_cold_one():
    """The two bounded solves of one step of the channel collapse at a = 10 on 0.5 mm cells
    with ``model.vertical_shear`` (step 116, t = 0.011 s, 560 rows), saved: the projection of
    ``V*`` from the interfaces where the bound held the step before, then the pressure of
    the update from those interfaces too (warm) instead of the projection's final set
    (cold, as before), with the projection's factor kept before the first row where the two
    sets differ.  The minimiser is unique (``A`` positive definite): from either start, and
    from a factorisation of its own, the pressure's solve ends on the same active set and
    the same ``lam`` to round-off, which satisfies the KKT conditions; the warm start takes
    fewer iterations (regression: this system's)."""
    from pathlib import Path

    d = np.load(Path(__file__).parent / "data" / "pressure_warm_start.npz")
    band, bound, held, r = d["band"], d["lam_max"], d["tension_free"], d["violation"]
    rows = np.arange(band.shape[0])
    lam, (U, final) = banded.multipliers(band, d["r"], rows, bound, held.copy())
    _assert_kkt(band, d["r"], bound, lam, final)
    assert np.array_equal(final, d["first_final"])
    # from the first's factor (copied: a solve refactors it in place), then from none
    cold = banded.multipliers(band, r, rows, bound, final.copy(), (U.copy(), final))
    warm = banded.multipliers(band, r, rows, bound, held.copy(), (U.copy(), final))
    alone = banded.multipliers(band, r, rows, bound, held.copy())
    for other in (cold, alone):
        assert np.array_equal(warm[1][1], other[1][1])
        assert np.abs(warm[0] - other[0]).max() <= 1e-13 * np.abs(warm[0]).max()
    _assert_kkt(band, r, bound, warm[0], warm[1][1])
    cap = banded.iteration_cap(rows.size)
    iterations = [
        banded.bounded(band, r, bound, guess.copy(), cap, np.empty(band.shape), 0)[1]
        for guess in (final, held)
    ]
    assert iterations == [36, 3]  # regression: this system's (cold, warm)


TALL = {
    **TINY_SCENARIO,
    "domain": {**TINY_SCENARIO["domain"], "layers": 5},
    "initial": [{**TINY_SCENARIO["initial"][0], "height": 1000.0}],
    "model": {"pressure": "non_hydrostatic"},
}
"""A column 1000 m high and 0.1 m wide on cells 0.0125 m wide in five layers: each of its four
pressure layers (the default) 2e4 cells thick."""


def test_a_bound_unsettled_on_a_tall_narrow_column_names_its_aspect_and_the_keys():
    """On the column of :data:`TALL` the active-set iteration of ``p >= 0`` does not settle
    at the first step; the message said only that (naming the solver): now it names the
    thickness of its pressure layers in cells and the keys that make the iteration settle,
    and with one pressure layer (the first key named) the same column's steps settle."""
    from multilayer.app.simulation import Simulation

    with pytest.raises(RunError) as failed:
        Simulation(multilayer.load(TALL)).advance(0.001)
    said = str(failed.value)
    assert (
        "not settled in" in said and "in 4 pressure layers" in said and "each layer 2e+04 cells thick" in said
    )
    assert "accepted: model.pressure_layers: 1" in said and "domain.cells" in said
    one = Simulation(multilayer.load(TALL, ["model.pressure_layers=1"]))
    one.advance(0.001)
    assert one.t == pytest.approx(0.001) and np.isfinite(one.u).all()


def test_the_aspect_said_of_an_unsettled_bound_names_keys_only_beyond_tall_columns():
    """Below :data:`TALL_ASPECT`, or on one pressure layer, the message says the aspect and
    no key (the iteration settled on such columns in the tests: another cause)."""
    h = np.array([0.0, 3.0, 1.0])
    assert nonhydrostatic.unsettled_columns(h, 3, 0.01).endswith("each layer 100 cells thick")
    assert "accepted" in nonhydrostatic.unsettled_columns(h, 2, 0.01)
    assert "accepted" not in nonhydrostatic.unsettled_columns(h, 1, 0.001)
