"""``StressModel.columns`` compiled: the velocity-independent coefficients in one pass.

When the bulk law (and the wall law, with side walls) declare the compiled form of their
yield part (``Rheology.yield_stress_kernel``: ``kappa = mu max(p, 0)``, ``mu_static
max(p, 0)`` at rest), the masses, interface pressures and yield stresses (start/stop and
basal conditions included), wall thresholds, spacings and mean layer pressures of the
wet columns are computed in one compiled pass, row by row, into arrays kept from step to
step, instead of a dozen numpy temporaries of their size per step.  The operations
are those of ``stress.StressModel.columns`` in the same order, so the coefficients are
the same bits (tests/test_stress_kernel.py).  Any value outside the plugin contract
(not finite, or negative) sends the call to ``StressModel.columns``, whose checks name
the plugin, the method, the value and where.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from multilayer.engine.compiled_forms import describes
from multilayer.engine.stress import COULOMB, NO_SLIP, ColumnStresses, StressModel
from multilayer.engine.threads import parallel_compiled


def yield_law_of(rheology, material) -> tuple[float, float] | None:
    """``(mu, mu_static)`` of a plugin's compiled yield part, None if it has none (or if
    a subclass or the instance redefines ``yield_stress`` or ``static_yield_stress``
    below the class that declares the form)."""
    if not describes(rheology, "yield_stress_kernel", ("yield_stress", "static_yield_stress")):
        return None
    declared = rheology.yield_stress_kernel(material)
    if declared is None or declared[0] != "frictional":
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


def _coefficients(
    hw, wet, rest, has_rest, yield_gravity, has_yield_gravity, g_n, rho, l, depth_interface,
    depth_centre, spacing_fraction, base_kind, base_mu, mu, mu_static, walls, mu_wall, wall_scale,
    m, kappa, w, pressure, spacing, viscous, wall_pressure,
):  # fmt: skip
    """The arrays of ``ColumnStresses`` (L, n) of the columns ``wet`` of thicknesses ``hw``
    (``StressModel.columns`` with the yield forms ``mu max(p, 0)``, ``mu_static max(p, 0)``
    at rest and ``mu_wall max(pbar, 0)`` on the walls), row by row (the rows in parallel
    in the parallel compilation).  Returns how many yield values are outside the plugin
    contract (not finite and >= 0).  Each row is written by loops over the thicknesses
    without branches (they vectorise); the gathers of the layers at rest and of
    ``yield_gravity`` and the basal row come separately."""
    L, n = l.size, wet.size
    g_p = rho * g_n
    checked = good = 0
    for a in prange(L):
        mass, apart = rho * l[a], spacing_fraction[a]
        at_depth, at_centre = depth_interface[a], depth_centre[a]
        wall_part = wall_scale * l[a]
        for j in range(n):
            hj = hw[j]
            m[a, j] = mass * hj
            spacing[a, j] = apart * hj
            wall_pressure[a, j] = g_p * at_centre * hj
            viscous[a, j] = True
        if has_yield_gravity:
            for j in range(n):
                pressure[a, j] = rho * yield_gravity[a, wet[j]] * at_depth * hw[j]
        else:
            for j in range(n):
                pressure[a, j] = g_p * at_depth * hw[j]
        checked += n
        for j in range(n):
            k = _frictional(mu, pressure[a, j])
            kappa[a, j] = k
            good += _within_contract(k)
        if has_rest:  # interface a is static where layer a and the one below (or the ground) rest
            for j in range(n):
                col = wet[j]
                if rest[a, col] and (a == 0 or rest[a - 1, col]):
                    k = _frictional(mu_static, pressure[a, j])
                    kappa[a, j] = k
                    checked += 1
                    good += _within_contract(k)
        if walls:
            checked += n
            for j in range(n):
                tau = _frictional(mu_wall, wall_pressure[a, j])
                w[a, j] = wall_part * hw[j] * tau
                good += _within_contract(tau)
        else:
            for j in range(n):
                w[a, j] = 0.0
    for j in range(n):  # the basal condition replaces interface 0
        kind = base_kind[wet[j]]
        if kind == COULOMB:
            kappa[0, j] = base_mu[wet[j]] * pressure[0, j]
        elif kind != NO_SLIP:  # free slip
            kappa[0, j] = 0.0
        viscous[0, j] = kind == NO_SLIP
    return checked - good


_serial = njit(cache=True)(_coefficients)
_parallel = parallel_compiled(_coefficients)

_NO_REST = np.zeros((1, 1), dtype=bool)
_NO_GRAVITY = np.zeros((1, 1))


class CompiledCoefficients:
    """``StressModel.columns`` of a stress model in one compiled pass, when its laws have
    compiled yield forms (read from the model at each call, so a law swapped on a running
    simulation is honoured); the numpy ``StressModel.columns`` otherwise.

    The arrays returned are overwritten by the next call."""

    def __init__(self, stresses: StressModel):
        self.stresses = stresses
        self._floats, self._flags = np.empty(0), np.empty(0, bool)

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

    def __call__(
        self,
        h: np.ndarray,
        where: np.ndarray,
        rest: np.ndarray | None = None,
        yield_gravity: np.ndarray | None = None,
        threads: int = 1,
    ) -> ColumnStresses:
        """``StressModel.columns(h, where, rest, yield_gravity)`` for the column indices
        ``where`` (an integer array), with the same bits."""
        s = self.stresses
        laws = self.laws()
        if laws is None:
            return s.columns(h, where, rest, yield_gravity)
        (mu, mu_static), mu_wall = laws
        where = np.ascontiguousarray(where, dtype=np.int64)
        L, n = s.l.shape[0], where.size
        arrays = self._arrays(L, n)
        args = (
            h[where], where, _NO_REST if rest is None else rest, rest is not None,
            _NO_GRAVITY if yield_gravity is None else np.ascontiguousarray(yield_gravity),
            yield_gravity is not None, float(s.g_n), float(s.material.density), s.l[:, 0],
            s.depth_interface[:, 0], s.depth_centre[:, 0], s.spacing_fraction[:, 0], s.base_kind, s.base_mu,
            mu, mu_static, mu_wall is not None, 0.0 if mu_wall is None else mu_wall, 2.0 / s.width, *arrays,
        )  # fmt: skip
        fine = (_parallel if threads > 1 else _serial)(*args) == 0
        if not fine:  # the numpy path names the plugin, the method and the value
            return s.columns(h, where, rest, yield_gravity)
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
