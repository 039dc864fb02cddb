"""``StressModel.columns`` compiled: the velocity-independent coefficients, column by column.

When the bulk law (and the wall law, with side walls) declare the compiled form of their
yield part (``Rheology.yield_stress_kernel``: ``kappa = mu max(p, 0)``, ``mu_static
max(p, 0)`` at rest), the masses, interface pressures and yield stresses (start/stop and
basal conditions included), wall thresholds, spacings and mean layer pressures of a
column are computed by one compiled function, :func:`column_coefficients`: column by
column into arrays kept from step to step (:class:`CompiledCoefficients`, instead of a
dozen numpy temporaries of their size per step), and inside the compiled Newton step
(``newton_kernel``), which so never stores them for the whole mesh.  The operations
are those of ``stress.StressModel.columns`` in the same order, so the coefficients are
the same bits (tests/test_stress_kernel.py).  Any value outside the plugin contract
(not finite, or negative) sends the call to ``StressModel.columns``, whose checks name
the plugin, the method, the value and where.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from multilayer.engine.compiled_forms import describes
from multilayer.engine.plugin_output import declared_form
from multilayer.engine.stress import COULOMB, NO_SLIP, ColumnStresses, StressModel


def yield_law_of(rheology, material) -> tuple[float, float] | None:
    """``(mu, mu_static)`` of a plugin's compiled yield part, None if it has none (or if
    a subclass or the instance redefines ``yield_stress`` or ``static_yield_stress``
    below the class that declares the form)."""
    if not describes(rheology, "yield_stress_kernel", ("yield_stress", "static_yield_stress")):
        return None
    declared = declared_form(rheology, "yield_stress_kernel", material, {"frictional": 2})
    if declared is None:
        return None
    mu, mu_static = declared[1]
    return float(mu), float(mu_static)


@njit(cache=True, inline="always")
def _frictional(mu, p):
    """``mu * numpy.maximum(p, 0.0)`` (a NaN pressure stays NaN and -0.0 gives +0.0, as in numpy)."""
    return mu * (p if (p > 0.0 or p != p) else 0.0)


@njit(cache=True, inline="always")
def _within_contract(value):
    """1 if ``value`` is finite and >= 0 (the plugin contract), else 0 (a NaN fails)."""
    return (value >= 0.0) & (value < np.inf)


class YieldInputs(NamedTuple):
    """What the compiled yield forms need to compute ``StressModel.columns`` of any column
    (one argument of the kernels; ``rest`` and ``yield_gravity`` are (1, 1) placeholders
    when absent)."""

    rest: np.ndarray  # (L, N) layers at rest at the start of the step
    has_rest: bool
    yield_gravity: np.ndarray  # (L, N) replaces g cos(theta) in the interface pressures
    has_yield_gravity: bool
    g_n: float
    rho: float
    l: np.ndarray  # (L,) layer fractions
    depth_interface: np.ndarray  # (L,) (h - z_k) / h
    depth_centre: np.ndarray  # (L,) depth of the layer centres / h
    spacing_fraction: np.ndarray  # (L,) h_k / h across interface k
    base_kind: np.ndarray  # (N,) NO_SLIP, COULOMB or FREE_SLIP
    base_mu: np.ndarray  # (N,) Coulomb friction of the base
    mu: float  # the frictional forms: kappa = mu max(p, 0), mu_static max(p, 0) at rest
    mu_static: float
    walls: bool
    mu_wall: float  # tau_w = mu_wall max(pbar, 0)
    wall_scale: float  # 2 / W


@njit(cache=True, inline="always")  # inlined: a call per column costs about 50 ns at L = 8
def column_coefficients(
    col, hj, rest, has_rest, yield_gravity, has_yield_gravity, g_n, rho, l, depth_interface,
    depth_centre, spacing_fraction, base_kind, base_mu, mu, mu_static, walls, mu_wall, wall_scale,
    m, kappa, w, pressure, spacing, viscous, wall_pressure,
):  # fmt: skip
    """Column ``col`` of thickness ``hj`` of ``StressModel.columns`` with the yield forms
    ``mu max(p, 0)``, ``mu_static max(p, 0)`` at rest and ``mu_wall max(pbar, 0)`` on the
    walls (the fields of :class:`YieldInputs`, unpacked once by the caller: reading an
    array out of a tuple per column would count a reference), into the (L,) arrays
    ``m ... wall_pressure``.  Returns how many yield values are outside the plugin
    contract (not finite and >= 0).

    The one source of these coefficients on the compiled paths: the arrays of
    :class:`CompiledCoefficients` and, column by column, the Newton kernel
    (``newton_kernel``), which so never stores them for the whole mesh."""
    g_p = rho * g_n
    L = l.size
    checked = good = 0  # loops without branches, so that they vectorise
    for a in range(L):
        m[a] = rho * l[a] * hj
        spacing[a] = spacing_fraction[a] * hj
        wall_pressure[a] = g_p * depth_centre[a] * hj
    for a in range(L):
        viscous[a] = True
    if has_yield_gravity:
        for a in range(L):
            pressure[a] = rho * yield_gravity[a, col] * depth_interface[a] * hj
    else:
        for a in range(L):
            pressure[a] = g_p * depth_interface[a] * hj
    checked += L
    for a in range(L):
        k = _frictional(mu, pressure[a])
        kappa[a] = k
        good += _within_contract(k)
    if has_rest:  # interface a is static where layer a and the one below (or the ground) rest
        for a in range(L):
            if rest[a, col] and (a == 0 or rest[a - 1, col]):
                k = _frictional(mu_static, pressure[a])
                kappa[a] = k
                checked += 1
                good += _within_contract(k)
    if walls:
        checked += L
        for a in range(L):
            tau = _frictional(mu_wall, wall_pressure[a])
            w[a] = wall_scale * l[a] * hj * tau
            good += _within_contract(tau)
    else:
        for a in range(L):
            w[a] = 0.0
    kind = base_kind[col]  # the basal condition replaces interface 0
    if kind == COULOMB:
        kappa[0] = base_mu[col] * pressure[0]
    elif kind != NO_SLIP:  # free slip
        kappa[0] = 0.0
    viscous[0] = kind == NO_SLIP
    return checked - good


@njit(cache=True)
def _coefficients(hw, wet, inputs, m, kappa, w, pressure, spacing, viscous, wall_pressure):
    """The arrays of ``ColumnStresses`` (L, n) of the columns ``wet`` of thicknesses
    ``hw``, column by column (:func:`column_coefficients`).  Returns how many yield values
    are outside the plugin contract."""
    L, n = m.shape
    (rest, has_rest, gravity, has_gravity, g_n, rho, l, at_interface, at_centre, apart, base_kind,
     base_mu, mu, mu_static, walls, mu_wall, wall_scale) = inputs  # fmt: skip
    bad = 0
    mc, kc, wc, pc, sc, wpc = np.empty(L), np.empty(L), np.empty(L), np.empty(L), np.empty(L), np.empty(L)
    vc = np.empty(L, np.bool_)
    for j in range(n):
        bad += column_coefficients(
            wet[j], hw[j], rest, has_rest, gravity, has_gravity, g_n, rho, l, at_interface, at_centre,
            apart, base_kind, base_mu, mu, mu_static, walls, mu_wall, wall_scale,
            mc, kc, wc, pc, sc, vc, wpc,
        )  # fmt: skip
        for a in range(L):
            m[a, j], kappa[a, j], w[a, j], pressure[a, j] = mc[a], kc[a], wc[a], pc[a]
            spacing[a, j], viscous[a, j], wall_pressure[a, j] = sc[a], vc[a], wpc[a]
    return bad


_NO_REST = np.zeros((1, 1), dtype=bool)
_NO_GRAVITY = np.zeros((1, 1))
Fractions = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""``l, depth_interface, depth_centre, spacing_fraction`` of a model, each (L,)."""


