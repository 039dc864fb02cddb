"""The map of the mixture's local step, its value at a trial (:class:`Evaluation`), and its
compiled form in columns of one layer under the built-in dilatant law: what
:meth:`~multilayer.engine.mixture.local_step.LocalStep._newton` evaluates at a trial ``X =
(p_e, z)`` (docs/mixture.md, "The mixture in x and in layers"), one column at a time, and
the Newton iteration that evaluates it (:func:`iterate_one_layer`).

The numpy evaluation in ``local_step`` is the reference: for a column of one layer, the
yield stress and viscosity of the law at the effective pressure ``p_s = P - p_e`` at the
thickness ``h = h* / z`` (the dilatant law of Bouchut, Fernández-Nieto, Mangeney &
Narbona-Reina 2016: ``kappa = max(tan(delta) + K (phi - phi_c), 0) max(p_s, 0)``, ``eta =
(K1 + K K2) eta_f``), the exact column solve (``engine/vertical/column_solve``), the
closure's quadratic (Bouchut et al. 2016; with a compressibility, one backward-Euler step
of the relaxation of George & Iverson 2014) and the residual.  The kernel does the same
operations in the same order, so its values are those of the reference bit for bit
(tests/test_mixture_kernel.py).  Wherever the reference would do anything but return
numbers (a trial pore pressure not finite or a ratio ``z`` no thickness with pores has,
a law value outside the plugin contract, coefficients the column solve refuses, a
closure that overflows) the kernel stops and says so: the reference then evaluates the
trial, with its marks and its messages.  The compiled iteration does the reference
iteration's operations column by column (the columns of a batch are independent: a
column's iterates, marks and count of iterations are the same alone as in its batch) with
the elimination of ``newton_system`` for its 2 x 2 Newton systems (:func:`solve_2x2`), and
hands the whole step back to the reference wherever it would not simply go on (a trial the
map hands back, a Jacobian not finite or singular).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from multilayer.engine.compiled import jit
from multilayer.engine.mixture.newton_system import TINY
from multilayer.engine.plugin_output import declared_form
from multilayer.engine.vertical.column_solve import _active_set, _dynamic_programme, _workspace
from multilayer.engine.vertical.forms import describes

MIXTURE_FORMS = {"dilatant": 2}
"""The compiled forms of a law in a mixture (``Rheology.mixture_kernel``, docs/plugins.md) and
their numbers of parameters: ``dilatant``, ``(tan(delta), K1)``, the law of Bouchut et al.
(2016) at the effective pressure, ``max(tan(delta) + K (phi - phi_c), 0) max(p_s, 0)`` and
``(K1 + K K2) eta_f``."""


def mixture_form(law: Any, material: Any, config: Any) -> tuple[float, float] | None:
    """``(tan(delta), eta)`` of a law whose mixture methods are the compiled ``dilatant``
    form (:data:`MIXTURE_FORMS`), with the constants ``K``, ``K2`` and ``eta_f`` of the
    mixture ``config``; None for a law without it, or whose class (or instance) redefines
    ``mixture_yield_stress`` or ``mixture_viscosity`` below the class that declares it, or
    whose coefficients are not finite numbers >= 0 (the plugin contract, which the numpy
    path then checks, naming the law): such laws run on the numpy path.  A known form with
    another number of parameters stops the run naming the law (``declared_form``)."""
    if not describes(law, "mixture_kernel", ("mixture_yield_stress", "mixture_viscosity")):
        return None
    declared = declared_form(law, "mixture_kernel", material, MIXTURE_FORMS)
    if declared is None:
        return None
    tan_delta, K1 = (float(value) for value in declared[1])
    eta = (K1 + config.dilatancy * config.critical_shift) * config.fluid_viscosity
    if not (math.isfinite(tan_delta) and math.isfinite(eta) and eta >= 0.0):
        return None
    return tan_delta, eta


class Evaluation(NamedTuple):
    """The local step's map at a trial ``X`` in some columns."""

    v: np.ndarray  # (L, k) velocities of the column solve
    rates: np.ndarray  # (L, k) interface shear rates
    pressure: np.ndarray  # (L, k) excess pore pressures of the closure at these velocities
    h: np.ndarray  # (k,) thickness of the dilation at these velocities
    dilation: np.ndarray  # (L, k) dilation rates of the closure at these velocities
    residual: np.ndarray  # (L + 1, k) X minus what it produces, scaled
    norm: np.ndarray  # (k,) largest scaled component of the residual

    @staticmethod
    def diverged(X: np.ndarray) -> Evaluation:
        """At trials ``X`` (L + 1, k) the step cannot evaluate (not finite, or whose closure
        fails): no velocities, an infinite residual."""
        L, k = X.shape[0] - 1, X.shape[1]
        residual = np.full(X.shape, np.inf)
        blank = np.zeros((L, k))
        return Evaluation(blank, blank, X[:L], residual[L], blank, residual, residual[0])

    @staticmethod
    def join(parts: list[Evaluation]) -> Evaluation:
        """The evaluations ``parts`` of consecutive columns side by side."""
        return Evaluation(*(np.concatenate(fields, axis=-1) for fields in zip(*parts)))

    def take(self, k: np.ndarray) -> Evaluation:
        """This evaluation in the columns ``k`` only."""
        return Evaluation(*(part[..., k] for part in self))

    def merge(self, k: np.ndarray, other: Evaluation) -> Evaluation:
        """This evaluation with the columns ``k`` replaced by ``other``'s."""
        parts = []
        for mine, theirs in zip(self, other):
            mine = mine.copy()
            mine[..., k] = theirs
            parts.append(mine)
        return Evaluation(*parts)


