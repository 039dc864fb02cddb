"""``StressModel.columns`` compiled: the velocity-independent coefficients, column by column.

When the bulk law (and the wall law, with side walls) declare the compiled form of their
yield part (``Rheology.yield_stress_kernel``: ``kappa = mu max(p, 0)``, ``mu_static max(p,
0)`` at rest; for a law of the column thickness ``h``, ``frictional_thickness``, the
friction of Forterre & Pouliquen 2003, ``(mu + D / (1 + h / L)) max(p, 0)``), the masses,
interface pressures and yield stresses (start/stop and basal conditions included), wall
thresholds, spacings and mean layer pressures of a column are computed by one compiled
function, :func:`column_coefficients`: column by column into arrays kept from step to step
(:class:`CompiledCoefficients`, instead of a dozen numpy temporaries of their size per
step), and inside the compiled Newton step (``newton_kernel``), which so never stores them
for the whole mesh. The operations are those of ``stresses.StressModel.columns`` in the same
order, so the coefficients are the same bits (tests/test_stress_kernel.py). Any value
outside the plugin contract (not finite, or negative) sends the call to
``StressModel.columns``, whose checks name the plugin, the method, the value and where.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from multilayer.engine.compiled import jit
from multilayer.engine.plugin_output import declared_form
from multilayer.engine.vertical.forms import describes
from multilayer.engine.vertical.stresses import ColumnStresses, StressModel

YIELD_FORMS = {"frictional": 2, "frictional_thickness": 4}
"""The compiled yield forms and their numbers of parameters: ``(mu, mu_static)``, and
``(mu, mu_static, D, L)`` (``mu + D / (1 + h / L)`` with the column thickness ``h``)."""


def yield_law_of(rheology, material) -> tuple[float, float, float, float] | None:
    """``(mu, mu_static, D, L)`` of a plugin's compiled yield part (``D = 0``, ``L = inf``
    for the ``frictional`` form), None if it has none (or if a subclass or the instance
    redefines ``yield_stress`` or ``static_yield_stress`` below the class that declares the
    form, or if the column quantities it uses, ``Rheology.uses``, are not those of its form:
    the thickness for ``frictional_thickness``, none for ``frictional``)."""
    if not describes(rheology, "yield_stress_kernel", ("yield_stress", "static_yield_stress")):
        return None
    uses = tuple(getattr(rheology, "uses", ()))
    declared = declared_form(rheology, "yield_stress_kernel", material, YIELD_FORMS)
    if declared is None or uses != (("thickness",) if declared[0] == "frictional_thickness" else ()):
        return None
    if declared[0] == "frictional":
        mu, mu_static = declared[1]
        return float(mu), float(mu_static), 0.0, np.inf
    mu, mu_static, drop, length = declared[1]
    return float(mu), float(mu_static), float(drop), float(length)


@jit(inline="always")
def _frictional(mu, p):
    """``mu * numpy.maximum(p, 0.0)`` (a NaN pressure stays NaN and -0.0 gives +0.0, as in numpy)."""
    return mu * (p if (p > 0.0 or p != p) else 0.0)


@jit(inline="always")
def _within_contract(value):
    """1 if ``value`` is finite and >= 0 (the plugin contract), else 0 (a NaN fails).  Finite
    as ``value * 0.0 == 0.0`` (NaN for an infinite or NaN value), the same test as ``value <
    inf``, which LLVM turns into a test of the value's bits: about 17 instructions per
    vector of values instead of 3 in a vectorised loop."""
    return (value >= 0.0) & (value * 0.0 == 0.0)


class YieldInputs(NamedTuple):
    """What the compiled yield forms need to compute ``StressModel.columns`` of any column
    (one argument of the kernels; ``rest`` and ``yield_gravity`` are (1, 1) placeholders
    when absent)."""

    rest: np.ndarray  # (L, N) layers at rest at the start of the step
    has_rest: bool
    resting: np.ndarray  # (N,) the columns with a layer at rest (any of rest)
    yield_gravity: np.ndarray  # (L, N) replaces g cos(theta) in the interface pressures
    has_yield_gravity: bool
    g_n: float
    rho: float
    l: np.ndarray  # (L,) layer fractions
    depth_interface: np.ndarray  # (L,) (h - z_k) / h
    depth_centre: np.ndarray  # (L,) depth of the layer centres / h
    spacing_fraction: np.ndarray  # (L,) h_k / h across interface k
    base_bulk: np.ndarray  # (N,) the bulk law holds the bed (basal.BasalColumns)
    base_friction: np.ndarray  # (N,) otherwise kappa_0 = friction p_0 + cohesion
    base_cohesion: np.ndarray  # (N,)
    mu: float  # the frictional forms: kappa = mu max(p, 0), mu_static max(p, 0) at rest
    mu_static: float
    thickness_law: bool  # frictional_thickness: mu + D / (1 + h / L) and mu_static + D / (1 + h / L)
    drop: float  # D
    length: float  # L
    walls: bool
    mu_wall: float  # tau_w = mu_wall max(pbar, 0)
    wall_scale: float  # 2 / W


class ColumnArrays(NamedTuple):
    """The coefficients of ``StressModel.columns`` of one column, each (L,)."""

    m: np.ndarray
    kappa: np.ndarray
    w: np.ndarray
    pressure: np.ndarray
    spacing: np.ndarray
    viscous: np.ndarray
    wall_pressure: np.ndarray


def column_arrays(L: int) -> ColumnArrays:
    """Empty :class:`ColumnArrays` of ``L`` layers."""
    return ColumnArrays(
        np.empty(L), np.empty(L), np.empty(L), np.empty(L), np.empty(L), np.empty(L, np.bool_), np.empty(L)
    )


@jit(inline="always")  # inlined: a call per column costs about 50 ns at L = 8
def column_coefficients(col, hj, inputs, out, at, step, wall_parts):
    """Column ``col`` of thickness ``hj`` of ``StressModel.columns`` with the yield forms ``mu
    max(p, 0)``, ``mu_static max(p, 0)`` at rest (each plus ``D / (1 + hj / L)`` with
    ``thickness_law``) and ``mu_wall max(pbar, 0)`` on the walls (:class:`YieldInputs`
    ``inputs``), into the (L,) arrays of ``out`` (:class:`ColumnArrays`), but for its yield
    stresses ``kappa``, wall thresholds ``w``, interface pressures ``pressure`` and spacings
    ``spacing``, which go to cells ``at``, ``at + step``, ... of theirs, layer a to cell
    ``at + a step`` (the Newton kernel writes them straight into rows of its tile), and the mean
    wall pressures with ``wall_parts`` (or side walls) only. Returns how many yield values
    are outside the plugin contract (not finite and >= 0). (Inlined, the fields
    of both tuples are read as the arrays themselves: numba prunes the reference counts.)

    Of what is the same in every column it writes only what may differ: the caller's
    ``out.viscous`` holds True above layer 0 (only the basal condition makes a layer not
    viscous: it writes ``viscous[0]``), and without side walls its ``w`` holds 0.0 at the
    column's cells (written only with walls), each filled once by the caller for all its
    columns (two fills per column were two calls of ``memset``).

    The one source of these coefficients on the compiled paths: the arrays of
    :class:`CompiledCoefficients` and, column by column, the Newton kernel
    (``newton_kernel``), which so never stores them for the whole mesh."""
    rho, l, rest, yield_gravity = inputs.rho, inputs.l, inputs.rest, inputs.yield_gravity
    m, kappa, w, pressure, wall_pressure = out.m, out.kappa, out.w, out.pressure, out.wall_pressure
    spacing, viscous = out.spacing, out.viscous
    g_p = rho * inputs.g_n
    L = l.size
    checked = good = 0  # loops without branches, so that they vectorise
    first, step = np.uint64(at), np.uint64(step)  # unsigned: no test for negative indices
    for a in range(L):
        m[a] = rho * l[a] * hj
        spacing[first + np.uint64(a) * step] = inputs.spacing_fraction[a] * hj
    if wall_parts or inputs.walls:
        for a in range(L):
            wall_pressure[a] = g_p * inputs.depth_centre[a] * hj
    if inputs.has_yield_gravity:
        for a in range(L):
            pressure[first + np.uint64(a) * step] = (
                rho * yield_gravity[a, col] * inputs.depth_interface[a] * hj
            )
    else:
        for a in range(L):
            pressure[first + np.uint64(a) * step] = g_p * inputs.depth_interface[a] * hj
    checked += L
    mu, mu_static = inputs.mu, inputs.mu_static
    if inputs.thickness_law:  # the operations of pouliquen_forterre.mu_stop
        mu = mu + inputs.drop / (1.0 + hj / inputs.length)
        mu_static = mu_static + inputs.drop / (1.0 + hj / inputs.length)
    for a in range(L):
        k = _frictional(mu, pressure[first + np.uint64(a) * step])
        kappa[first + np.uint64(a) * step] = k
        good += _within_contract(k)
    # interface a is static where layer a and the one below (or the ground) rest
    if inputs.has_rest and inputs.resting[col]:
        for a in range(L):
            if rest[a, col] and (a == 0 or rest[a - 1, col]):
                k = _frictional(mu_static, pressure[first + np.uint64(a) * step])
                kappa[first + np.uint64(a) * step] = k
                checked += 1
                good += _within_contract(k)
    if inputs.walls:
        checked += L
        for a in range(L):
            tau = _frictional(inputs.mu_wall, wall_pressure[a])
            w[first + np.uint64(a) * step] = inputs.wall_scale * l[a] * hj * tau
            good += _within_contract(tau)
    if not inputs.base_bulk[col]:  # the basal condition: the friction of the bed at interface 0
        kappa[first] = inputs.base_friction[col] * pressure[first] + inputs.base_cohesion[col]
    viscous[0] = inputs.base_bulk[col]
    return checked - good


@jit
def _coefficients(hw, wet, inputs, m, kappa, w, pressure, spacing, viscous, wall_pressure):
    """The arrays of ``ColumnStresses`` (L, n) of the columns ``wet`` of thicknesses
    ``hw``, column by column (:func:`column_coefficients`).  Returns how many yield values
    are outside the plugin contract."""
    L, n = m.shape
    bad = 0
    # viscous above layer 0, no wall thresholds without walls: as column_coefficients needs
    column = ColumnArrays(
        np.empty(L), np.empty(L), np.zeros(L), np.empty(L), np.empty(L), np.ones(L, np.bool_), np.empty(L)
    )
    for j in range(n):
        bad += column_coefficients(wet[j], hw[j], inputs, column, 0, 1, True)
        for a in range(L):
            m[a, j], kappa[a, j], w[a, j] = column.m[a], column.kappa[a], column.w[a]
            pressure[a, j], spacing[a, j] = column.pressure[a], column.spacing[a]
            viscous[a, j], wall_pressure[a, j] = column.viscous[a], column.wall_pressure[a]
    return bad


def columns_at_rest(rest: np.ndarray, columns: tuple[int, int] | None) -> np.ndarray:
    """The columns (N,) of ``rest`` (L, N) with a layer at rest, among the columns
    ``columns`` (lo, hi; None: all), False in the others: a pass over the columns read
    only (a dam break holds material in a tenth of its mesh)."""
    if columns is None:
        return np.logical_or.reduce(rest, axis=0)
    lo, hi = columns
    found = np.zeros(rest.shape[1], dtype=bool)
    np.logical_or.reduce(rest[:, lo:hi], axis=0, out=found[lo:hi])
    return found


_NO_REST = np.zeros((1, 1), dtype=bool)
_NO_RESTING = np.zeros(1, dtype=bool)
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

    def laws(self) -> tuple[tuple[float, float, float, float], float | None] | None:
        """((mu, mu_static, D, L) of the bulk law, mu of the wall law or None), or None when
        a law has no compiled yield form (or the wall law's depends on the thickness)."""
        return self.stresses.forms("yield", self._read_laws)

    def _read_laws(self) -> tuple[tuple[float, float, float, float], float | None] | None:
        s = self.stresses
        bulk = yield_law_of(s.bulk, s.material)
        if bulk is None:
            return None
        if s.walls is None:
            return bulk, None
        walls = yield_law_of(s.walls, s.material)
        return None if walls is None or walls[2] != 0.0 else (bulk, walls[0])

    def inputs(
        self,
        rest: np.ndarray | None = None,
        yield_gravity: np.ndarray | None = None,
        columns: tuple[int, int] | None = None,
    ) -> tuple[YieldInputs, bool]:
        """The :class:`YieldInputs` of the model with these layers at rest and yield
        gravity (those of ``StressModel.columns``), and whether its laws have compiled
        yield forms (if not, the frictional coefficients are NaN placeholders).  With
        ``columns`` (lo, hi), the kernels read the columns ``lo .. hi-1`` only: the columns
        with a layer at rest (``resting``) are found among them (False in the others)."""
        laws = self.laws()
        s = self.stresses
        (mu, mu_static, drop, length), mu_wall = (
            ((np.nan, np.nan, 0.0, np.inf), None) if laws is None else laws
        )
        inputs = YieldInputs(
            _NO_REST if rest is None else rest, rest is not None,
            _NO_RESTING if rest is None else columns_at_rest(rest, columns),
            _NO_GRAVITY if yield_gravity is None else np.ascontiguousarray(yield_gravity),
            yield_gravity is not None, float(s.g_n), float(s.material.density), *self._fractions(),
            s.base.bulk, s.base.friction, s.base.cohesion, mu, mu_static, drop != 0.0, drop, length,
            mu_wall is not None,
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
            wall_pressure=wall_pressure, x=s.x[where], thickness=h[where],
        )  # fmt: skip

    def _arrays(self, L: int, n: int) -> tuple[np.ndarray, ...]:
        """The seven (L, n) arrays of ``ColumnStresses``: contiguous views of two buffers
        grown when a call needs more columns than any call before."""
        if self._floats.size < 6 * L * n:
            self._floats, self._flags = np.empty(6 * L * max(n, 1)), np.empty(L * max(n, 1), bool)
        m, kappa, w, pressure, spacing, wall_pressure = self._floats[: 6 * L * n].reshape(6, L, n)
        return m, kappa, w, pressure, spacing, self._flags[: L * n].reshape(L, n), wall_pressure
