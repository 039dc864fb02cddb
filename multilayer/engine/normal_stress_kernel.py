"""The compiled normal-stress step: :func:`chain_step`, the projected Newton method of
:func:`multilayer.engine.normal_stress.plastic_chain_step` (its numpy reference, the
algorithm documented there: Bertsekas 1982, SIAM J. Control Optim. 20, 221) in one numba
kernel, with the constants both use.

The tridiagonal Newton systems are solved by the Thomas algorithm (elimination without
pivoting: the Hessian is symmetric positive definite, the fixed faces' rows the identity);
the sums over faces and cells run in index order (the reference's numpy sums pairwise), so
the two agree to round-off, not bit for bit.
"""

from __future__ import annotations

import numpy as np

from multilayer.engine.compiled import jit

TURN = 0.5
"""The largest change of an angle ``phi_f`` in one Newton step (rad): far from its optimum
the dual objective is not convex in ``phi_f`` (each angle's step is cut to it, or, where that
would not descend, the whole step scaled)."""


STALL = 0.01
"""A step that moves no velocity by more than this fraction of its Newton step's largest
change has stalled (the path met a bound of a plastic face the Newton step would take
across): the next iteration tries the scaled gradient step first."""


ROUNDING = 100.0
"""The round-off of a velocity ``u_i = u*_i + (Z_(i+1/2) - Z_(i-1/2)) / M_i`` in units of the
machine epsilon times its terms: below it the iteration cannot go."""


NODES, WEIGHTS = np.polynomial.legendre.leggauss(16)
"""Gauss-Legendre rule of the dual term's change (``normal_stress.barrier_change``): its
integrand is analytic, its nearest poles ``sin(phi) = -1/e`` at ``acosh(1/|e|)`` from the real
axis (error below 1e-15 of the integral of its absolute value for ``|e| <= 0.8``, below 1e-12
at 0.9, on changes up to :data:`TURN`: tested)."""


HALF_PI = 0.5 * np.pi
EPSILON = float(np.finfo(float).eps)

CONVERGED, NOT_CONVERGED = -1, -2
"""What :func:`chain_step` returns when it converged or did not within its iterations; a face
index ``>= 0`` is the first face whose Newton step is not finite (a zero pivot)."""


@jit(error_model="numpy")
def _barrier_change(start: float, end: float, e: float) -> float:
    """The integral of ``sin(phi) / (1 + e sin(phi))^2`` from ``start`` to ``end``
    (:data:`NODES`, :data:`WEIGHTS`)."""
    half = 0.5 * (end - start)
    middle = 0.5 * (end + start)
    total = 0.0
    for q in range(NODES.size):
        sin = np.sin(middle + half * NODES[q])
        total += WEIGHTS[q] * sin / (1.0 + e * sin) ** 2
    return half * total


@jit(error_model="numpy")
def _gradient(v, s, a, b, e, smooth, jacobian, g):
    """``dZ/dv`` into ``jacobian`` and the dual gradient into ``g`` at the angles or impulses
    ``v`` and face velocity jumps ``s``."""
    for f in range(v.size):
        if smooth[f]:
            sin = np.sin(v[f])
            denominator = 1.0 + e[f] * sin
            jacobian[f] = a[f] * (np.cos(v[f]) / denominator**2)
            g[f] = -s[f] * jacobian[f] + a[f] * b[f] * (sin / denominator**2)
        else:
            jacobian[f] = 1.0
            g[f] = -s[f]


@jit(error_model="numpy")
def _change(dz, left, right, inv, du):
    """The velocities' change ``du`` of the impulses' change ``dz``."""
    du[:] = 0.0
    for f in range(dz.size):
        du[left[f]] += dz[f] * inv[left[f]]
        du[right[f]] -= dz[f] * inv[right[f]]