class CompiledStep(NamedTuple):
    """The compiled local step of some columns: its map (:func:`one_layer`) and its Newton
    iteration (:func:`iterate_one_layer`), each None where the reference must do the work."""

    map: Callable[[np.ndarray, np.ndarray, np.ndarray], Evaluation | None]
    iterate: Callable[[np.ndarray, Evaluation, np.ndarray], tuple[Evaluation, int] | None]


def compiled_step(
    local: Any,
    given: tuple[np.ndarray, ...],
    scale: np.ndarray,
    pores: np.ndarray,
    dt: float,
    lag: float,
    previous: np.ndarray | None,
    controls: tuple[float, ...],
) -> CompiledStep | None:
    """The compiled step of the local step ``local`` (a
    :class:`~multilayer.engine.mixture.local_step.LocalStep` of a law of a compiled form,
    :func:`mixture_form`) in columns of one layer, None for other columns or laws.  Its map:
    at the trials ``X`` (2, len(k)) of the columns ``k`` from the velocities ``guess`` (1, n),
    the evaluation of the reference, bit for bit, or None where the reference must evaluate
    them itself (a trial it marks diverged or outside, a value it refuses: :func:`one_layer`).
    Its iteration: from the trials ``X`` (2, n) of every column, their evaluation and the
    columns marked diverged (n,), the reference's Newton iteration, bit for bit: the
    evaluation it ends at and its count of iterations (``diverged`` updated), or None
    (nothing changed) where the reference must iterate itself (:func:`iterate_one_layer`).
    ``given``: ``h*`` (n,), the solid, its buoyant weight, the masses and momenta before the
    step (1, n); ``previous`` (1, n) the pore pressure a compressibility relaxes from, ``lag =
    alpha / dt``; ``scale`` (2, n) and ``pores`` (n,) as in ``LocalStep._newton``;
    ``controls`` those of :func:`iterate_one_layer`."""
    if local.form is None or local.l.shape[0] != 1:
        return None
    cfg, (tan_delta, eta), relaxing = local.config, local.form, previous is not None
    constants = np.array(
        [
            dt, local.l[0, 0], local.spacing[0, 0], local.rho_s, local.rho_f, cfg.dilatancy, cfg.phi_critical,
            cfg.dilatancy * cfg.critical_shift * cfg.fluid_viscosity, cfg.kozeny * cfg.fluid_viscosity,
            local.material.grain_diameter, tan_delta, eta, lag, float(relaxing),
        ],
        dtype=float,
    )  # fmt: skip
    h_star, *layer = given
    arrays = (
        np.ascontiguousarray(h_star, dtype=float),
        *(np.ascontiguousarray(a[0], dtype=float) for a in layer),
    )
    start = np.ascontiguousarray(np.zeros(h_star.size) if previous is None else previous[0], dtype=float)
    scales, bounds = np.ascontiguousarray(scale, dtype=float), np.ascontiguousarray(pores, dtype=float)
    settings = np.array(controls, dtype=float)

    def evaluate(X: np.ndarray, k: np.ndarray, guess: np.ndarray) -> Evaluation | None:
        out = np.empty((8, k.size))
        trial, columns = np.ascontiguousarray(X, dtype=float), np.ascontiguousarray(k, dtype=np.int64)
        velocities = np.ascontiguousarray(guess[0], dtype=float)
        if not one_layer(trial, columns, *arrays, velocities, start, scales, bounds, constants, out):
            return None
        return _evaluation(out)

    def iterate(X: np.ndarray, now: Evaluation, diverged: np.ndarray) -> tuple[Evaluation, int] | None:
        trials, marks = np.array(X, dtype=float), diverged.copy()
        out = np.ascontiguousarray(
            np.concatenate(
                [now.v, now.rates, now.pressure, now.h[None], now.dilation, now.residual, now.norm[None]]
            )
        )
        iterations = iterate_one_layer(trials, out, marks, arrays, start, scales, bounds, constants, settings)
        if iterations < 0:
            return None
        diverged[:] = marks
        return _evaluation(out), int(iterations)

    return CompiledStep(evaluate, iterate)


