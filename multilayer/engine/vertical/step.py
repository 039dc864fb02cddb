"""The vertical stress step of a simulation: its stresses, solver and iteration in one place.

:class:`VerticalStep` holds the stress model of the rheology plugins, the exact solver
of the column problem (the compiled one, or another such as the FiPy reference handed to
the simulation) and, with the compiled solver, the fused compiled iteration
(:class:`~.newton_kernel.CompiledStep`), used whenever every law has compiled forms
(read at each step: a law swapped on a running simulation is honoured).  A step is tried
from each seed its pressure model gives, in turn: the seed changes the Newton work, not
the answer, and where one does not converge the next one is tried.

A step redone (``Simulation`` redoes a time step whose stress steps set material at rest
moving, with those columns taking part) is given what its last attempt solved
(:class:`Solved`): the columns whose thickness, velocities after transport, seed and
yield gravity are the same bits take that attempt's answer unsolved (each column's
problem is its own: the same inputs, the same iterations, the same answer); the others
are solved.  The columns set moving change only the transport of their neighbours, so a
redone step solves a few columns again instead of every one.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np

from multilayer.engine.compiled import jit
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

    def copy(self) -> Solved:
        """The same, in arrays of its own (the step's arrays are reused by the next ones)."""
        gravity = self.yield_gravity
        return Solved(
            self.h.copy(), self.ustar.copy(), self.seed.copy(), None if gravity is None else gravity.copy(),
            self.u.copy(),
        )  # fmt: skip


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
        #: what the last call solved from its first seed (None: another seed, or no call yet)
        self.solved: Solved | None = None

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
        again: Solved | None = None,
    ) -> tuple[np.ndarray, int]:
        """The velocities (L, N) after the stresses of a step of ``dt`` on the thickness
        ``h`` from the velocities ``ustar`` after transport, and the Newton iterations;
        ``rest`` (L, N) marks the layers at rest at the start of the step and
        ``yield_gravity`` (L, N) replaces ``g cos(theta)`` in the yield pressures; ``poll()``
        is called between kernel calls and may raise to abandon the step (Ctrl-C).
        ``again``: what the last attempt of the same step (the same ``dt`` and ``rest``)
        solved from the first of the same ``seeds`` (module docstring).  :attr:`solved`
        is then this call's, or None where its first seed did not converge."""
        self.solved = None
        known = None
        if again is not None and self.solver is column_solve.solve:  # (the FiPy reference solves all at once)
            same = np.zeros(h.size, np.bool_)
            if (yield_gravity is None) == (again.yield_gravity is None):
                none = np.empty((0, 0))
                gravity = none if yield_gravity is None else yield_gravity
                before = none if again.yield_gravity is None else again.yield_gravity
                _same_columns(h, ustar, seeds[0], gravity, again.h, again.ustar, again.seed, before, same)
            known = (same, again.u)
        for attempt, seed in enumerate(seeds):
            try:
                u, iterations = self._solve(
                    h, ustar, seed, dt, rest, yield_gravity, threads, poll, known if attempt == 0 else None
                )
            except NotConverged:
                if attempt == len(seeds) - 1:
                    raise
                continue
            if attempt == 0:
                self.solved = Solved(h, ustar, seed, yield_gravity, u)
            return u, iterations
        raise AssertionError("no seed given")  # (seeds is not empty)

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
def _same_columns(h, ustar, seed, gravity, h0, ustar0, seed0, gravity0, same):
    """``same[i]``: the thickness ``h``, velocities after transport ``ustar``, seed ``seed``
    and yield gravity ``gravity`` (L, N; an empty array: none) of column ``i`` are the same
    bits as those ending in 0."""
    L, N = ustar.shape
    for i in range(N):
        same[i] = _bits(h[i], h0[i])
    for a in range(L):
        for i in range(N):
            if same[i]:
                same[i] = _bits(ustar[a, i], ustar0[a, i]) and _bits(seed[a, i], seed0[a, i])
    if gravity.size:
        for a in range(L):
            for i in range(N):
                if same[i]:
                    same[i] = _bits(gravity[a, i], gravity0[a, i])


@jit(inline="always")
def _bits(x, y):
    """``x`` and ``y`` are the same number, bit for bit (not 0.0 and -0.0; NaN: never)."""
    return x == y and np.signbit(x) == np.signbit(y)
