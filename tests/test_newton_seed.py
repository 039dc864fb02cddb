"""The Newton seeds of the vertical steps (engine/vertical/extrapolation.py): they change the
work of the iteration (counted), not its answer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from engine import simulation

import multilayer
from multilayer.engine.vertical import column_solve, newton_kernel
from multilayer.engine.vertical.extrapolation import _extrapolate

DAM_BREAK = {
    "gravity": 1.0,
    "domain": {"x_min": 0.0, "x_max": 50.0, "cells": 1000, "layers": 8},
    "material": {"density": 1.0, "grain_diameter": 1.0 / 32.0, "particle_density": 1.0},
    "rheology": {"name": "jop_mu_i", "mu_s": 0.35, "mu_2": 0.56, "I_0": 0.4},
    "base": [{"condition": "no_slip"}],
    "bed": {"points": [[0.0, 0.0], [50.0, -22.5]]},
    "initial": [{"shape": "rectangle", "x_min": 0.0, "x_max": 2.0, "height": 1.0}],
    "boundaries": {"left": "wall", "right": "outflow"},
    "time": {"end": 5.0, "output_interval": 5.0},
    "numerics": {"order": 2, "threads": 1},
}
"""The mu(I) dam break of benchmarks/dam_break.py on 1000 x 8 cells."""


class StateSeed:
    """No extrapolation: the first vertical step of a time step seeded by the state's velocities."""

    def __call__(self, seed, dt, columns):
        return None

    def accept(self, dt):
        pass

    def reset(self):
        pass


def test_the_extrapolated_seed_cuts_the_newton_solves_not_the_answer():
    """The dam break to t = 5 (399 steps): seeded by the extrapolated velocities (the first
    vertical step of a time step) and by the first stage's (the second), a column's Newton
    iteration takes 1.14 solves per vertical step (measured; 1.54 from the state's
    velocities) and the steps 4.85 iterations (the most of any column, both vertical steps
    added).  Counts, never times.  Seeded by the state's velocities instead, the run takes
    the same steps and ends with the same layers at rest, exactly, and velocities within
    the Newton tolerance accumulated over its steps (each vertical step lies within the
    tolerance times the velocity scale of the exact step, whatever its seed)."""
    seeded, plain = simulation(**DAM_BREAK), simulation(**DAM_BREAK)
    plain.seeds = StateSeed()
    for sim in (seeded, plain):
        sim.advance(5.0)
    stats, steps = seeded.vertical.compiled, seeded.steps
    assert stats.solves <= 1.2 * stats.columns < plain.vertical.compiled.solves
    assert seeded.newton_iterations <= 5.0 * steps
    assert plain.steps == steps and plain.t == seeded.t
    assert np.array_equal(seeded.u == 0.0, plain.u == 0.0)
    threshold = seeded.config.numerics.tolerance * seeded.vertical.velocity_scale
    assert np.abs(seeded.u - plain.u).max() <= 4 * steps * threshold


def test_a_state_restored_half_way_continues_bit_for_bit():
    """The checkpoint carries the extrapolation's last seed: a run restored half-way and
    continued equals the uninterrupted run bit for bit (without it, the first step after
    the restore starts Newton from another seed and ends within the tolerance only)."""
    path = Path(__file__).resolve().parents[1] / "scenarios" / "column_collapse.yaml"
    scenario = multilayer.load(path, {"domain.cells": 60, "time.end": 0.1})
    whole = multilayer.Simulation(scenario)
    whole.advance(0.05)
    saved = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in whole.state_dict().items()}
    whole.advance(0.1)
    restored = multilayer.Simulation(scenario)
    restored.load_state(saved)
    restored.advance(0.1)
    assert restored.steps == whole.steps
    assert np.array_equal(restored.u, whole.u) and np.array_equal(restored.h, whole.h)


