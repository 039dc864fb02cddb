"""``StressModel.columns`` compiled: the velocity-independent coefficients in one pass.

When the bulk law (and the wall law, with side walls) declare the compiled form of their
yield part (``Rheology.yield_stress_kernel``: ``kappa = mu max(p, 0)``, ``mu_static
max(p, 0)`` at rest), the masses, interface pressures and yield stresses (start/stop and
basal conditions included), wall thresholds, spacings and mean layer pressures of the
wet columns are computed in one compiled pass, row by row, into arrays kept from step to
step, instead of a dozen numpy temporaries of the mesh's size per step.  The operations
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
    """``mu * numpy.maximum(p, 0.0)`` (a NaN pressure stays NaN, as in numpy)."""
    return mu * (p if (p >= 0.0 or p != p) else 0.0)


@njit(cache=True, inline="always")
def _outside_contract(value):
    return not (value >= 0.0 and value < np.inf)


def _coefficients(
    h, wet, rest, has_rest, yield_gravity, has_yield_gravity, g_n, rho, l, depth_interface, depth_centre,
    spacing_fraction, base_kind, base_mu, mu, mu_static, walls, mu_wall, wall_scale,
    m, kappa, w, pressure, spacing, viscous, wall_pressure,
):  # fmt: skip
    """The arrays of ``ColumnStresses`` (L, n) of the columns ``wet`` (``StressModel.columns``
    with the yield forms ``mu max(p, 0)``, ``mu_static max(p, 0)`` at rest and
    ``mu_wall max(pbar, 0)`` on the walls).  Returns False if a yield value is outside
    the plugin contract (not finite and >= 0)."""
    L = l.size
    n = wet.size
    bad = 0
    for a in prange(L):
        g_p = rho * g_n
        mass, apart = rho * l[a], spacing_fraction[a]
        at_depth, at_centre = depth_interface[a], depth_centre[a]
        wall_part = wall_scale * l[a]
        for j in range(n):
            col = wet[j]
            hj = h[col]
            g = rho * yield_gravity[a, col] if has_yield_gravity else g_p
            p = g * at_depth * hj
            pressure[a, j] = p
            flowing = _frictional(mu, p)
            if _outside_contract(flowing):
                bad += 1
            k = flowing
            if has_rest and rest[a, col] and (a == 0 or rest[a - 1, col]):
                k = _frictional(mu_static, p)
                if _outside_contract(k):
                    bad += 1
            is_viscous = True
            if a == 0:
                kind = base_kind[col]
                if kind == COULOMB:
                    k = base_mu[col] * p
                elif kind != NO_SLIP:  # free slip
                    k = 0.0
                is_viscous = kind == NO_SLIP
            kappa[a, j] = k
            viscous[a, j] = is_viscous
            pbar = g_p * at_centre * hj
            wall_pressure[a, j] = pbar
            if walls:
                tau = _frictional(mu_wall, pbar)
                if _outside_contract(tau):
                    bad += 1
                w[a, j] = wall_part * hj * tau
            else:
                w[a, j] = 0.0
            m[a, j] = mass * hj
            spacing[a, j] = apart * hj
    return bad == 0


_serial = njit(cache=True)(_coefficients)
_parallel = njit(cache=True, parallel=True)(_coefficients)

_NO_REST = np.zeros((1, 1), dtype=bool)
_NO_GRAVITY = np.zeros((1, 1))


class CompiledCoefficients:
    """``StressModel.columns`` of a stress model in one compiled pass, when its laws have
    compiled yield forms (read from the model at each call, so a law swapped on a running
    simulation is honoured); the numpy ``StressModel.columns`` otherwise.

    The arrays returned are overwritten by the next call."""

    def __init__(self, stresses: StressModel):
        self.stresses = stresses
        self._buffers: dict[str, np.ndarray] = {}

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
        L, n = s.l.shape[0], where.size
        arrays = self._arrays(L, n)
        kernel = _parallel if threads > 1 else _serial
        fine = kernel(
            h, np.ascontiguousarray(where, dtype=np.int64),
            _NO_REST if rest is None else rest, rest is not None,
            _NO_GRAVITY if yield_gravity is None else np.ascontiguousarray(yield_gravity),
            yield_gravity is not None, float(s.g_n),
            float(s.material.density), s.l[:, 0], s.depth_interface[:, 0], s.depth_centre[:, 0],
            s.spacing_fraction[:, 0], s.base_kind, s.base_mu, mu, mu_static, mu_wall is not None,
            0.0 if mu_wall is None else mu_wall, 2.0 / s.width, *arrays,
        )  # fmt: skip
        if not fine:  # the numpy path names the plugin, the method and the value
            return s.columns(h, where, rest, yield_gravity)
        m, kappa, w, pressure, spacing, viscous, wall_pressure = arrays
        return ColumnStresses(
            m=m, kappa=kappa, w=w, pressure=pressure, spacing=spacing, viscous=viscous,
            wall_pressure=wall_pressure, x=s.x[where],
        )  # fmt: skip

    def _arrays(self, L: int, n: int) -> list[np.ndarray]:
        """The seven (L, n) arrays of ``ColumnStresses``: contiguous views of buffers grown
        when a call needs more columns than any call before."""
        names = ("m", "kappa", "w", "pressure", "spacing", "viscous", "wall_pressure")
        if self._buffers.get("m", np.empty(0)).size < L * n:
            size = L * max(n, 1)
            self._buffers = {name: np.empty(size, bool if name == "viscous" else float) for name in names}
        return [self._buffers[name][: L * n].reshape(L, n) for name in names]
