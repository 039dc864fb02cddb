"""The map of the mixture's local step, its value at a trial (:class:`Evaluation`), and its
compiled form in columns of one layer under the built-in dilatant law: what
:meth:`~multilayer.engine.mixture.local_step.LocalStep._newton` evaluates at a trial ``X =
(p_e, z)`` (docs/mixture.md, "The mixture in x and in layers"), one column at a time.

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
trial, with its marks and its messages.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from multilayer.engine.compiled import jit
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


def compiled_map(
    local: Any,
    given: tuple[np.ndarray, ...],
    scale: np.ndarray,
    pores: np.ndarray,
    dt: float,
    lag: float,
    previous: np.ndarray | None,
) -> Callable[[np.ndarray, np.ndarray, np.ndarray], Evaluation | None] | None:
    """The compiled map of the local step ``local`` (a
    :class:`~multilayer.engine.mixture.local_step.LocalStep` of a law of a compiled form,
    :func:`mixture_form`) in columns of one layer, None for other columns or laws: at the
    trials ``X`` (2, len(k)) of the columns ``k`` from the velocities ``guess`` (1, n), the
    evaluation of the reference, bit for bit, or None where the reference must evaluate
    them itself (a trial it marks diverged or outside, a value it refuses: :func:`one_layer`).
    ``given``: ``h*`` (n,), the solid, its buoyant weight, the masses and momenta before the
    step (1, n); ``previous`` (1, n) the pore pressure a compressibility relaxes from, ``lag =
    alpha / dt``; ``scale`` (2, n) and ``pores`` (n,) as in ``LocalStep._newton``."""
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
    arrays = [
        np.ascontiguousarray(h_star, dtype=float),
        *(np.ascontiguousarray(a[0], dtype=float) for a in layer),
    ]
    start = np.ascontiguousarray(np.zeros(h_star.size) if previous is None else previous[0], dtype=float)
    scales, bounds = np.ascontiguousarray(scale, dtype=float), np.ascontiguousarray(pores, dtype=float)

    def evaluate(X: np.ndarray, k: np.ndarray, guess: np.ndarray) -> Evaluation | None:
        out = np.empty((8, k.size))
        trial, columns = np.ascontiguousarray(X, dtype=float), np.ascontiguousarray(k, dtype=np.int64)
        velocities = np.ascontiguousarray(guess[0], dtype=float)
        if not one_layer(trial, columns, *arrays, velocities, start, scales, bounds, constants, out):
            return None
        return Evaluation(out[0:1], out[1:2], out[2:3], out[3], out[4:5], out[5:7], out[7])

    return evaluate


@jit(inline="always")
def _finite(value):
    """True if ``value`` is a finite number (a NaN fails)."""
    return value * 0.0 == 0.0


@jit(inline="always")
def _positive_part(value):
    """``numpy.maximum(value, 0.0)`` (a NaN stays NaN and -0.0 gives +0.0, as in numpy)."""
    return value if (value > 0.0 or value != value) else 0.0


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
    dt, l, spacing, rho_s, rho_f = constants[0], constants[1], constants[2], constants[3], constants[4]
    K, phi_c, viscous, kozeny_eta, d = constants[5], constants[6], constants[7], constants[8], constants[9]
    tan_delta, eta, lag = constants[10], constants[11], constants[12]
    relaxing = constants[13] != 0.0
    if not (_finite(dt) and dt > 0.0):
        return False
    ws = _workspace(1)
    first = np.empty(2, np.int64)
    grounded = np.empty(1, np.bool_)
    U, diag, low, rhs = np.empty(1), np.empty(1), np.empty(1), np.empty(1)
    hint = np.empty(2, np.int64)
    inertia, inflow = np.empty(1), np.empty(1)
    kappa, c, free, u, start = np.empty(1), np.empty(1), np.zeros(1), np.empty(1), np.empty(1)
    per_dt = 1.0 / dt
    for i in range(k.size):
        j = k[i]
        p, z = X[0, i], X[1, i]
        if not (_finite(p) and z > 0.0 and z < pores[j]):
            return False
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
            return False
        if m <= 0.0:
            u[0] = 0.0
        else:
            inertia[0] = m * per_dt
            inflow[0] = m * ustar * per_dt
            start[0] = guess[j]
            if not _active_set(
                inertia, inflow, kappa, c, free, free, start, u, first, grounded, U, diag, low, rhs, hint
            ):
                _dynamic_programme(inertia, inflow, kappa, c, free, free, u, ws)
        v = u[0]
        if not _finite(v):
            return False
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
            return False
        dilation = linear + (C / p_s if p_s > 0.0 else 0.0)
        pressure = weight[j] - p_s
        if relaxing:  # the Darcy outflow of one relaxing layer
            dilation = -pressure / darcy
        growth = 1.0 - dt * (l * dilation)
        r0 = (p - pressure) / scale[0, j]
        r1 = (z - growth) / scale[1, j]
        r0 = r0 if _finite(r0) else np.inf
        r1 = r1 if _finite(r1) else np.inf
        out[0, i], out[1, i], out[2, i] = v, gamma, pressure
        out[3, i] = h_star[j] / growth if growth > 0.0 else np.inf
        out[4, i], out[5, i], out[6, i] = dilation, r0, r1
        out[7, i] = max(abs(r0), abs(r1))
    return True