class BinghamColumn:
    """One column's implicit step with Bingham interfaces (column_solve): ``L`` layers of
    mass 1/L, step 0.05, yield stresses ``kappa`` (L,) and conductances 0.01."""

    def __init__(self, kappa: np.ndarray):
        self.L = kappa.size
        self.m = np.full(self.L, 1.0 / self.L)
        self.dt = 0.05
        self.kappa, self.c, self.w = kappa, np.full(self.L, 0.01), np.zeros(self.L)
        self.z = (np.arange(self.L) + 0.5) / self.L  # the layers' heights in the column

    def coefficients(self, ustar: np.ndarray) -> tuple[np.ndarray, ...]:
        return self.m / self.dt, self.m * ustar / self.dt, self.kappa, self.c, self.w, self.w

    def exact(self, ustar: np.ndarray) -> np.ndarray:
        """The exact minimiser, by the O(L^2) dynamic programme."""
        u = np.empty(self.L)
        column_solve._dynamic_programme(*self.coefficients(ustar), u, column_solve._workspace(self.L))
        return u

    def solve(self, seed: np.ndarray, ustar: np.ndarray) -> tuple[str, np.ndarray]:
        """How the compiled Newton step solves with the structure of ``seed`` (the active set
        alone, or after the other structures, or the dynamic programme), and the answer."""
        L, u = self.L, np.empty(self.L)
        work = (np.empty(L + 1, np.int64), np.empty(L, np.bool_), *(np.empty(L) for _ in range(4)))
        hint = np.empty(2, np.int64)
        args = self.coefficients(ustar)
        if column_solve._active_set(*args, seed, u, *work, hint):
            return "active set", u
        proposal, column = np.empty(L), np.ascontiguousarray(ustar.reshape(L, 1))
        if newton_kernel._other_structures(*args, seed, column, np.int64(0), proposal, u, *work, hint):
            return "other structures", u
        return "dynamic programme", self.exact(ustar)