def _evaluation(out: np.ndarray) -> Evaluation:
    """The evaluation whose rows (8, k) the kernels wrote (:func:`one_layer`)."""
    return Evaluation(out[0:1], out[1:2], out[2:3], out[3], out[4:5], out[5:7], out[7])


@jit(inline="always")
def _finite(value):
    """True if ``value`` is a finite number (a NaN fails)."""
    return value * 0.0 == 0.0


@jit(inline="always")
def _positive_part(value):
    """``numpy.maximum(value, 0.0)`` (a NaN stays NaN and -0.0 gives +0.0, as in numpy)."""
    return value if (value > 0.0 or value != value) else 0.0


OK, BURST, OUTSIDE, REFUSED = 0, 1, 2, 3
"""What the compiled map made of a trial in one column: its evaluation, a trial pore pressure
not finite or a ratio ``z`` no thickness with pores has (the reference's blank evaluation,
the first marked diverged), or a value the reference must evaluate itself."""


@jit(inline="always")
def _scratch():
    """The work arrays of the column solve of one layer (``engine/vertical/column_solve``)."""
    return (
        _workspace(1), np.empty(2, np.int64), np.empty(1, np.bool_), np.empty(1), np.empty(1), np.empty(1),
        np.empty(1), np.empty(2, np.int64), np.empty(1), np.empty(1), np.empty(1), np.empty(1), np.zeros(1),
        np.empty(1), np.empty(1),
    )  # fmt: skip


