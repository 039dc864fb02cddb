"""The shear stress of the layers on vertical planes (``model.vertical_shear``, with
``model.pressure: non_hydrostatic``; docs/model.md, "Shear stress on vertical planes").

In the mu(I) law written as a tensor (Jop, Forterre & Pouliquen 2006, Nature 441, 727; the
two-dimensional collapses of Lagree, Staron & Popinet 2011, J. Fluid Mech. 686, 378, eq.
2.1-2.3) the shear stress ``tau_xz = tau_zx = mu(I) p D_xz / |D|`` has the rate
``2 D_xz = d_z u + d_x w``.  The layers' interface stresses (the vertical step) see ``d_z u``
only; the vertical velocity's change across columns, ``d_x w``, shears the vertical planes
between the columns, and its stress resists the fall of a column's outer part past its core.

Notes
-----
**Model.**  Each layer's vertical momentum (docs/nonhydrostatic.md, the Keller box) gains the
divergence of that stress on the vertical planes::

    d_t(h_a wbar_a) + ... = -(q_{a+1} - q_a) + d_x(h_a T_a) / rho,
    T_a = kappa(P_a) sgn(gamma) + eta(|gamma|, P_a) gamma,  |T_a| <= kappa(P_a) where gamma = 0,
    gamma = d_x wbar_a,

with the bulk law of the vertical step (``kappa``, ``eta``: docs/model.md, "Rheology") at the
layer's mean total pressure ``P_a = rho max(g cos(theta) (h - z_a,mid) + qbar_a, 0)`` (``qbar_a``
the mean of the non-hydrostatic pressures of the layer's two interfaces, those of the step's
start, as the vertical step's yield stresses use them).  This is the ``d_x w`` half of ``2 D_xz``
given its own stress: the x-momentum's interlayer stress keeps ``d_z u`` alone (its
counterpart ``d_z tau_zx`` in the ``u`` equation through ``d_x w`` is not included), and the
two stresses are each bounded by the law's, not by one norm ``mu p`` of the two rates
together.  Where both rates are large the material is therefore held by up to twice the
tensor law's shear stress: this is an upper estimate of what the stress on vertical planes
can do, not the tensor law.

**Discretisation.**  After the vertical step and the advection of ``wbar``, and before the
projection (which sees the changed ``wbar``), per layer along x over each run of moving cells
(``u != 0`` after the vertical step, ``h > dry``: the cells the projection corrects; a chain),
the implicit step minimises::

    sum_i m_i / (2 dt) (w_i - w*_i)^2 + sum_f [ K_f |s_f| + C_f s_f^2 / 2 ],   s_f = w_(i+1) - w_i,

``m_i = rho l_a h_i``, ``K_f = l_a h_f kappa(P_f) / dx``, ``C_f = l_a h_f eta(|gamma_f^n|, P_f)
/ dx^2`` with ``h_f``, ``P_f`` the means of the face's two cells and the rate ``gamma_f^n =
(wbar_(i+1) - wbar_i) / dx`` of the step's start (the viscous part lagged, a Picard step; the
yield part is exact).  A face between a moving cell and a wet cell at rest joins the chain to
a fixed ``w = 0`` (the projection leaves the vertical velocity of material at rest at zero);
a face to a dry cell, a domain end or a periodic link carries no stress.  Each chain is the
problem of one column of the vertical step (:class:`~multilayer.engine.vertical.problem.ColumnProblem`
with the cells as its layers, the left fixed end as its bed and the right one as its wall
term), solved exactly by the same solvers: the compiled dynamic programme
(:func:`multilayer.engine.vertical.column_solve.solve`) or the FiPy ALG2 reference
(:func:`multilayer.reference.vertical_fipy.solve`).

**Energy.**  The optimality condition is ``m_i (w_i - w*_i) / dt = Z_(i+1/2) - Z_(i-1/2)``
with ``Z_f = K_f xi_f + C_f s_f``, ``xi_f in sgn(s_f)``; so ``sum m_i (w_i^2 - w*_i^2) / 2 =
-sum m_i (w_i - w*_i)^2 / 2 - dt sum_f Z_f s_f`` with ``Z_f s_f = K_f |s_f| + C_f s_f^2 >= 0``
(the fixed ends likewise): the step never adds kinetic energy, and the projection after it is
orthogonal in the kinetic-energy norm.  The step conserves the vertical momentum of a chain
with free ends.

**Rest.**  Only moving cells change: a cell with ``u == 0`` after the vertical step is not in a
chain, its ``w`` is set to zero by the projection, so material at rest stays exactly at rest
(``u == 0.0``) and no creep is introduced.  The viscous conductance is lagged from ``w`` of the
step's start, which is zero at rest, so it changes no yield decision of the vertical step (it
comes after it).  A chain whose ``w*`` are all equal and that is free at both ends, or
all zero, is its own answer (the zero subgradient): it is kept to the bit, so a flow
uniform along x is unchanged.
"""

from __future__ import annotations

import numpy as np

from multilayer.engine.normal_stress import runs
from multilayer.engine.vertical import column_solve
from multilayer.engine.vertical.problem import ColumnProblem, VerticalSolver
from multilayer.engine.vertical.stresses import StressModel

