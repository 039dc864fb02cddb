"""The implicit vertical step: interlayer, basal and wall stresses, exactly.

After transport each column holds velocities ``u*``.  The new velocities minimise the
strictly convex energy (docs/model.md; Bouchut, Ionescu & Mangeney 2016, eq. 1.3-1.8)::

    sum_a rho h_a (u_a - u*_a)^2 / (2 dt) + sum_k [kappa_k |Delta u_k| + viscous potential]
      + sum_a (2 mu_w / W) h_a pbar_a |u_a| + basal term

whose optimality conditions are the implicit momentum balance
``rho h_a (u_a - u*_a) / dt = tau_{a+1/2} - tau_{a-1/2} - F_a`` with the multivalued
``sgn`` of the yield stresses.  Each iteration solves a Bingham-type problem exactly
(``column_solve.solve`` or the FiPy reference ``vertical_fipy.solve``, both
:class:`~multilayer.engine.vertical.problem.VerticalSolver`): the rate-dependent part
is replaced by its tangent at the current shear rates (``StressModel.linearise``, a
Newton iteration whose fixed points are the exact solutions), and the step towards the
model's minimiser is taken in full or damped by an exact line search on the energy
(``newton_control``), until the error bound of the velocities is within ``tolerance``
times the velocity scale.

This is the iteration in numpy, over all unconverged columns at once: the one path that
calls the rheology plugins' own Python methods (a third-party law without compiled forms,
or one a subclass redefines) and the one that runs another exact solver of the column
problem (the FiPy reference).  Where every law has compiled forms the same iteration runs
compiled and fused per column (:mod:`.newton_kernel`; ``implicit_step(compiled=...)``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from multilayer.engine.vertical import column_solve
from multilayer.engine.vertical.forms import concave_laws
from multilayer.engine.vertical.newton_control import HALVINGS, examine_columns, slopes_along
from multilayer.engine.vertical.newton_kernel import CompiledStep
from multilayer.engine.vertical.problem import VerticalSolver
from multilayer.engine.vertical.stresses import ColumnStresses, StressModel
from multilayer.errors import RunError


class NotConverged(RunError):
    """The Newton iteration of the vertical step (or of the normal-stress step,
    engine/normal_stress.py) did not reach its tolerance."""


def implicit_step(
    stresses: StressModel,
    h: np.ndarray,
    ustar: np.ndarray,
    u_guess: np.ndarray,
    dt: float,
    *,
    solver: VerticalSolver = column_solve.solve,
    tolerance: float = 1e-10,
    max_iterations: int = 200,
    velocity_scale: float = 1.0,
    rest: np.ndarray | None = None,
    poll: Callable[[], None] | None = None,
    yield_gravity: np.ndarray | None = None,
    threads: int = 1,
    compiled: CompiledStep | None = None,
    known: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, int]:
    """New layer velocities (L, N) after the stresses of one step, and the Newton count.

    ``u_guess`` (usually the previous velocities) seeds the viscosity.  ``rest`` (L, N)
    marks the layers at rest at the start of the step, where the static yield stress of
    a start/stop law applies (``StressModel.columns``).  Only columns that have not
    converged are solved again.  ``poll()`` is called before every kernel call: it may
    raise to abandon the step (how a run honours Ctrl-C within a kernel call).
    ``yield_gravity`` (L, N) replaces ``g cos(theta)`` in the interface pressures.
    ``threads`` goes to the solver.  With ``compiled`` the same iteration runs fused per
    column when every law has a compiled form.  ``known = (same, answer)``: the wet columns
    where ``same`` (N,) is True take the velocities of ``answer`` (L, N) unsolved (with a
    solver that solves each column on its own, a column's answer is a function of its own
    inputs only); the iterations are those of the others.
    """
    threshold = tolerance * velocity_scale
    if compiled is not None and compiled.laws() is not None:
        if poll is not None:
            poll()
        u, _ = compiled(
            h,
            ustar,
            u_guess,
            dt,
            threshold=threshold,
            max_iterations=max_iterations,
            threads=threads,
            rest=rest,
            yield_gravity=yield_gravity,
            known=known,
        )
        if compiled.not_converged:
            raise _not_converged(tolerance, max_iterations, compiled.not_converged)
        return u, compiled.most_iterations
    u = np.zeros_like(ustar)
    wet = np.flatnonzero(h > 0)
    if known is not None:
        same, answer = known[0][wet], known[1]
        u[:, wet[same]] = answer[:, wet[same]]
        wet = wet[~same]
        if wet.size == 0:
            return u, 1
    cs = (
        stresses.columns(h, wet, rest, yield_gravity)
        if compiled is None
        else compiled.coefficients(h, wet, rest, yield_gravity)
    )
    per_dt = 1.0 / dt  # m/dt and m u*/dt as products with 1/dt, the compiled kernels' bits
    inertia, momentum = cs.m * per_dt, cs.m * ustar[:, wet] * per_dt
    concave = concave_laws((stresses.bulk, stresses.walls), stresses.material)
    current = u_guess[:, wet]
    at_current = stresses.viscous_stresses(cs, current)
    todo = np.arange(wet.size)  # wet columns still iterating
    # a guess at rest at the bed and the surface within the error bound is the answer
    resting = np.flatnonzero((current[0] == 0.0) & (current[-1] == 0.0) & (inertia[0] > 0.0))
    if resting.size:
        cols = (slice(None), resting)
        at = current[cols]
        bound, _ = examine_columns(
            inertia[cols], momentum[cols], cs.kappa[cols], at_current[0][cols], cs.w[cols],
            at_current[2][cols], at, at, at_current[:, :, resting], concave,
        )  # fmt: skip
        todo = np.setdiff1d(todo, resting[bound <= threshold])
        if todo.size == 0:
            u[:, wet] = current
            return u, 1
    for iteration in range(1, max_iterations + 1):
        if poll is not None:
            poll()
        cols = (slice(None), todo)
        problem = stresses.linearise(cs, current, ustar[:, wet], dt).columns(todo)
        new = solver(problem, guess=current[cols], threads=threads, poll=poll)
        trial = current.copy()
        trial[cols] = new
        at_new = stresses.viscous_stresses(cs, trial)  # (like linearise, every column)
        bound, rise = examine_columns(
            inertia[cols], momentum[cols], cs.kappa[cols], at_new[0][cols], cs.w[cols], at_new[2][cols],
            current[cols], new, at_current[:, :, todo], concave,
        )  # fmt: skip
        change = np.max(np.abs(new - current[cols]), axis=0)
        done = (bound <= threshold) | (change <= threshold)
        full = done | (rise <= 0.0)
        current[:, todo[full]] = new[:, full]
        at_current[:, :, todo[full]] = at_new[:, :, todo[full]]
        if not full.all():
            damped = todo[~full]
            current[:, damped] = _line_search(
                stresses, cs, inertia, momentum, current, new[:, ~full], damped, threshold
            )
            at_current[:, :, damped] = stresses.viscous_stresses(cs, current)[:, :, damped]
        todo = todo[~done]
        if todo.size == 0:
            u[:, wet] = current
            return u, iteration
    raise _not_converged(tolerance, max_iterations, todo.size)


def _line_search(
    stresses: StressModel,
    cs: ColumnStresses,
    inertia: np.ndarray,
    momentum: np.ndarray,
    current: np.ndarray,
    new: np.ndarray,
    damped: np.ndarray,
    threshold: float,
) -> np.ndarray:
    """The damped step of the columns ``damped`` from ``current`` towards the Newton model's
    minimisers ``new`` (L, n): the minimiser of the convex ``phi(t) = E(u0 + t d)`` on
    [0, 1], by bisection on the sign of ``phi'(t+)`` (``newton_control``)."""
    cols = (slice(None), damped)
    start = current[cols]
    d = new - start
    size = np.max(np.abs(d), axis=0)
    lo, hi = np.zeros(damped.size), np.ones(damped.size)
    trial = current.copy()
    for _ in range(HALVINGS):
        open_ = (hi - lo) * size > threshold
        if not open_.any():
            break
        mid = 0.5 * (lo + hi)
        trial[cols] = start + mid * d
        at = stresses.viscous_stresses(cs, trial)
        up = slopes_along(
            inertia[cols], momentum[cols], cs.kappa[cols], at[0][cols], cs.w[cols], at[2][cols],
            start, new, trial[cols], 1.0,
        ) >= 0.0  # fmt: skip
        hi = np.where(open_ & up, mid, hi)
        lo = np.where(open_ & ~up, mid, lo)
    return start + np.where(lo > 0.0, lo, hi) * d


def _not_converged(tolerance: float, max_iterations: int, columns: int) -> NotConverged:
    return NotConverged(
        f"the viscous (Newton) iteration of the vertical step did not reach tolerance "
        f"{tolerance:g} in {max_iterations} iterations in {columns} column(s); "
        "raise numerics.max_iterations or numerics.tolerance"
    )