def seeds(now: np.ndarray, last: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The seed of the next step (r = 1) extrapolated layer by layer, and the seed of
    ``extrapolation._extrapolate`` (jump by jump)."""
    L = now.size
    guess, start = np.empty((L, 1)), np.empty((L, 1))
    _extrapolate(now.reshape(L, 1).copy(), last.reshape(L, 1).copy(), 0, 1, 1.0, guess, start, 0, 1)
    return now + (now - last), guess[:, 0]


def lock_pattern(u: np.ndarray) -> str:
    """The structure of ``u``: per interface from the bed up, locked '.', or the jump's sign."""
    jumps = np.diff(u, prepend=0.0)
    return "".join("." if s == 0.0 else ("+" if s > 0.0 else "-") for s in jumps)


def test_a_plug_whose_edge_moved_keeps_its_structure_in_the_seed():
    """A plug on top of a sheared column grows down by one layer from one step to the next
    (16 layers, yield stresses 0.2 + 0.6 p with p the weight above): extrapolated layer by
    layer, its new edge layer leaves the plug with a reversed jump, a structure the exact
    solve rejects (a repair mends it); extrapolated jump by jump the seed keeps the plug, the
    structure of the next step's answer, which the active set accepts at once.  The answer
    is the dynamic programme's to round-off (the minimiser is unique)."""
    col = BinghamColumn(0.2 + 0.6 * (16 - np.arange(16)) / 16)

    def profile(speed: float) -> np.ndarray:  # sheared at the bed, flat at the surface
        return speed * (1.0 - (1.0 - col.z) ** 3)

    last, now, ustar = col.exact(profile(2.25)), col.exact(profile(2.0)), profile(1.75)
    exact = col.exact(ustar)
    assert (lock_pattern(last), lock_pattern(now), lock_pattern(exact)) == (
        "+" * 13 + "." * 3, "+" * 12 + "." * 4, "+" * 12 + "." * 4,
    )  # fmt: skip
    layerwise, jumpwise = seeds(now, last)
    assert lock_pattern(layerwise) == "+" * 12 + "-..."
    assert lock_pattern(jumpwise) == lock_pattern(now)
    assert col.solve(layerwise, ustar)[0] == "other structures"
    how, u = col.solve(jumpwise, ustar)
    assert how == "active set"
    assert np.abs(u - exact).max() <= 1e-14 * np.abs(exact).max()
    assert np.array_equal(u == 0.0, exact == 0.0)


def test_a_column_locking_from_the_surface_down_is_solved_without_the_dynamic_programme():
    """The top 17 of 24 layers lock into one plug in one step (a flow stopping from the
    surface down; its bed locked, layer 0 at rest): the plug was sheared (reversed jumps) at
    the step before.  Extrapolated layer by layer, the seed shears the plug the other way at
    10 interfaces: the exact solve mends them one by one, one solve each (with at most 8
    repairs the dynamic programme solved).  Extrapolated jump by jump, the seed is the
    plug, which the active set accepts at once; the answer equals the programme's to
    round-off, with the layer at rest exactly 0."""
    L = 24
    kappa = 0.1 + 0.3 * (L - np.arange(L)) / L
    kappa[0] = 3.0  # the bed
    col = BinghamColumn(kappa)

    def profile(speed: float, shear: float) -> np.ndarray:  # sheared below z = 1/4, reversed above
        return speed * np.minimum(col.z / 0.25, 1.0) - shear * np.maximum(col.z - 0.25, 0.0)

    last, now, ustar = col.exact(profile(1.0, 0.8)), col.exact(profile(1.0, 0.2)), profile(0.95, 0.15)
    exact = col.exact(ustar)
    assert lock_pattern(now) == lock_pattern(exact) == "." + "+" * 6 + "." * 17
    assert lock_pattern(last).count("-") == 10
    layerwise, jumpwise = seeds(now, last)
    assert col.solve(layerwise, ustar)[0] == "other structures"
    how, u = col.solve(jumpwise, ustar)
    assert how == "active set"
    assert np.abs(u - exact).max() <= 1e-14 * np.abs(exact).max()
    assert u[0] == 0.0 and np.array_equal(u == 0.0, exact == 0.0)


def test_the_seed_of_each_column_is_that_column_extrapolated_on_its_own():
    """``_extrapolate`` passes the (L, N) arrays layer by layer: over a window of columns
    ``lo .. hi-1``, part of them with a last seed (``first .. stop-1``), each column's
    seed is the one of that column extrapolated alone (jump by jump, layers at rest kept
    0, the columns without a last seed not extrapolated), to the bit, and the columns
    outside the window are not written."""
    rng = np.random.default_rng(3)
    L, N = 9, 40
    now, last = rng.normal(size=(L, N)), rng.normal(size=(L, N))
    now[rng.random((L, N)) < 0.3] = 0.0  # layers at rest, and locked interfaces
    last[rng.random((L, N)) < 0.3] = 0.0
    for lo, hi, first, stop, ratio in ((3, 37, 0, 40, 1.0), (0, 40, 10, 25, 0.5), (5, 30, 28, 40, 0.7)):
        guess, start = np.full((L, N), 7.0), np.full((L, N), 7.0)
        _extrapolate(now, last, first, stop, ratio, guess, start, lo, hi)
        for i in range(N):
            alone, alone_start = np.empty((L, 1)), np.empty((L, 1))
            known = 1 if first <= i < stop else 0
            column = (now[:, i : i + 1].copy(), last[:, i : i + 1].copy())
            _extrapolate(*column, 0, known, ratio, alone, alone_start, 0, 1)
            inside = lo <= i < hi
            assert guess[:, i].tobytes() == (alone[:, 0] if inside else np.full(L, 7.0)).tobytes()
            assert start[:, i].tobytes() == (now[:, i] if inside else np.full(L, 7.0)).tobytes()