VERTICAL = "a vertical plane between two columns of a layer (model.vertical_shear)"


class VerticalShear:
    """The implicit step of the shear stress on vertical planes (module Notes)."""

    def __init__(
        self,
        stresses: StressModel,
        fractions: np.ndarray,
        *,
        dx: float,
        dry: float,
        g_n: float,
        solver: VerticalSolver | None = None,
    ):
        """``solver`` solves each chain's :class:`ColumnProblem` (None: the compiled one, as
        for the vertical step; ``numerics.vertical_solver``)."""
        self.stresses, self.dx, self.dry, self.g_n = stresses, dx, dry, g_n
        self.solver: VerticalSolver = column_solve.solve if solver is None else solver
        self.fractions = fractions
        below = np.concatenate([[0.0], np.cumsum(fractions)[:-1]])
        self._centre = (1.0 - below - 0.5 * fractions)[:, None]  # (h - z_mid) / h

    def faces(
        self, h: np.ndarray, w: np.ndarray, q: np.ndarray, lo: int, hi: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """The yield thresholds ``K_f`` and conductances ``C_f`` (L, hi - lo - 1) of the faces
        between the columns ``lo .. hi-1`` (module Notes), ``w`` and ``q`` of the step's start;
        zero at a face beside a dry column (the law is evaluated between wet ones only)."""
        rho = self.stresses.material.density
        hw = h[lo:hi]
        qbar = 0.5 * (q[:, lo:hi] + np.vstack([q[1:, lo:hi], np.zeros((1, hi - lo))]))
        pressure = rho * np.maximum(self.g_n * self._centre * hw + qbar, 0.0)
        wet = (hw[1:] > self.dry) & (hw[:-1] > self.dry)
        p_f = 0.5 * (pressure[:, 1:] + pressure[:, :-1])[:, wet]
        thickness = 0.5 * (hw[1:] + hw[:-1])[wet]
        rate = np.abs(np.diff(w[:, lo:hi], axis=1))[:, wet] / self.dx
        x = self.stresses.x[lo:hi]
        x_f = np.broadcast_to(0.5 * (x[1:] + x[:-1])[wet], rate.shape)
        column = np.broadcast_to(thickness, rate.shape)
        kappa, eta = self.stresses.bulk_law(rate.ravel(), p_f.ravel(), column.ravel(), x_f.ravel(), VERTICAL)
        layer = self.fractions[:, None] * thickness
        K, C = np.zeros((2, self.fractions.size, hw.size - 1))
        K[:, wet] = layer * kappa.reshape(rate.shape) / self.dx
        C[:, wet] = layer * eta.reshape(rate.shape) / self.dx**2
        return K, C

    def __call__(
        self,
        h: np.ndarray,
        u: np.ndarray,
        start: tuple[np.ndarray, np.ndarray],
        dt: float,
        columns: tuple[int, int],
        w_star: np.ndarray,
    ) -> None:
        """The step over ``dt`` of ``w_star`` (L, N), in place at the moving cells of the
        columns ``columns`` (``u`` the vertical step's velocities on the thickness ``h``;
        ``start = (w, q)`` of the step's start)."""
        lo, hi = columns
        if hi - lo < 2:
            return
        moving = (u[:, lo:hi] != 0.0) & (h[lo:hi] > self.dry)
        if not moving.any():
            return
        K, C = self.faces(h, *start, lo, hi)
        wet = h[lo:hi] > self.dry
        mass = self.stresses.material.density * self.fractions[:, None] * h[lo:hi]
        for a in range(u.shape[0]):
            for run in runs(moving[a], shortest=1):
                self._chain(a, run.start, run.stop - 1, lo, wet, K[a], C[a], mass[a], dt, w_star, self.solver)

    @staticmethod
    def _chain(a, first, last, lo, wet, K, C, mass, dt, w_star, solver) -> None:
        """The step of the chain of cells ``lo + first .. lo + last`` of layer ``a``."""
        n = last - first + 1
        cells = slice(lo + first, lo + last + 1)
        ws = w_star[a, cells]
        left = first > 0 and wet[first - 1]  # a wet cell at rest beside it (the chain is maximal)
        right = last < wet.size - 1 and wet[last + 1]
        if not (ws != ws[0]).any() and (ws[0] == 0.0 or not (left or right)):
            return  # its own answer (module Notes), kept to the bit
        kappa, c = np.zeros(n), np.zeros(n)
        kappa[1:], c[1:] = K[first:last], C[first:last]
        if left:
            kappa[0], c[0] = K[first - 1], C[first - 1]
        wall, cw = np.zeros(n), np.zeros(n)
        if right:
            wall[-1], cw[-1] = K[last], C[last]
        problem = ColumnProblem(
            m=mass[first : last + 1, None],
            ustar=ws[:, None].copy(),
            dt=dt,
            kappa=kappa[:, None],
            c=c[:, None],
            w=wall[:, None],
            cw=cw[:, None],
        )
        w_star[a, cells] = np.asarray(solver(problem))[:, 0]
