"""The vertical stress step of a simulation: its stresses, solver and iteration in one place.

:class:`VerticalStep` holds the stress model of the rheology plugins, the exact solver
of the column problem (the compiled one, or another such as the FiPy reference handed to
the simulation) and, with the compiled solver, the fused compiled iteration
(:class:`~.newton_kernel.CompiledStep`), used whenever every law has compiled forms
(read at each step: a law swapped on a running simulation is honoured).  A step is tried
from each seed its pressure model gives, in turn: the seed changes the Newton work, not
the answer, and where one does not converge the next one is tried.

A time step redone (``Simulation`` redoes a step whose stress steps set material at rest
moving, with those columns taking part; :meth:`VerticalStep.begin`,
:meth:`VerticalStep.redo`) solves in each vertical step only the columns whose thickness,
velocities after transport, seed or yield gravity are not the same bits as in the same
call of the attempt before (:class:`Solved`); the others take that attempt's answer,
which is theirs to the bit (each column's problem is its own: the same inputs, the same
iterations, the same answer).  The columns set moving change only the transport of
themselves and their neighbours, so a redone step solves a few columns again instead of
every one.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np

from multilayer.engine.compiled import jit
from multilayer.engine.state import span
from multilayer.engine.vertical import column_solve
from multilayer.engine.vertical.newton import NotConverged, implicit_step
from multilayer.engine.vertical.newton_kernel import CompiledStep
from multilayer.engine.vertical.problem import VerticalSolver
from multilayer.engine.vertical.stresses import StressModel


class Solved(NamedTuple):
    """A vertical step's inputs and answer (arrays of the mesh; ``yield_gravity`` None for
    ``g cos(theta)``), for the same step redone (module docstring)."""

    h: np.ndarray
    ustar: np.ndarray
    seed: np.ndarray
    yield_gravity: np.ndarray | None
    u: np.ndarray


def kept(solved: tuple) -> Solved:
    """``solved`` (``VerticalStep._tried``) in arrays of its own on the columns holding
    material, zero elsewhere (where no column is the same: its thickness is not): the
    step's arrays are reused by the next ones."""
    h, ustar, seed, gravity, u = solved
    lo, hi = span(h)

    def window(values: np.ndarray) -> np.ndarray:
        own = np.zeros_like(values)
        own[..., lo:hi] = values[..., lo:hi]
        return own

    own_gravity = None if gravity is None else window(gravity)
    return Solved(window(h), window(ustar), window(seed), own_gravity, window(u))


