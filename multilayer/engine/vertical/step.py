"""The vertical stress step of a simulation: its stresses, solver and iteration in one place.

:class:`VerticalStep` holds the stress model of the rheology plugins, the exact solver
of the column problem (the compiled one, or another such as the FiPy reference handed to
the simulation) and, with the compiled solver, the fused compiled iteration
(:class:`~.newton_kernel.CompiledStep`), used whenever every law has compiled forms
(read at each step: a law swapped on a running simulation is honoured).  A step is tried
from each seed its pressure model gives, in turn: the seed changes the Newton work, not
the answer, and where one does not converge the next one is tried.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from multilayer.engine.vertical import column_solve
from multilayer.engine.vertical.newton import NotConverged, implicit_step
from multilayer.engine.vertical.newton_kernel import CompiledStep
from multilayer.engine.vertical.problem import VerticalSolver
from multilayer.engine.vertical.stresses import StressModel


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
        is called between kernel calls and may raise to abandon the step (Ctrl-C)."""
        for seed in seeds[:-1]:
            try:
                return self._solve(h, ustar, seed, dt, rest, yield_gravity, threads, poll)
            except NotConverged:
                continue
        return self._solve(h, ustar, seeds[-1], dt, rest, yield_gravity, threads, poll)

    def _solve(self, h, ustar, seed, dt, rest, yield_gravity, threads, poll) -> tuple[np.ndarray, int]:
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
        )
