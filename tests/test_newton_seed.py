"""The Newton seeds of the vertical steps (engine/vertical/extrapolation.py): they change the
work of the iteration (counted), not its answer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from engine import simulation

import multilayer

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