@jit
def _column(p, z, j, given, guess, previous, scale, pores, constants, work, out):
    """The map at the trial ``(p, z)`` of column ``j`` from the velocity ``guess`` (the
    arguments of :func:`one_layer`, ``given`` its ``h_star``, ``solid``, ``weight``,
    ``m_before`` and ``momentum``, ``work`` its :func:`_scratch`): :data:`OK` with the
    velocity, shear rate, pore pressure, thickness, dilation rate, the two residuals and
    their norm in ``out`` (8,), or what stopped it (:data:`BURST`, :data:`OUTSIDE`,
    :data:`REFUSED`; ``out`` then unwritten)."""
    dt, l, spacing, rho_s, rho_f = constants[0], constants[1], constants[2], constants[3], constants[4]
    K, phi_c, viscous, kozeny_eta, d = constants[5], constants[6], constants[7], constants[8], constants[9]
    tan_delta, eta, lag = constants[10], constants[11], constants[12]
    relaxing = constants[13] != 0.0
    h_star, solid, weight, m_before, momentum = given
    ws, first, grounded, U, diag, low, rhs, hint, inertia, inflow, kappa, c, free, u, start = work
    if not (_finite(dt) and dt > 0.0):
        return REFUSED
    if not _finite(p):
        return BURST
    if not (z > 0.0 and z < pores[j]):
        return OUTSIDE
    h = h_star[j] / z
    s = solid[j]
    p_s = weight[j] - p
    thickness = l * h
    phi = s / thickness
    kappa[0] = _positive_part(tan_delta + K * (phi - phi_c)) * _positive_part(p_s)
    m = 0.5 * (m_before[j] + (rho_s * s + rho_f * (l * h - s)))
    ustar = momentum[j] / m
    c[0] = eta / (spacing * h)
    if not (_finite(kappa[0]) and _finite(m) and _finite(ustar) and _finite(c[0])):
        return REFUSED
    if m <= 0.0:
        u[0] = 0.0
    else:
        inertia[0] = m * (1.0 / dt)
        inflow[0] = m * ustar * (1.0 / dt)
        start[0] = guess
        if not _active_set(
            inertia, inflow, kappa, c, free, free, start, u, first, grounded, U, diag, low, rhs, hint
        ):
            _dynamic_programme(inertia, inflow, kappa, c, free, free, u, ws)
    v = u[0]
    if not _finite(v):
        return REFUSED
    # the closure (LocalStep.closure, LocalStep.darcy) of one layer
    gamma = abs(v - 0.0) / (spacing * h)
    beta = kozeny_eta * phi * phi / (d * d * (1.0 - phi))
    M = spacing * h * (beta / ((1.0 - phi) * (1.0 - phi)) * thickness)
    darcy, base = M, weight[j]
    if relaxing:
        ratio = lag * M
        M = M / (1.0 + ratio)
        base = weight[j] - previous[j] * ratio / (1.0 + ratio)
    linear = gamma * K * (phi - phi_c)
    C = viscous * gamma * gamma
    A = base + (0.0 + M * linear)
    root = np.sqrt(A * A + 4.0 * M * C)
    if A >= 0.0:
        positive = 0.5 * (A + root)
    else:
        positive = 2.0 * M * C / (root - A if root - A > 0.0 else 1.0)
    p_s = positive if M * C > 0.0 else _positive_part(A)
    if not _finite(p_s):
        return REFUSED
    dilation = linear + (C / p_s if p_s > 0.0 else 0.0)
    pressure = weight[j] - p_s
    if relaxing:  # the Darcy outflow of one relaxing layer
        dilation = -pressure / darcy
    growth = 1.0 - dt * (l * dilation)
    r0 = (p - pressure) / scale[0, j]
    r1 = (z - growth) / scale[1, j]
    r0 = r0 if _finite(r0) else np.inf
    r1 = r1 if _finite(r1) else np.inf
    out[0], out[1], out[2] = v, gamma, pressure
    out[3] = h_star[j] / growth if growth > 0.0 else np.inf
    out[4], out[5], out[6] = dilation, r0, r1
    out[7] = max(abs(r0), abs(r1))
    return OK


