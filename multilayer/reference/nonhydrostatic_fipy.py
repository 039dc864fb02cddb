"""Reference formulation of the non-hydrostatic pressure projection as FiPy terms.

The fast path (``multilayer.engine.pressure.non_hydrostatic.projection.project``) assembles the constraint
``E`` and solves ``A lam = E V*`` with ``A = E M^-1 E^T`` by banded Cholesky.  Here the same
problem is written on the X-sigma ``Grid2D`` (``dx``, ``dy = l_a h``) for flat interfaces
(uniform ``h``, flat bed) and every cell moving, where ``A`` splits into two diffusion
operators (docs/nonhydrostatic.md)::

    A lam = -div_sigma(Gamma_v grad_sigma lam) - B^T div_x(Gamma_x grad_x (B lam)),
    lam = 0 on the free surface, no flux at the bed and at walls,

with ``(B lam)_a = lam_a + lam_{a+1}`` (``lam_L = 0``), ``Gamma_v A_f / d_f = 1 / m_a`` on
the face above layer ``a`` (``m_a = l_a h``) and ``Gamma_x A_f / d_f = h_a / (4 dx^2)``
on the faces between columns.  Both are FiPy ``DiffusionTerm``s (matrices taken from
FiPy's own assembly); the sum over adjacent layers ``B`` is not a FiPy term and is applied
to their matrices.  The right-hand side uses FiPy's divergence of the layer fluxes
``h_a v_f`` and the correction FiPy's face gradient of ``B lam``.

With the pressure on fewer layers (``pressure_nodes``: the velocity layers whose bottom
interfaces carry it) the multipliers are ``lam = P lam_p``, ``P`` the linear interpolation
in sigma between those interfaces and zero at the free surface, and the reduced problem is
the Galerkin one, ``P^T A P lam_p = P^T E V*`` (``P`` built here with ``numpy.interp``).
"""

from __future__ import annotations

import fipy as fp
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def _diffusion_matrix(var: fp.CellVariable, coeff: fp.FaceVariable) -> sp.csr_matrix:
    """``-`` FiPy's matrix of ``DiffusionTerm(coeff)`` acting on ``var`` (with its constraints)."""
    equation = fp.DiffusionTerm(coeff=coeff) == 0.0
    equation.cacheMatrix()
    equation.cacheRHSvector()
    equation.sweep(var=var, solver=fp.DummySolver())
    return -equation.matrix.matrix.tocsr()


def project(
    h: float,
    u: np.ndarray,
    w: np.ndarray,
    fractions: np.ndarray,
    *,
    dx: float,
    dt: float,
    periodic: bool = False,
    pressure_nodes: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The projection of ``projection.project`` for a uniform thickness ``h`` on a flat
    bed with every cell moving: returns the new ``u``, ``w`` and the pressures ``q`` (L, N),
    with the pressure on the bottom interfaces of the layers ``pressure_nodes`` (default:
    every layer) interpolated on the others."""
    L, N = u.shape
    dy = list(np.asarray(fractions, dtype=float) * h)
    grid = fp.PeriodicGrid2DLeftRight if periodic else fp.Grid2D
    mesh = grid(dx=dx, dy=dy, nx=N, ny=L)
    horizontal = int((L + 1) * N)  # Grid2D numbers the faces between layers first
    area = np.asarray(mesh._faceAreas)
    dist = np.asarray(mesh._cellDistances)
    m = np.asarray(fractions) * h

    lam_var = fp.CellVariable(mesh=mesh, value=0.0)
    lam_var.constrain(0.0, where=mesh.facesTop)
    above = np.zeros(mesh.numberOfFaces)
    above[N:horizontal] = np.repeat(1.0 / m, N)  # the face above layer a: 1 / m_a
    vertical = fp.FaceVariable(mesh=mesh, value=above * dist / area)
    A_v = _diffusion_matrix(lam_var, vertical)

    big_var = fp.CellVariable(mesh=mesh, value=0.0)
    across = np.zeros(mesh.numberOfFaces)
    centres_y = np.asarray(mesh.faceCenters[1])[horizontal:]
    edges = np.concatenate([[0.0], np.cumsum(dy)])
    layer = np.searchsorted(edges, centres_y) - 1  # the layer of each face between columns
    across[horizontal:] = m[layer] / (4 * dx * dx)
    A_x = _diffusion_matrix(big_var, fp.FaceVariable(mesh=mesh, value=across * dist / area))

    B = sp.eye(L * N, format="csr") + sp.eye(L * N, k=N, format="csr")  # cell a*N+i: lam_a + lam_{a+1}
    A = (A_v + B.T @ A_x @ B).tocsc()

    # right-hand side E V*: w_a - w_{a-1} + (F_{a-1} + F_a) / 2 with F = div_x(h_a v*)
    flux = fp.FaceVariable(mesh=mesh, rank=1, value=0.0)
    face_u = fp.CellVariable(mesh=mesh, value=u.ravel()).arithmeticFaceValue
    values = np.zeros((2, mesh.numberOfFaces))
    values[0, horizontal:] = np.asarray(face_u)[horizontal:] * m[layer]
    walls = np.asarray(mesh.facesLeft | mesh.facesRight) if not periodic else np.zeros(values.shape[1], bool)
    values[:, walls] = 0.0  # no flux through a wall
    flux.setValue(values)
    F = np.asarray(flux.divergence).reshape(L, N)
    rhs = w.copy()
    rhs[1:] -= w[:-1]
    rhs += 0.5 * F
    rhs[1:] += 0.5 * F[:-1]
    if pressure_nodes is None:
        lam = spla.spsolve(A, rhs.ravel())
    else:
        sigma = np.concatenate([[0.0], np.cumsum(fractions)[:-1]])
        at = np.append(sigma[pressure_nodes], 1.0)
        P = np.column_stack([np.interp(sigma, at, np.eye(at.size)[g]) for g in range(at.size - 1)])
        P_cells = sp.kron(sp.csr_matrix(P), sp.eye(N)).tocsc()  # cell a*N+i from g*N+i
        lam = P_cells @ spla.spsolve((P_cells.T @ A @ P_cells).tocsc(), P_cells.T @ rhs.ravel())

    big = fp.CellVariable(mesh=mesh, value=B @ lam)
    dv_faces = 0.5 * np.asarray(big.faceGrad[0])  # dv_f = (Lam_R - Lam_L) / (2 dx)
    dv_faces = np.where(np.arange(mesh.numberOfFaces) >= horizontal, dv_faces, 0.0)
    dv_faces[walls] = 0.0  # walls carry no correction
    # cell centres take the mean of the corrections of their two faces
    cell_faces = np.asarray(mesh.cellFaceIDs)  # (4, cells): bottom, right, top, left
    du = 0.5 * (dv_faces[cell_faces[1]] + dv_faces[cell_faces[3]])
    lam2 = lam.reshape(L, N)
    up = np.vstack([lam2[1:], np.zeros((1, N))])
    dw = -(lam2 - up) / m[:, None]
    q = np.cumsum((m[:, None] * dw)[::-1], axis=0)[::-1] / dt
    return u + du.reshape(L, N), w + dw, q
