"""The Newton seed of a vertical step, extrapolated in time from the last two steps.

The Newton iteration of the vertical step (``newton.py``, ``newton_kernel.py``) starts
from a seed, which changes its work and never its answer (the same stopping test ends
it).  The state's velocities ``u^n`` lie O(dt) from the step's answer; the linear
extrapolation ``u^n + r (u^n - u^{n-1})``, ``r = dt / dt_{n-1}``, lies O(dt^2) from it in
a smooth flow, where one Newton iteration then meets the tolerance.  ``r`` is at most 1
(the step after one cut short to land on an output time does not amplify the last
difference), and 0 (no extrapolation) where ``u^{n-1}`` is not known.

The seed also proposes the lock/sign structure of the first Newton solve
(``column_solve._active_set``): which interfaces are locked, and the sign of each jump.
So the extrapolation is made jump by jump, from the bed up, and keeps the structure of
``u^n``: the jump ``s`` of ``u^n`` across an interface becomes ``s + r (s - s^{n-1})``
where that has the sign of ``s``, else stays ``s``.  A locked interface (``s = 0``)
stays locked, so a plug of ``u^n`` stays one, and a jump extrapolated through zero keeps
its sign; where every extrapolated jump keeps its sign and no layer below is at rest,
the seed is the linear extrapolation above.  A
layer at rest (``u^n == 0``) keeps the seed 0, so that the guess of a column at rest is
the column at rest (``newton_kernel._columns`` skips it when that is within the error
bound).  Extrapolated layer by layer instead, a plug of ``u^n`` whose layers moved apart
at ``n - 1`` (its edge moved) comes out sheared, and a jump that shrinks comes out
reversed: structures the exact solve rejects, several interfaces at once, more than its
repairs (``newton_kernel._other_structures``) mend.
"""

from __future__ import annotations

import numpy as np

from multilayer.engine.compiled import jit

MAX_RATIO = 1.0
"""The largest ratio ``r`` of the step to the last one that the extrapolation takes."""


class SeedExtrapolation:
    """The Newton seed at the start of the last step, and the next one extrapolated (module docstring)."""

    def __init__(self, shape: tuple[int, int]):
        self._last = np.zeros(shape)  # the seed at the start of the last accepted step
        self._start = np.zeros(shape)  # the seed at the start of this step
        self._guess = np.zeros(shape)
        self._window = (0, 0)  # the columns of _last that hold its seed
        self._pending = (0, 0)  # those of _start
        self._dt = 0.0  # the last accepted step; 0: none known

    def __call__(self, seed: np.ndarray, dt: float, columns: tuple[int, int]) -> np.ndarray | None:
        """The seed of a step of ``dt`` from ``seed`` (L, N), the seed at its start, in the
        columns ``columns`` (lo, hi), the others not set; None where no last step is known.
        ``seed`` is kept until :meth:`accept`."""
        ratio = min(dt / self._dt, MAX_RATIO) if self._dt > 0.0 else 0.0
        (first, stop), (lo, hi) = self._window, columns
        _extrapolate(seed, self._last, first, stop, ratio, self._guess, self._start, lo, hi)
        self._pending = columns
        return self._guess if ratio > 0.0 else None

    def accept(self, dt: float) -> None:
        """The step of ``dt`` whose seed was last given is taken: its start is the last step."""
        self._last, self._start = self._start, self._last
        self._window, self._dt = self._pending, dt

    def reset(self) -> None:
        """No last step known."""
        self._dt = 0.0
        self._window = (0, 0)

    def state_dict(self) -> dict:
        """The last step's seed, its columns and its step, so that a restored run
        extrapolates as the uninterrupted one does (a resumed run equals it bit for bit)."""
        return {"seed_last": self._last.copy(), "seed_window": np.array(self._window), "seed_dt": self._dt}

    def load_state(self, saved: dict) -> None:
        """Restore :meth:`state_dict`; a state saved without it restarts the extrapolation."""
        if "seed_dt" not in saved:
            self.reset()
            return
        self._last[...] = saved["seed_last"]
        first, stop = (int(v) for v in np.asarray(saved["seed_window"]))
        self._window, self._dt = (first, stop), float(saved["seed_dt"])


@jit
def _extrapolate(seed, last, first, stop, ratio, guess, start, lo, hi):
    """Over the columns ``lo .. hi-1``: ``start = seed`` and ``guess`` the seed extrapolated
    jump by jump (module docstring) where ``seed != 0`` and ``last`` holds the last step's
    seed (its columns ``first .. stop-1``), else ``seed``.

    Layer by layer, each a pass along the rows of the (L, N) arrays (the values below a
    layer are those of the row before it, just passed): a pass column by column reads the
    rows of the four arrays a cache line apart, a stream per layer that the processor does
    not prefetch (on a mesh whose arrays exceed its caches, the pass costs several times its
    instructions).  The extrapolated seed of the layer below is carried in a row of its own
    (``below_guess``), written beside ``guess``: read from ``guess`` itself, the row below
    the one written, the compiler could not tell the two apart and the loop ran one value
    at a time (18.6 against 5.5 instructions per cell on a (64, 20 000) call, the same
    values)."""
    L = seed.shape[0]
    known_lo = min(max(lo, first), hi)  # the columns where last is known: known_lo .. known_hi-1
    known_hi = max(min(hi, stop), known_lo)
    bed = np.zeros(hi)  # the values below layer 0
    below_guess = np.zeros(hi)  # the seed of the layer below (0: the bed), known columns only
    lo, hi, known_lo, known_hi = np.uint64(lo), np.uint64(hi), np.uint64(known_lo), np.uint64(known_hi)
    for a in range(L):  # the indices unsigned: no test for negative ones
        now, before, new = seed[a], last[a], guess[a]
        below, below_last = (seed[a - 1], last[a - 1]) if a > 0 else (bed, bed)
        for i in range(lo, hi):  # one stream stored per loop
            start[a, i] = now[i]
        for i in range(lo, known_lo):
            new[i] = now[i]
        for i in range(known_hi, hi):
            new[i] = now[i]
        for i in range(known_lo, known_hi):
            v = now[i]
            jump = v - below[i]
            change = jump + ratio * (jump - (before[i] - below_last[i]))
            extrapolated = below_guess[i] + (change if change * jump > 0.0 else jump)
            g = v if v == 0.0 else extrapolated
            below_guess[i] = g  # for the layer above
            new[i] = g
