"""What the compiled vertical step (``newton_kernel._columns``) writes, and its passes
around each call: the dry columns of the reused result cleared (and the answers known
without a solve written) before, the counts read after.  Each is one compiled call where
numpy took several (five for the clearing, eight for the counts: together about 13 us a
call, a quarter of a kernel call on the 33 wet columns of the dam break of
``benchmarks/dam_break.py --cells 250``); on the small meshes of most scenarios that
fixed cost of each step outweighed the columns' own work."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from multilayer.engine.compiled import jit


class Results(NamedTuple):
    """What ``_columns`` writes: the velocities (L, N), and per wet column the Newton
    iterations (-1: not converged), the solves by the dynamic programme, the fault code
    and values, and whether it was solved side by side."""

    u: np.ndarray
    iterations: np.ndarray
    fallbacks: np.ndarray
    faults: np.ndarray
    fault_values: np.ndarray
    side_by_side: np.ndarray


@jit
def clear_dry(u, h, lo, hi):
    """Zero the columns ``lo .. hi-1`` of ``u`` (L, N) without material (``h`` not > 0):
    ``u[:, lo:hi][:, ~(h[lo:hi] > 0)] = 0``."""
    for i in range(lo, hi):
        if not h[i] > 0.0:
            for a in range(u.shape[0]):
                u[a, i] = 0.0


def bounds(occupied: np.ndarray) -> tuple[int, int]:
    """The columns (lo, hi) from the first to the last of the increasing column indices
    ``occupied``, (0, 0) for none: those a call on the wet columns ``occupied`` may make
    non-zero in the velocities, and reads of the coefficients' inputs."""
    return (int(occupied[0]), int(occupied[-1]) + 1) if occupied.size else (0, 0)


def written(
    u: np.ndarray, columns: tuple[int, int], known: tuple[np.ndarray, np.ndarray] | None
) -> tuple[int, int]:
    """``columns`` (lo, hi: :func:`bounds` of the wet columns), those of ``u`` that a call may make
    non-zero; with ``known = (same, answer)``, the columns ``same`` (N,) among them take the
    velocities of ``answer`` (L, N) (the call solves the others)."""
    if known is not None:
        _take(u, known[1], known[0], *columns)
    return columns


@jit
def _take(u, answer, same, lo, hi):
    """``u[:, i] = answer[:, i]`` for the columns ``i`` in ``lo .. hi-1`` where ``same``."""
    for a in range(u.shape[0]):
        for i in range(lo, hi):
            if same[i]:
                u[a, i] = answer[a, i]


@jit
def tally(out, max_iterations):
    """What the callers read of the :class:`Results` ``out``, in one pass: whether a column
    has a fault, the columns not converged (iterations < 0), the most iterations of a column
    (at least 1), the solves (``max_iterations`` for a column not converged), of which by
    the dynamic programme, and the columns solved side by side."""
    faulty, failed, most, solves, fallbacks, side_by_side = False, 0, 1, 0, 0, 0
    for j in range(out.iterations.size):
        count = out.iterations[j]
        faulty = faulty or out.faults[j] != 0
        failed += count < 0
        most = max(most, count)
        solves += max_iterations if count < 0 else count
        fallbacks += out.fallbacks[j]
        side_by_side += out.side_by_side[j]
    return faulty, failed, most, solves, fallbacks, side_by_side
