"""Reference formulation of the implicit vertical step as FiPy terms.

Per column the step minimises the energy ``E(u)`` of a
:class:`~multilayer.engine.vertical.problem.ColumnProblem` (docs/model.md, "The implicit
vertical step")::

    E(u) = sum_a [ m_a/(2 dt) (u_a - u*_a)^2 + w_a |u_a| + cw_a/2 u_a^2 ]
         + sum_{k=0}^{L-1} [ kappa_k |u_{k+1} - u_k| + c_k/2 (u_{k+1} - u_k)^2 ],   u_0 = 0.

The yield terms are handled exactly by the augmented-Lagrangian algorithm ALG2 of
Fortin & Glowinski (1983) (the ADMM of Boyd et al. 2011): with the shear jumps
``s_k = (Du)_k = u_{k+1} - u_k`` and wall velocities ``t_a = u_a`` as auxiliary
variables, multipliers ``lam`` and ``mu`` and penalties ``r`` and ``rw``, each
iteration is

1. u-step, a linear implicit equation written as FiPy terms on the (x, sigma) mesh::

       (m/dt + cw + rw) u - div_sigma((c + r) grad_sigma u)
           = m/dt u* + rw t - mu - div_sigma(r s - lam),      u = 0 on the bed face;

2. exact soft thresholding (the proximal map of ``kappa |s| + r/2 (s - z)^2``)::

       s = sgn(z) max(|z| - kappa/r, 0),   z = Du + lam/r,
       t = sgn(y) max(|y| - w/rw, 0),      y = u + mu/rw;

3. multiplier ascent ``lam += r (Du - s)``, ``mu += rw (u - t)``;

steps 2 and 3 use the over-relaxed ``RELAXATION Du + (1 - RELAXATION) s`` for ``Du``
(and likewise for ``u``; Eckstein & Bertsekas 1992).

The viscous parts ``c`` and ``cw`` stay in the linear u-step, so only interfaces with
``kappa > 0`` (walls with ``w > 0``) are split; elsewhere ``r = 0`` (``rw = 0``) and
``s = Du`` (``t = u``).  The velocities are rebuilt from the auxiliary variables, whose
thresholding gives exact zeros: ``u_a = u_{a-1} + s_{a-1}`` from the ground, and a plug
block containing a layer stuck to the wall (``t_a == 0``) is set to ``0.0``.  Hence
static layers are exactly ``0.0`` and rigid plugs share one velocity to the last bit.
See docs/numerics.md, "Vertical step: FiPy reference formulation".
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence

import fipy as fp
import numpy as np

from multilayer.engine.vertical.problem import ColumnProblem
from multilayer.errors import RunError

PENALTY = 1.0
"""Penalties ``r_k = PENALTY sqrt(m_{k+1} M_k)/dt`` with ``M_k = sum_{b > k} m_b`` the mass
carried by link k, and ``rw_a = PENALTY m_a/dt`` (docs/numerics.md)."""
RELAXATION = 1.8
"""Over-relaxation of ``Du`` and ``u`` in the s-, t- and multiplier steps (Eckstein &
Bertsekas 1992); any value in (0, 2) converges, 1.8 roughly halves the iterations."""


def column_mesh(
    n_columns: int, fractions: Sequence[float] | None = None, n_layers: int | None = None
) -> fp.Grid2D:
    """The (x, sigma) mesh of ``n_columns`` independent columns, ``dy = fractions``.

    ``fractions`` are the layer fractions ``l_a`` (any positive values; uniform
    ``1/n_layers`` when omitted).  Cell ``i + j N`` is layer ``j`` of column ``i``.
    """
    if fractions is None:
        if n_layers is None:
            raise ValueError("column_mesh needs fractions or n_layers")
        fractions = [1.0 / n_layers] * n_layers
    dy = [float(f) for f in fractions]
    return fp.Grid2D(dx=1.0, dy=dy, nx=n_columns, ny=len(dy))


class VerticalStep:
    """The u-step equation of ALG2 on one mesh, built once and reused for every solve.

    ``mesh`` is a ``Grid2D`` in (x, sigma) with one row of cells per layer, possibly
    translated (:func:`column_mesh` or ``multilayer.mesh.LayeredMesh.grid``).

    The coefficients are FiPy variables updated with ``setValue`` (the equation is not
    rebuilt; ``tests/test_vertical_fipy.py`` checks that this agrees with a freshly built
    equation, FiPy issue #1223).
    """

    def __init__(self, mesh: fp.meshes.mesh2D.Mesh2D) -> None:
        self.mesh = mesh
        self.N = int(np.count_nonzero(mesh.facesBottom))
        self.L = mesh.numberOfCells // self.N
        # Grid2D numbers the horizontal faces first: face i + k N lies below layer k of
        # column i (link k); a face coefficient g acts as g A_f / d_f on the cell values
        links = slice(0, self.L * self.N)
        self._volume = np.asarray(mesh.cellVolumes).reshape(self.L, self.N)
        self._area = np.asarray(mesh._faceAreas)[links].reshape(self.L, self.N)
        self._dist = np.asarray(mesh._cellDistances)[links].reshape(self.L, self.N)

        self.u = fp.CellVariable(mesh=mesh, name="u", value=0.0)
        self.u.constrain(0.0, where=mesh.facesBottom)  # the ground, u_0 = 0
        self.inertia = fp.CellVariable(mesh=mesh, name="(m/dt + cw + rw)/V", value=1.0)
        self.conductance = fp.FaceVariable(mesh=mesh, name="(c + r) d/A", value=0.0)
        self.source = fp.CellVariable(mesh=mesh, name="(m/dt u* + rw t - mu)/V", value=0.0)
        self.flux = fp.FaceVariable(mesh=mesh, rank=1, name="(r s - lam)/A e_sigma", value=0.0)
        self.equation = (
            fp.ImplicitSourceTerm(coeff=self.inertia)
            == fp.DiffusionTerm(coeff=self.conductance) + self.source - self.flux.divergence
        )
        self.solver = fp.LinearLUSolver(tolerance=1e-15, iterations=10)
        self.iterations = 0  #: ALG2 iterations of the last call

    def _faces(self, per_link: np.ndarray) -> np.ndarray:
        """Face values: ``per_link`` (L, N) on the links k = 0..L-1, zero elsewhere."""
        values = np.zeros(self.mesh.numberOfFaces)
        values[: self.L * self.N] = per_link.ravel()
        return values

    def set_operator(self, inertia: np.ndarray, conductance: np.ndarray) -> None:
        """Set ``m/dt + cw + rw`` per layer and ``c + r`` per link (both (L, N))."""
        self.inertia.setValue((inertia / self._volume).ravel())
        self.conductance.setValue(self._faces(conductance * self._dist / self._area))

    def solve_u(self, source: np.ndarray, link_flux: np.ndarray) -> np.ndarray:
        """Solve the u-step for the cell source ``m/dt u* + rw t - mu`` and ``r s - lam``."""
        self.source.setValue((source / self._volume).ravel())
        flux = np.zeros((2, self.mesh.numberOfFaces))
        flux[1] = self._faces(link_flux / self._area)
        self.flux.setValue(flux)
        self.equation.solve(var=self.u, solver=self.solver)
        return np.array(self.u.value).reshape(self.L, self.N)

    def __call__(
        self,
        problem: ColumnProblem,
        *,
        tol: float = 1e-12,
        max_iter: int = 20000,
        poll: Callable[[], None] | None = None,
    ) -> np.ndarray:
        """Minimiser of E(u) for every column by ALG2 (module docstring).

        Converged when the primal residuals ``|Du - s|, |u - t|`` and the changes of
        ``s, t`` in one iteration (the dual residuals divided by ``r``) are all below
        ``tol * max|u*|``.  Raises :class:`~multilayer.errors.RunError` otherwise.
        ``poll()`` is called before every iteration (a FiPy solve each): it may raise to
        abandon the solve, as a run does on a signal (a call takes up to minutes).
        """
        p, dt = problem, problem.dt
        coefficients = (p.m, p.ustar, p.kappa, p.c, p.w, p.cw)
        m, ustar, kappa, c, w, cw = (np.asarray(a, dtype=float) for a in coefficients)
        wet = (m > 0.0).all(axis=0)
        m = np.where(wet, m, 0.0)
        inertia = m / dt
        carried = np.cumsum(inertia[::-1], axis=0)[::-1]  # M_k/dt: the column above link k
        r = np.where(wet & (kappa > 0.0), PENALTY * np.sqrt(inertia * carried), 0.0)
        rw = np.where(wet & (w > 0.0), PENALTY * inertia, 0.0)
        inv_r = np.divide(1.0, r, out=np.zeros_like(r), where=r > 0.0)
        inv_rw = np.divide(1.0, rw, out=np.zeros_like(rw), where=rw > 0.0)
        self.set_operator(np.where(wet, inertia + cw + rw, 1.0), np.where(wet, c + r, 0.0))

        s = np.zeros_like(m)
        t = np.zeros_like(m)
        lam = np.zeros_like(m)
        mu = np.zeros_like(m)
        scale = tol * np.abs(np.where(wet, ustar, 0.0)).max(initial=0.0)
        self.u.setValue(0.0)
        for iteration in range(1, max_iter + 1):  # noqa: B007 (read after the loop)
            if poll is not None:
                poll()
            u = self.solve_u(inertia * ustar + rw * t - mu, r * s - lam)
            du = np.diff(u, axis=0, prepend=0.0)
            du_relaxed = RELAXATION * du + (1.0 - RELAXATION) * s
            u_relaxed = RELAXATION * u + (1.0 - RELAXATION) * t
            z = du_relaxed + lam * inv_r
            s_new = np.where(r > 0.0, np.sign(z) * np.maximum(np.abs(z) - kappa * inv_r, 0.0), du)
            y = u_relaxed + mu * inv_rw
            t_new = np.where(rw > 0.0, np.sign(y) * np.maximum(np.abs(y) - w * inv_rw, 0.0), u)
            lam += r * (du_relaxed - s_new)
            mu += rw * (u_relaxed - t_new)
            residual = max(
                np.abs(du - s_new).max(),
                np.abs(u - t_new).max(),
                np.abs(s_new - s).max(),
                np.abs(t_new - t).max(),
            )
            s, t = s_new, t_new
            if residual <= scale:
                break
        else:
            raise RunError(
                f"vertical_fipy: ALG2 did not converge in {max_iter} iterations "
                f"(residual {residual:.3e} > {scale:.3e})"
            )
        self.iterations = iteration
        return np.where(wet, _reconstruct(s, t, w), 0.0)


def _reconstruct(s: np.ndarray, t: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Velocities from the shear jumps, ``u_a = u_{a-1} + s_{a-1}`` from the ground.

    A plug block (layers joined by ``s == 0``) holding a layer stuck to the wall
    (``w > 0``, ``t == 0``) is at rest: its velocity is set to exactly ``0.0``.
    """
    block = np.cumsum(s != 0.0, axis=0)  # plug-block label of each layer within its column
    stuck = (w > 0.0) & (t == 0.0)
    at_rest = np.zeros_like(stuck)
    for label in np.unique(block[stuck]):
        in_block = block == label
        at_rest |= in_block & (in_block & stuck).any(axis=0)
    u = np.empty_like(s)
    below = np.zeros(s.shape[1])
    for a in range(s.shape[0]):
        below = u[a] = np.where(at_rest[a], 0.0, below + s[a])
    return u


def solve(
    problem: ColumnProblem,
    *,
    fractions: Sequence[float] | None = None,
    tol: float = 1e-12,
    max_iter: int = 20000,
    poll: Callable[[], None] | None = None,
) -> np.ndarray:
    """Implicit vertical step for all columns on one FiPy mesh (module docstring).

    A column with ``m <= 0`` is dry and gets ``u = 0``.  ``fractions`` only sets the mesh
    geometry (``dy``); the coefficients are scaled so that the discrete equations are
    the optimality conditions of E(u) for any geometry.
    """
    L, N = problem.shape
    step = _uniform_step(N, L) if fractions is None else VerticalStep(column_mesh(N, fractions))
    return step(problem, tol=tol, max_iter=max_iter, poll=poll)


@functools.lru_cache(maxsize=8)
def _uniform_step(n_columns: int, n_layers: int) -> VerticalStep:
    """One equation per mesh size, reused across calls: its coefficients are variables
    updated with ``setValue``, which the tests check against fresh equations (FiPy issue #1223)."""
    return VerticalStep(column_mesh(n_columns, n_layers=n_layers))