class VerticalStep:
    """The implicit vertical step with the stresses ``stresses`` (module docstring)."""

    def __init__(
        self,
        stresses: StressModel,
        *,
        solver: VerticalSolver | None = None,
        tolerance: float,
        max_iterations: int,
        velocity_scale: float,
    ):
        self.stresses = stresses
        self.solver: VerticalSolver = column_solve.solve if solver is None else solver
        #: the fused compiled iteration (with the compiled column solver only)
        self.compiled = CompiledStep(stresses) if solver is None else None
        self.tolerance, self.max_iterations = tolerance, max_iterations
        self.velocity_scale = velocity_scale
        # what the calls of the attempt solved from their first seed, the fields of Solved (its
        # arrays, the yield gravity copied; None: from another seed), and of the attempt before
        self._tried: list[tuple | None] = []
        self._again: list[Solved | None] = []
        self._keep = False  # (only within a time step: begin)
        self._gravity: list[np.ndarray] = []  # the copies of the yield gravity, call by call

    def begin(self, keep: bool) -> None:
        """A time step starts: nothing solved yet; ``keep``: its calls are one per stage
        (what each solved is kept for the step redone: :meth:`redo`)."""
        self._tried, self._again, self._keep = [], [], keep

    def redo(self) -> None:
        """The time step is redone: each call takes what the same call of the attempt before
        solved (the columns whose inputs are the same bits keep its answer)."""
        self._again = [None if solved is None else kept(solved) for solved in self._tried]
        self._tried = []

    def __call__(
        self,
        h: np.ndarray,
        ustar: np.ndarray,
        dt: float,
        seeds: Sequence[np.ndarray],
        *,
        rest: np.ndarray | None,
        yield_gravity: np.ndarray | None,
        threads: int,
        poll: Callable[[], None] | None = None,
    ) -> tuple[np.ndarray, int]:
        """The velocities (L, N) after the stresses of a step of ``dt`` on the thickness
        ``h`` from the velocities ``ustar`` after transport, and the Newton iterations;
        ``rest`` (L, N) marks the layers at rest at the start of the step and
        ``yield_gravity`` (L, N) replaces ``g cos(theta)`` in the yield pressures; ``poll()``
        is called between kernel calls and may raise to abandon the step (Ctrl-C).  In a
        time step redone, the columns whose problem is the same as in the same call of the
        attempt before are not solved again (module docstring)."""
        call = len(self._tried)
        again = self._again[call] if call < len(self._again) else None
        known = None if again is None else self._known(h, ustar, seeds[0], yield_gravity, again)
        for k, seed in enumerate(seeds):
            try:
                u, iterations = self._solve(h, ustar, seed, dt, rest, yield_gravity, threads, poll, known)
            except NotConverged:
                if k == len(seeds) - 1:
                    raise
                known = None  # (a seed after the first: every column solved)
                continue
            if self._keep:
                self._tried.append(self._solved(call, k == 0, h, ustar, seed, yield_gravity, u))
            return u, iterations
        raise ValueError("a vertical step needs at least one seed")

    def _solved(self, call, first, h, ustar, seed, yield_gravity, u) -> tuple | None:
        """What the call ``call`` of the attempt solved, if from its ``first`` seed (else
        None): its arrays, valid until the attempt ends, but for the yield gravity, which the
        next call's overwrites: copied on the columns holding material."""
        if not first:
            return None
        if yield_gravity is not None:
            while len(self._gravity) <= call:
                self._gravity.append(np.empty((0, 0)))
            if self._gravity[call].shape != yield_gravity.shape:
                self._gravity[call] = np.empty_like(yield_gravity)
            lo, hi = span(h)
            self._gravity[call][:, lo:hi] = yield_gravity[:, lo:hi]
            yield_gravity = self._gravity[call]
        return h, ustar, seed, yield_gravity, u

    def _known(self, h, ustar, seed, yield_gravity, again: Solved) -> tuple[np.ndarray, np.ndarray] | None:
        """``(same, answer)`` of ``implicit_step``: the columns whose inputs are those of
        ``again``, bit for bit, and its answer; None with another solver than the compiled
        column solve (the FiPy reference solves all columns at once)."""
        if self.solver is not column_solve.solve:
            return None
        same = np.zeros(h.size, np.bool_)
        if (yield_gravity is None) == (again.yield_gravity is None):
            none = np.empty((0, 0))
            gravity = none if yield_gravity is None else yield_gravity
            before = none if again.yield_gravity is None else again.yield_gravity
            arrays = (h, ustar, seed, gravity, again.h, again.ustar, again.seed, before)
            _same_columns(*(a.view(np.int64) for a in arrays), *span(h), same)
        return same, again.u

    def _solve(self, h, ustar, seed, dt, rest, yield_gravity, threads, poll, known) -> tuple[np.ndarray, int]:
        return implicit_step(
            self.stresses,
            h,
            ustar,
            seed,
            dt,
            solver=self.solver,
            tolerance=self.tolerance,
            max_iterations=self.max_iterations,
            velocity_scale=self.velocity_scale,
            rest=rest,
            poll=poll,
            yield_gravity=yield_gravity,
            threads=threads,
            compiled=self.compiled,
            known=known,
        )


@jit
def _same_columns(h, ustar, seed, gravity, h0, ustar0, seed0, gravity0, lo, hi, same):
    """``same[i]`` for the columns ``lo .. hi-1``: the thickness ``h``, velocities after
    transport ``ustar``, seed ``seed`` and yield gravity ``gravity`` (L, N; an empty array:
    none) of column ``i`` are those ending in 0, the arrays seen as int64 (the same bits:
    0.0 is not -0.0, a NaN is the same NaN).  One pass along the rows per array, no branch."""
    for i in range(lo, hi):
        same[i] = h[i] == h0[i]
    for a in range(ustar.shape[0]):
        for i in range(lo, hi):
            same[i] = same[i] & (ustar[a, i] == ustar0[a, i]) & (seed[a, i] == seed0[a, i])
    for a in range(gravity.shape[0]):
        for i in range(lo, hi):
            same[i] = same[i] & (gravity[a, i] == gravity0[a, i])