@jit
def one_layer(X, k, h_star, solid, weight, m_before, momentum, guess, previous, scale, pores, constants, out):
    """The map of the local step at the trials ``X`` (2, len(k)) of the columns ``k`` of one
    layer: ``h_star``, ``solid``, ``weight`` (its buoyant weight ``P``), ``m_before``,
    ``momentum`` and the velocity ``guess`` (n,), ``previous`` (n,) the pore pressure a
    compressibility relaxes from, ``scale`` (2, n) the residual's scales and ``pores`` (n,)
    the ratio's bound.  ``constants``: ``dt``, ``l``, ``spacing``, ``rho_s``, ``rho_f``,
    ``K``, ``phi_c``, ``K K2 eta_f``, ``kozeny eta_f``, ``d``, ``tan(delta)``, ``eta``,
    ``lag`` (``alpha / dt``) and ``relaxing`` (1.0 or 0.0: with a compressibility, whose
    one layer drains, ``local_step`` Notes).  Writes the rows
    velocity, shear rate, pore pressure, thickness, dilation rate, the two residuals and
    their norm of ``out`` (8, len(k)); False (the rest of ``out`` unwritten) at the first
    column the reference would not simply evaluate (module docstring)."""
    work, found, given = _scratch(), np.empty(8), (h_star, solid, weight, m_before, momentum)
    for i in range(k.size):
        j = k[i]
        if (
            _column(X[0, i], X[1, i], j, given, guess[j], previous, scale, pores, constants, work, found)
            != OK
        ):
            return False
        out[:, i] = found
    return True


@jit
def solve_2x2(a00, a01, a10, a11, b0, b1):
    """``(solved, x0, x1)``: the solution of ``[[a00, a01], [a10, a11]] x = b`` by the
    elimination with partial pivoting of ``newton_system.solve_pairs``, the same operations in
    the same order (the same bits); not solved where a pivot is zero."""
    if abs(a10) > abs(a00):
        a00, a01, a10, a11, b0, b1 = a10, a11, a00, a01, b1, b0
    if a00 == 0.0:
        return False, 0.0, 0.0
    multiplier = a10 * (1.0 / a00) if abs(a00) >= TINY else a10 / a00
    a11 = a11 - multiplier * a01
    if a11 == 0.0:
        return False, 0.0, 0.0
    x1 = (b1 - multiplier * b0) / a11
    return True, (b0 - a01 * x1) / a00, x1


@jit
def _trial(p, z, j, given, guess, previous, scale, pores, constants, work, out):
    """:func:`_column`, the reference's blank evaluation at a trial it marks diverged or
    outside (``Evaluation.diverged``): what :func:`_column` returned."""
    found = _column(p, z, j, given, guess, previous, scale, pores, constants, work, out)
    if found == BURST or found == OUTSIDE:
        out[0], out[1], out[2], out[3], out[4] = 0.0, 0.0, p, np.inf, 0.0
        out[5], out[6], out[7] = np.inf, np.inf, np.inf
    return found