@jit(error_model="numpy")
def _newton_step(fixed, moves, g, diagonal, coupling, upper, rhs, step):
    """The Newton step ``step`` of the tridiagonal Hessian (``diagonal``, ``coupling`` of each
    face with the next) and gradient ``g``, the faces ``fixed`` moved by ``moves`` (their rows
    the identity, their columns eliminated), by the Thomas algorithm."""
    k = g.size
    for f in range(k):
        rhs[f] = moves[f] if fixed[f] else -g[f]
    for f in range(k - 1):
        if fixed[f] and not fixed[f + 1]:
            rhs[f + 1] -= coupling[f] * moves[f]
        if fixed[f + 1] and not fixed[f]:
            rhs[f] -= coupling[f] * moves[f + 1]
    pivot = 1.0
    for f in range(k):
        pivot = 1.0 if fixed[f] else diagonal[f]
        if f > 0:
            lower = 0.0 if fixed[f - 1] or fixed[f] else coupling[f - 1]
            pivot -= lower * upper[f - 1]
            rhs[f] -= lower * rhs[f - 1]
        rhs[f] /= pivot
        if f < k - 1:
            upper[f] = (0.0 if fixed[f] or fixed[f + 1] else coupling[f]) / pivot
    for f in range(k - 1, -1, -1):
        step[f] = rhs[f] - (upper[f] * step[f + 1] if f < k - 1 else 0.0)


@jit(error_model="numpy")
def _first_not_finite(values):
    """The index of the first value that is not finite, -1 if none."""
    for f in range(values.size):
        if not np.isfinite(values[f]):
            return f
    return -1


@jit(error_model="numpy")
def _turned(step, g, smooth, out):
    """``step`` with each angle's change cut to :data:`TURN`, or scaled as a whole where that
    would not descend along ``g``, into ``out``."""
    slope = 0.0
    largest = 0.0
    for f in range(step.size):
        out[f] = min(max(step[f], -TURN), TURN) if smooth[f] else step[f]
        slope += g[f] * out[f]
        if smooth[f]:
            largest = max(largest, abs(step[f]))
    if slope < 0.0:
        return
    largest = max(TURN, largest)
    for f in range(step.size):
        out[f] = step[f] * TURN / largest


@jit(error_model="numpy")
def _search(v, z, u, step, mass, inv, left, right, a, b, e, smooth, low, high, work, trial, z_trial, moved):
    """Backtracking on the projected path from ``v`` along ``step`` until the dual objective
    falls (or, below its round-off, until the slope along the step is not positive): True
    with the new angles or impulses, ``Z`` and ``u`` in ``trial``, ``z_trial``, ``moved``;
    False if no step does.  ``work`` holds four face arrays."""
    dz, s, jacobian, slope = work[0], work[1], work[2], work[3]
    alpha = 1.0
    while alpha >= 1e-12:
        for f in range(v.size):
            t = v[f] + alpha * step[f]
            if smooth[f]:
                t = min(max(t, -HALF_PI), HALF_PI)
                sin = np.sin(t)
                z_trial[f] = a[f] * (sin / (1.0 + e[f] * sin))
            else:
                t = min(max(t, low[f]), high[f])
                z_trial[f] = t
            trial[f] = t
            dz[f] = z_trial[f] - z[f]
        _change(dz, left, right, inv, moved)
        rise = 0.0
        for i in range(u.size):
            rise += mass[i] * moved[i] * (u[i] + 0.5 * moved[i])
            moved[i] += u[i]
        for f in range(v.size):
            s[f] = moved[right[f]] - moved[left[f]]
        _gradient(trial, s, a, b, e, smooth, jacobian, slope)
        along = 0.0
        for f in range(v.size):
            along += slope[f] * (trial[f] - v[f])
        if along <= 0.0:  # accepted whatever the rise: the dual term's change is not needed
            return True
        for f in range(v.size):
            if smooth[f]:
                rise += a[f] * b[f] * _barrier_change(v[f], trial[f], e[f])
        if rise <= 0.0:
            return True
        alpha *= 0.5
    return False


