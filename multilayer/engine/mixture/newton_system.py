"""The linear systems of the mixture's Newton iteration (``LocalStep._newton``): one per
column, ``J x = b``, J the finite-difference Jacobian of the residual in the pore pressures
and ``z = h* / h'``.

In columns of one layer the system is 2 x 2 and is solved by Gaussian elimination with
partial pivoting, written out (:func:`solve_pairs`)::

    swap the rows if |J_10| > |J_00|
    l = J_10 (1 / J_00)                    (J_10 / J_00 where |J_00| < tiny)
    u = J_11 - l J_01
    x_1 = (b_1 - l b_0) / u,   x_0 = (b_0 - J_01 x_1) / J_00

the operations and their order of LAPACK's ``dgetf2`` and ``dgetrs``, each rounded once: the
compiled iteration (``local_kernel.solve_2x2``) makes the same operations, so the two answer
the same bits on every machine, whatever LAPACK (and its fused multiply-adds) numpy is built
with.  Larger systems (columns of several layers) are solved by LAPACK.  A batch holding a
singular system (a zero pivot) is solved by least squares, column by column.
"""

from __future__ import annotations

import numpy as np

TINY = float(np.finfo(float).tiny)
"""The least pivot multiplied by its reciprocal; LAPACK divides by smaller ones."""


def solve_pairs(jacobian: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(solved, x)``: the 2 x 2 systems ``jacobian`` (n, 2, 2), ``rhs`` (n, 2) solved by the
    elimination of the module's Notes; ``solved`` (n,) False where a pivot is zero."""
    (a00, a01), (a10, a11) = jacobian[:, 0].T, jacobian[:, 1].T
    b0, b1 = rhs.T
    swap = np.abs(a10) > np.abs(a00)
    a00, a10 = np.where(swap, a10, a00), np.where(swap, a00, a10)
    a01, a11 = np.where(swap, a11, a01), np.where(swap, a01, a11)
    b0, b1 = np.where(swap, b1, b0), np.where(swap, b0, b1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # the singular: not solved
        multiplier = np.where(np.abs(a00) >= TINY, a10 * (1.0 / a00), a10 / a00)
        u = a11 - multiplier * a01
        x1 = (b1 - multiplier * b0) / u
        x0 = (b0 - a01 * x1) / a00
    return (a00 != 0.0) & (u != 0.0), np.stack([x0, x1], axis=1)


def solve_batched(jacobian: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``jacobian^-1 rhs`` per column (n, k, k) x (n, k): :func:`solve_pairs` for k = 2, LAPACK
    for larger k; least squares in every column where one system is singular."""
    if jacobian.shape[1] == 2:
        solved, x = solve_pairs(jacobian, rhs)
        if solved.all():
            return x
    else:
        try:
            return np.linalg.solve(jacobian, rhs[..., None])[..., 0]
        except np.linalg.LinAlgError:
            pass
    return np.stack([np.linalg.lstsq(J, r, rcond=None)[0] for J, r in zip(jacobian, rhs, strict=True)])