@jit
def iterate_one_layer(X, now, diverged, given, previous, scale, pores, constants, controls):
    """The Newton iteration of ``LocalStep._newton`` in the columns of one layer, each on its
    own, from the trials ``X`` (2, n) and their evaluations ``now`` (8, n; the rows of
    :func:`one_layer`'s ``out``), ``diverged`` (n,) the columns marked so far; ``given`` the
    arrays ``h_star``, ``solid``, ``weight``, ``m_before`` and ``momentum`` of
    :func:`one_layer`.  ``controls``: the tolerance, ``numerics.max_iterations``, the
    relative increment of the finite differences, the halvings of the line search, the
    bisections, expansions and sweeps of the bracketing and the window of a wandering
    iteration (``local_step``).  Updates ``X``, ``now`` and ``diverged`` as the reference's
    iteration does (the columns of a batch are independent: the reference's iteration of a
    column does the same operations on its own) and returns the reference's count of
    iterations, or -1 (``X``, ``now``, ``diverged`` partly updated) where the reference would
    do anything but these operations: a trial it evaluates itself (:data:`REFUSED`), a
    Jacobian not finite or singular (its least-squares solution), a finite-difference step
    not finite."""
    tolerance, max_iterations, relative = controls[0], controls[1], controls[2]
    halvings, bisections, expansions = int(controls[3]), int(controls[4]), int(controls[5])
    sweeps, window = int(controls[6]), controls[7]
    weight = given[2]
    work, here, attempt, probe = _scratch(), np.empty(8), np.empty(8), np.empty(8)
    most = 0
    for j in range(X.shape[1]):
        x0, x1 = X[0, j], X[1, j]
        here[:] = now[:, j]
        best, since, passes = here[7], 0, 0
        burst = diverged[j]
        while not (here[7] <= tolerance) and not burst and passes < max_iterations:
            passes += 1
            guess = here[0]
            # the Jacobian by finite differences, one column solve per unknown
            step0 = relative * max(abs(x0), scale[0, j])
            step1 = relative * max(abs(x1), scale[1, j])
            if not (_finite(step0) and _finite(step1)):
                return -1
            found = _trial(x0 + step0, x1, j, given, guess, previous, scale, pores, constants, work, probe)
            if found == REFUSED:
                return -1
            burst = burst or found == BURST
            a00, a10 = (probe[5] - here[5]) / step0, (probe[6] - here[6]) / step0
            found = _trial(x0, x1 + step1, j, given, guess, previous, scale, pores, constants, work, probe)
            if found == REFUSED:
                return -1
            burst = burst or found == BURST
            a01, a11 = (probe[5] - here[5]) / step1, (probe[6] - here[6]) / step1
            b0, b1 = -here[5], -here[6]
            if not (
                _finite(a00)
                and _finite(a01)
                and _finite(a10)
                and _finite(a11)
                and _finite(b0)
                and _finite(b1)
            ):
                return -1
            solved, u0, u1 = solve_2x2(a00, a01, a10, a11, b0, b1)
            if not solved:
                return -1
            # the backtracking line search
            fraction, better, t0, t1 = 1.0, False, x0, x1
            for _ in range(halvings):
                t0, t1 = x0 + fraction * u0, x1 + fraction * u1
                found = _trial(t0, t1, j, given, guess, previous, scale, pores, constants, work, attempt)
                if found == REFUSED:
                    return -1
                burst = burst or found == BURST
                better = attempt[7] < here[7] or attempt[7] <= tolerance
                if better:
                    break
                fraction = 0.5 * fraction
            if not better and not burst:  # no descent: the pore pressure bracketed (LocalStep._bisect)
                t0, t1, bed = x0, x1, weight[j]
                for _ in range(sweeps):
                    found = _trial(t0, t1, j, given, guess, previous, scale, pores, constants, work, probe)
                    if found == REFUSED:
                        return -1
                    burst = burst or found == BURST
                    held = probe[5] < 0.0  # below the root: the bracket is [t0, P]
                    low = t0 if held else t0 - bed
                    high = bed if held else t0
                    for stage in range(expansions + bisections):  # down until it holds, then halved
                        expanding = stage < expansions
                        if expanding and held:
                            continue
                        point = low if expanding else 0.5 * (low + high)
                        found = _trial(
                            point, t1, j, given, guess, previous, scale, pores, constants, work, probe
                        )
                        if found == REFUSED:
                            return -1
                        burst = burst or found == BURST
                        negative = probe[5] < 0.0
                        if expanding:
                            held = negative
                            low = low if negative else low - 2.0 * (high - low)
                        elif negative:
                            low = point
                        else:
                            high = point
                    t0 = high
                found = _trial(t0, t1, j, given, guess, previous, scale, pores, constants, work, attempt)
                if found == REFUSED:
                    return -1
                burst = burst or found == BURST
            # back where it started, bit for bit: the iteration would repeat itself
            stalled = t0 == x0 and t1 == x1 and attempt[0] == here[0] and attempt[1] == here[1]
            x0, x1 = t0, t1
            here[:] = attempt
            since = 0 if here[7] < best else since + 1
            best = min(best, here[7])
            if stalled or since >= window:
                break
        X[0, j], X[1, j] = x0, x1
        now[:, j] = here
        diverged[j] = burst
        most = max(most, passes)
    return 1 + most