class CompiledCoefficients:
    """``StressModel.columns`` of a stress model, compiled column by column, when its laws have
    compiled yield forms (read from the model at each call, so a law swapped on a running
    simulation is honoured); the numpy ``StressModel.columns`` otherwise.

    The arrays returned are overwritten by the next call."""

    def __init__(self, stresses: StressModel):
        self.stresses = stresses
        self._floats, self._flags = np.empty(0), np.empty(0, bool)
        self._fraction_cache: tuple[np.ndarray, Fractions] | None = None  # (s.l, _fractions())

    def laws(self) -> tuple[tuple[float, float], float | None] | None:
        """((mu, mu_static) of the bulk law, mu of the wall law or None), or None when a
        law has no compiled yield form."""
        s = self.stresses
        bulk = yield_law_of(s.bulk, s.material)
        if bulk is None:
            return None
        if s.walls is None:
            return bulk, None
        walls = yield_law_of(s.walls, s.material)
        return None if walls is None else (bulk, walls[0])

    def inputs(
        self, rest: np.ndarray | None = None, yield_gravity: np.ndarray | None = None
    ) -> tuple[YieldInputs, bool]:
        """The :class:`YieldInputs` of the model with these layers at rest and yield
        gravity (those of ``StressModel.columns``), and whether its laws have compiled
        yield forms (if not, the frictional coefficients are NaN placeholders)."""
        laws = self.laws()
        s = self.stresses
        (mu, mu_static), mu_wall = ((np.nan, np.nan), None) if laws is None else laws
        inputs = YieldInputs(
            _NO_REST if rest is None else rest, rest is not None,
            _NO_GRAVITY if yield_gravity is None else np.ascontiguousarray(yield_gravity),
            yield_gravity is not None, float(s.g_n), float(s.material.density), *self._fractions(),
            s.base_kind, s.base_mu, mu, mu_static, mu_wall is not None,
            0.0 if mu_wall is None else mu_wall, 2.0 / s.width,
        )  # fmt: skip
        return inputs, laws is not None

    def _fractions(self) -> Fractions:
        """``l, depth_interface, depth_centre, spacing_fraction`` of the model, contiguous (L,)."""
        s = self.stresses
        if self._fraction_cache is None or self._fraction_cache[0] is not s.l:
            parts = (s.l, s.depth_interface, s.depth_centre, s.spacing_fraction)
            l, interface, centre, spacing = (np.ascontiguousarray(a[:, 0]) for a in parts)
            self._fraction_cache = (s.l, (l, interface, centre, spacing))
        return self._fraction_cache[1]

    def __call__(
        self,
        h: np.ndarray,
        where: np.ndarray,
        rest: np.ndarray | None = None,
        yield_gravity: np.ndarray | None = None,
    ) -> ColumnStresses:
        """``StressModel.columns(h, where, rest, yield_gravity)`` for the column indices
        ``where`` (an integer array), with the same bits."""
        s = self.stresses
        inputs, compiled = self.inputs(rest, yield_gravity)
        if not compiled:
            return s.columns(h, where, rest, yield_gravity)
        where = np.ascontiguousarray(where, dtype=np.int64)
        arrays = self._arrays(s.l.shape[0], where.size)
        if _coefficients(h[where], where, inputs, *arrays) != 0:
            return s.columns(h, where, rest, yield_gravity)  # it names the plugin, the method and the value
        m, kappa, w, pressure, spacing, viscous, wall_pressure = arrays
        return ColumnStresses(
            m=m, kappa=kappa, w=w, pressure=pressure, spacing=spacing, viscous=viscous,
            wall_pressure=wall_pressure, x=s.x[where],
        )  # fmt: skip

    def _arrays(self, L: int, n: int) -> tuple[np.ndarray, ...]:
        """The seven (L, n) arrays of ``ColumnStresses``: contiguous views of two buffers
        grown when a call needs more columns than any call before."""
        if self._floats.size < 6 * L * n:
            self._floats, self._flags = np.empty(6 * L * max(n, 1)), np.empty(L * max(n, 1), bool)
        m, kappa, w, pressure, spacing, wall_pressure = self._floats[: 6 * L * n].reshape(6, L, n)
        return m, kappa, w, pressure, spacing, self._flags[: L * n].reshape(L, n), wall_pressure
