"""The shear stress on vertical planes (``model.vertical_shear``, engine/vertical_shear.py;
docs/model.md, "Shear stress on vertical planes"): its step against the FiPy reference, its
optimality conditions and energy on the steps of a collapse, exact rest and flows uniform
along x unchanged to the bit."""

from __future__ import annotations

import numpy as np
import pytest
from test_nonhydrostatic import heap_below_repose, non_hydrostatic
from test_rest import held
from test_vertical import simple_shear

import multilayer
from multilayer.engine import vertical_shear
from multilayer.engine.normal_stress import runs
from multilayer.engine.vertical import column_solve
from multilayer.reference import vertical_fipy
from multilayer.validation.runs import SCENARIOS

SHEARED = {"pressure": "non_hydrostatic", "vertical_shear": True}
ON = {"model.vertical_shear": True}


def collapse_steps(count: int) -> tuple[vertical_shear.VerticalShear, list[tuple]]:
    """The channel collapse at a = 2 on 4 mm cells x 8 layers with the option: its shear step
    and the arguments of its first ``count`` calls (``w_star`` as it came in)."""
    sim = multilayer.Simulation(
        multilayer.load(SCENARIOS / "column_collapse_channel.yaml", {"domain.cells": 100, **ON})
    )
    shear = sim.pressure.projection.shear
    calls: list[tuple] = []

    def recording(h, u, start, dt, columns, w_star):
        calls.append((h.copy(), u.copy(), tuple(s.copy() for s in start), dt, columns, w_star.copy()))
        shear(h, u, start, dt, columns, w_star)

    sim.pressure.projection.shear = recording
    while len(calls) < count:
        sim.step()
    return shear, calls


def chain_faces(K, C, w, ws, mass, wet, a, first, last, dt):
    """The stresses ``Z``, jumps ``s``, yield thresholds and conductances of the faces of a
    chain (its left end, the faces between its cells, its right end), ``Z`` recovered from
    the momentum change of its cells; None where both ends are fixed and the left end's face
    does not shear (its stress is then not found from the momentum alone)."""
    cells = slice(first, last + 1)
    impulse = np.concatenate(([0.0], np.cumsum(mass[a, cells] * (w[a, cells] - ws[a, cells]) / dt)))
    left = first > 0 and wet[first - 1]
    right = last < wet.size - 1 and wet[last + 1]
    k, c = (
        np.concatenate(([F[a, first - 1] if left else 0.0], F[a, first:last], [F[a, last] if right else 0.0]))
        for F in (K, C)
    )
    s = np.concatenate(([w[a, first] * left], np.diff(w[a, cells]), [-w[a, last] * right]))
    if not left:
        z_left = 0.0
    elif not right:
        z_left = -impulse[-1]
    elif s[0] != 0.0:
        z_left = k[0] * np.sign(s[0]) + c[0] * s[0]
    else:
        return None
    return z_left + impulse, s, k, c


@pytest.mark.slow
def test_the_step_is_the_fipy_reference():
    """On a step of a collapse (every chain of its 8 layers): the compiled dynamic programme
    equals ALG2 on FiPy terms."""
    shear, calls = collapse_steps(30)
    h, u, start, dt, columns, w_in = calls[-1]
    compiled, reference = w_in.copy(), w_in.copy()
    shear(h, u, start, dt, columns, compiled)
    shear.solver = lambda p: vertical_fipy.solve(p, tol=1e-13)
    shear(h, u, start, dt, columns, reference)
    scale = np.abs(w_in).max()
    assert scale > 0.0 and not np.array_equal(compiled, w_in)
    np.testing.assert_allclose(compiled, reference, rtol=0, atol=1e-9 * scale)


