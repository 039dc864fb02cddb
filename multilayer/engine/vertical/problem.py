"""The problem one implicit vertical step poses per column, and the solvers' interface.

Per column the step minimises the strictly convex energy (docs/model.md, "The implicit
vertical step")::

    E(u) = sum_a [ m_a/(2 dt) (u_a - u*_a)^2 + cw_a/2 u_a^2 + w_a |u_a| ]
         + sum_{k=0}^{L-1} [ kappa_k |u_{k+1} - u_k| + c_k/2 (u_{k+1} - u_k)^2 ],   u_0 = 0.

:class:`ColumnProblem` holds its coefficients by name (they are all arrays of the same
shape, so passing them by position would let two be swapped silently);
:class:`VerticalSolver` is what the numba kernel (:mod:`multilayer.engine.vertical.column_solve`)
and the FiPy reference (:mod:`multilayer.reference.vertical_fipy`) provide.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Protocol

import numpy as np


@dataclass(frozen=True, eq=False)
class ColumnProblem:
    """Coefficients of ``E(u)`` for ``N`` columns of ``L`` layers; every array is (L, N).

    Interface ``k`` lies below layer ``k`` (0-based; ``k = 0`` is the bed).  A column with
    ``m == 0`` is dry and gets ``u = 0``.
    """

    m: np.ndarray
    """Layer masses per unit area ``rho h_a`` (kg/m^2)."""
    ustar: np.ndarray
    """Velocities after transport ``u*`` (m/s)."""
    dt: float
    """Time step (s)."""
    kappa: np.ndarray
    """Interface yield stresses (Pa)."""
    c: np.ndarray
    """Interface viscous conductances (Pa s/m)."""
    w: np.ndarray
    """Wall yield thresholds per unit area of each layer (Pa)."""
    cw: np.ndarray
    """Wall viscous conductances of each layer (Pa s/m)."""

    def __post_init__(self) -> None:
        shapes = {f.name: np.shape(getattr(self, f.name)) for f in fields(self) if f.name != "dt"}
        if len(set(shapes.values())) != 1 or len(shapes["m"]) != 2:
            raise ValueError(f"ColumnProblem arrays must all be (L, N), got {shapes}")

    @property
    def shape(self) -> tuple[int, int]:
        """``(L, N)``: layers and columns."""
        layers, columns = np.shape(self.m)
        return layers, columns

    def columns(self, index: np.ndarray | slice) -> ColumnProblem:
        """The sub-problem of the columns ``index``."""
        return ColumnProblem(
            m=self.m[:, index],
            ustar=self.ustar[:, index],
            dt=self.dt,
            kappa=self.kappa[:, index],
            c=self.c[:, index],
            w=self.w[:, index],
            cw=self.cw[:, index],
        )


class VerticalSolver(Protocol):
    """An exact minimiser of ``E(u)``: returns the new velocities (L, N).

    ``guess`` (e.g. the previous velocities) may be used to speed the solve up; it never
    changes the answer.  ``threads`` is the number of threads a solver may use.  ``poll()``,
    if given, is called between the solver's own iterations and may raise to abandon the
    solve (how a run honours a signal within a long solve).
    """

    def __call__(
        self,
        problem: ColumnProblem,
        guess: np.ndarray | None = None,
        threads: int = 1,
        poll: Callable[[], None] | None = None,
    ) -> np.ndarray: ...


def workspace_bytes(L: int) -> int:
    """Bytes of the workspace of the exact solver of columns of ``L`` layers
    (``column_solve._workspace``, one per thread, kept here where no kernel is compiled):
    the piecewise-linear messages of every layer, quadratic in ``L``."""
    cap = 8 * L + 16
    return 8 * (2 * L * cap + 4 * cap + 3 * L + 8)