@jit(error_model="numpy")
def chain_step(ustar, mass, left, right, linked, a, b, e, tolerance, max_iterations, u, z):
    """``normal_stress.plastic_chain_step`` compiled: the velocities into ``u`` and the face
    impulses into ``z``; :data:`CONVERGED` within ``max_iterations``, :data:`NOT_CONVERGED`,
    or the first face whose Newton step is not finite (compiled with numpy's error model, as
    the other kernels: a zero pivot gives an infinity, checked here, not numba's exception)."""
    n, k = ustar.size, a.size
    inv = 1.0 / mass
    smooth = (b > 0.0) & (a > 0.0)
    low, high = -a / (1.0 - e), a / (1.0 + e)
    off = np.zeros(k)
    for f in range(k):
        if linked[f]:
            off[f] = -inv[right[f]]
    v = np.zeros(k)
    z[:] = 0.0
    u[:] = ustar
    faces = np.empty((13, k))
    s, jacobian, g, diagonal, coupling = faces[0], faces[1], faces[2], faces[3], faces[4]
    plain, step, moves, upper, rhs = faces[5], faces[6], faces[7], faces[8], faces[9]
    direction, trial, z_trial = faces[10], faces[11], faces[12]
    work = np.empty((4, k))
    active = np.empty(k, dtype=np.bool_)
    fixed = np.empty(k, dtype=np.bool_)
    cells = np.empty((3, n))
    du, held, moved = cells[0], cells[1], cells[2]
    stalled = False
    for _ in range(max_iterations):
        for f in range(k):
            s[f] = u[right[f]] - u[left[f]]
        _gradient(v, s, a, b, e, smooth, jacobian, g)
        for f in range(k):
            if smooth[f]:
                active[f] = a[f] <= 0.0
                sin = np.sin(v[f])
                cos = np.cos(v[f])
                denominator = 1.0 + e[f] * sin
                curvature = a[f] * b[f] * (cos * (1.0 - e[f] * sin) / denominator**3) + abs(
                    a[f] * s[f] * (-(sin * denominator + 2.0 * e[f] * cos**2) / denominator**3)
                )
                d = jacobian[f] ** 2 * (inv[left[f]] + inv[right[f]]) + curvature
                diagonal[f] = max(d, abs(g[f]) / TURN)
            else:
                active[f] = a[f] <= 0.0 or (z[f] >= high[f] and g[f] < 0.0) or (z[f] <= low[f] and g[f] > 0.0)
                diagonal[f] = jacobian[f] ** 2 * (inv[left[f]] + inv[right[f]])
            moves[f] = 0.0
        for f in range(k - 1):
            coupling[f] = off[f] * jacobian[f] * jacobian[f + 1]
        _newton_step(active, moves, g, diagonal, coupling, upper, rhs, plain)
        bad = _first_not_finite(plain)
        if bad >= 0:
            return bad
        held[:] = 0.0
        for f in range(k):
            held[left[f]] += abs(z[f])
            held[right[f]] += abs(z[f])
            direction[f] = jacobian[f] * plain[f]
        _change(direction, left, right, inv, du)
        converged = True
        size = 0.0
        for i in range(n):
            floor = ROUNDING * EPSILON * (held[i] * inv[i] + abs(ustar[i]))
            if abs(du[i]) > max(tolerance, floor):
                converged = False
            size = max(size, abs(du[i]))
        if converged:
            return CONVERGED
        # the plastic faces the step takes across their bounds go to them, the others solved again
        step[:] = plain
        fixed[:] = active
        while True:
            crossing = False
            for f in range(k):
                if not smooth[f] and not fixed[f] and (z[f] + step[f] > high[f] or z[f] + step[f] < low[f]):
                    crossing = True
                    fixed[f] = True
                    moves[f] = (high[f] if step[f] > 0.0 else low[f]) - z[f]
            if not crossing:
                break
            _newton_step(fixed, moves, g, diagonal, coupling, upper, rhs, step)
            bad = _first_not_finite(step)
            if bad >= 0:
                return bad
        found = False
        for tried in range(3):
            attempt = (tried + 2) % 3 if stalled else tried  # after a stalled step the gradient step first
            if attempt == 0:  # the step with the crossing faces at their bounds
                _turned(step, g, smooth, direction)
            elif attempt == 1:  # the projected Newton step
                _turned(plain, g, smooth, direction)
            else:  # a scaled gradient step
                for f in range(k):
                    moves[f] = 0.0 if active[f] else -g[f] / diagonal[f]
                _turned(moves, g, smooth, direction)
            found = _search(
                v,
                z,
                u,
                direction,
                mass,
                inv,
                left,
                right,
                a,
                b,
                e,
                smooth,
                low,
                high,
                work,
                trial,
                z_trial,
                moved,
            )
            if found:
                break
        progress = 0.0
        if found:
            for i in range(n):
                progress = max(progress, abs(moved[i] - u[i]))
            v[:] = trial
            z[:] = z_trial
            u[:] = moved
        stalled = progress < STALL * size
    return NOT_CONVERGED