def test_the_step_meets_its_optimality_conditions_and_dissipates():
    """On steps of a collapse: the stresses ``Z_f`` recovered from the momentum change are
    the law's (``K sgn(s) + C s`` where the face shears, within ``K`` where it does not, zero
    at a free end), and the kinetic energy of ``w`` falls by exactly ``sum m (w - w*)^2 / 2 +
    dt sum Z s``, ``Z s >= 0``."""
    shear, calls = collapse_steps(60)
    checked = yielded = rigid = 0
    for h, u, start, dt, columns, w_in in calls[10::10]:
        compiled = w_in.copy()
        shear(h, u, start, dt, columns, compiled)
        lo, hi = columns
        K, C = shear.faces(h, *start, lo, hi)
        moving = (u[:, lo:hi] != 0.0) & (h[lo:hi] > shear.dry)
        wet = h[lo:hi] > shear.dry
        mass = shear.stresses.material.density * shear.fractions[:, None] * h[lo:hi]
        w, ws = compiled[:, lo:hi], w_in[:, lo:hi]
        assert np.array_equal(w[~moving], ws[~moving])  # cells at rest are not touched
        for a in range(u.shape[0]):
            for run in runs(moving[a], shortest=1):
                faces = chain_faces(K, C, w, ws, mass, wet, a, run.start, run.stop - 1, dt)
                if faces is None:
                    continue
                Z, s, k, c = faces
                tol = 1e-7 * (np.abs(Z).max() + k.max())
                sheared = s != 0.0
                assert np.all(np.abs(Z - (k * np.sign(s) + c * s))[sheared] <= tol)
                assert np.all(np.abs(Z[~sheared]) <= k[~sheared] + tol)
                assert np.all(Z * s >= 0.0)
                before = 0.5 * (mass[a, run] * ws[a, run] ** 2).sum()
                after = 0.5 * (mass[a, run] * w[a, run] ** 2).sum()
                lost = 0.5 * (mass[a, run] * (w[a, run] - ws[a, run]) ** 2).sum() + dt * (Z * s).sum()
                assert after <= before
                assert after - before == pytest.approx(-lost, rel=1e-6, abs=1e-12 * before)
                checked += 1
                yielded += int(sheared.sum())
                rigid += int((~sheared & (k > 0.0)).sum())
    assert checked > 20 and yielded > 100 and rigid > 10


def test_the_collapse_deposit_comes_exactly_to_rest():
    """The channel collapse at a = 0.5 (4 mm cells): with the option it stops with ``u ==
    0.0`` and ``w == 0.0`` everywhere, its volume kept."""
    sim = multilayer.Simulation(
        multilayer.load(
            SCENARIOS / "column_collapse_channel.yaml",
            {"initial.0.height": 0.025, "domain.x_max": 0.2, "domain.cells": 50, **ON},
        )
    )
    volume = sim.h.sum()
    sim.advance(0.4)
    assert np.all(sim.u == 0.0) and np.all(sim.w == 0.0)
    assert sim.h.sum() == pytest.approx(volume, rel=1e-12)


def test_a_heap_below_repose_stays_exactly_at_rest():
    sim = heap_below_repose(SHEARED)
    max_u, max_dh = held(sim, 300)
    assert max_u == 0.0 and max_dh == 0.0
    assert np.all(sim.w == 0.0) and np.all(sim.q == 0.0)


def test_a_flow_uniform_along_x_is_unchanged_bit_for_bit():
    """Prop. 2.2 (``d_x w = 0``): the same velocities to the bit with and without the option."""
    runs = [simple_shear(nu=0.0, layers=40, model=model) for model in (non_hydrostatic(), SHEARED)]
    for sim in runs:
        sim.advance(0.2)
    assert np.array_equal(runs[0].u, runs[1].u) and np.array_equal(runs[0].w, runs[1].w)


def test_a_uniform_chain_is_kept_to_the_bit_and_a_sheared_one_is_not():
    """A chain with one ``w*`` and free ends is its own answer, to the bit; the same chain
    next to material at rest is held back by the face between them."""
    sim = multilayer.Simulation(
        multilayer.load(SCENARIOS / "column_collapse_channel.yaml", {"domain.cells": 100})
    )
    fractions = sim.fractions
    shear = vertical_shear.VerticalShear(
        sim.vertical.stresses, fractions, dx=sim.dx, dry=sim.dry, g_n=sim.g_n
    )
    L, N = fractions.size, sim.x.size
    h = np.where(np.arange(N) < 20, 0.05, 0.0)
    u = np.where(np.arange(N) < 20, 0.1, 0.0) * np.ones((L, 1))
    start = (np.zeros((L, N)), np.zeros((L, N)))
    w_star = np.where(np.arange(N) < 20, -0.3, 0.0) * np.ones((L, 1))
    kept = w_star.copy()
    shear(h, u, start, 1e-3, (0, 21), kept)
    assert np.array_equal(kept, w_star)
    u[:, :5] = 0.0  # the first five columns at rest
    held_back = w_star.copy()
    shear(h, u, start, 1e-3, (0, 21), held_back)
    assert np.all(held_back[:, 5] > w_star[:, 5]) and np.array_equal(held_back[:, :5], w_star[:, :5])


def test_the_step_solves_with_the_runs_vertical_solver():
    """``numerics.vertical_solver: fipy`` reaches the step's chains as it reaches the vertical
    step's columns; the default is the compiled solver."""
    path = SCENARIOS / "column_collapse_channel.yaml"
    overrides = {"domain.cells": 100, **ON}
    fipy = multilayer.Simulation(multilayer.load(path, {**overrides, "numerics.vertical_solver": "fipy"}))
    kernel = multilayer.Simulation(multilayer.load(path, overrides))
    assert fipy.pressure.projection.shear.solver is fipy.vertical.solver is not column_solve.solve
    assert kernel.pressure.projection.shear.solver is kernel.vertical.solver is column_solve.solve
