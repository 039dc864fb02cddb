"""The implicit vertical step compiled: viscous linearisation and exact solve fused per column.

``vertical_step.implicit_step`` iterates, over all unconverged columns at once, the Newton
model of the viscous stresses (``StressModel.linearise``, numpy, calling the rheology
plugins) and the exact solver (``column_kernel``).  Each column's iteration depends on
that column only, so the same iteration runs here column by column with every quantity in
cache, when the bulk and wall laws declare a compiled form of their viscosity
(``Rheology.viscosity_kernel``).  The operations are those of ``stress.py`` in the same
order, so both paths agree to round-off (tests/test_newton_kernel.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from multilayer.engine.column_kernel import _active_set, _dynamic_programme, _workspace
from multilayer.engine.plugin_output import PluginOutputError, outside_contract
from multilayer.engine.stress import INTERFACE, LAYER, ColumnStresses, StressModel

FORMS = {"constant": 0, "inertial": 1, "power": 2}
BLOCK = 16
"""Columns gathered at a time (their coefficients stay in cache)."""


def _owner(rheology: object, name: str) -> type | None:
    """The class whose definition of ``name`` an instance uses (None: the instance's own)."""
    if name in vars(rheology):
        return None
    return next((cls for cls in type(rheology).__mro__ if name in vars(cls)), None)


def law_of(rheology, material) -> tuple[int, np.ndarray] | None:
    """(form code, parameters) of a plugin's compiled viscosity, None if it has none.

    A compiled form describes the ``viscosity`` of the class that declares it: where a
    subclass (or the instance) redefines ``viscosity`` below that class, the form is not
    used, and the step runs the plugin's own ``viscosity`` (numpy path)."""
    kernel_owner, viscosity_owner = _owner(rheology, "viscosity_kernel"), _owner(rheology, "viscosity")
    if kernel_owner is None or viscosity_owner is None or not issubclass(kernel_owner, viscosity_owner):
        return None
    declared = rheology.viscosity_kernel(material)
    if declared is None or declared[0] not in FORMS:
        return None
    return FORMS[declared[0]], np.array(declared[1], dtype=float)


@njit(cache=True)
def _pressure_part(form, params, p):
    """The factor of eta that depends on the pressure only, and the one added to the
    rate term (computed once per column and step, not per Newton iteration)."""
    p = max(p, 0.0)
    if form == 0:
        return params[0], 0.0
    if form == 1:
        return params[0] * p, params[1] * np.sqrt(p)
    return params[0] * p ** params[1], 0.0


@njit(cache=True)
def _viscosity(form, params, rate, factor, offset):
    """eta(|gamma|, p) of the compiled forms (``Rheology.viscosity_kernel``) from the
    pressure parts ``factor, offset = _pressure_part(form, params, p)``."""
    if form == 0:
        return factor
    if form == 1:
        denominator = offset + params[2] * abs(rate)
        return factor / denominator if denominator > 0.0 else 0.0
    return factor * max(abs(rate), params[3]) ** params[2]


@njit(cache=True)
def _newton_model(form, params, kappa, rate, factor, offset):
    """``stress._newton_model`` for one value: (yield stress, slope)."""
    step = 1e-7 * rate
    eta = _viscosity(form, params, rate, factor, offset)
    if not (eta >= 0.0 and eta < np.inf):  # outside the plugin contract: (kappa, eta) shows it
        return kappa, eta
    tau = eta * rate
    up = _viscosity(form, params, rate + step, factor, offset) * (rate + step)
    if rate > 0.0:
        tangent = (up - tau) / (step if step > 0.0 else 1.0)
    else:
        tangent = eta
    slope = max(tangent, 0.0)
    offset_yield = kappa + tau - slope * rate
    if offset_yield >= 0.0:
        return offset_yield, slope
    return kappa, eta


def _columns(
    chunks, wet, m, kappa0, w0, pressure, spacing, viscous, wall_pressure, ustar, guess,
    dt, bulk_form, bulk_params, wall_form, wall_params, width, density, threshold, max_iterations,
    u_out, iterations, fallbacks, faults, fault_values,
):  # fmt: skip
    """Newton iterations of every wet column (``wet`` indexes the columns of ustar/guess);
    ``fallbacks`` counts the solves per column that needed the O(L^2) dynamic programme.
    A column where a compiled viscosity is not finite and >= 0 stops iterating: ``faults``
    gets a + 1 for the bulk law at interface a, -(a + 1) for the wall law of layer a (0:
    none) and ``fault_values`` the viscosity and the shear rate."""
    L = m.shape[0]
    n = wet.size
    for k in prange(chunks):
        ws = _workspace(L)
        first = np.empty(L + 1, np.int64)
        grounded = np.empty(L, np.bool_)
        U, diag, low, rhs = np.empty(L), np.empty(L), np.empty(L), np.empty(L)
        mc, kc, cc, wc, cwc = np.empty(L), np.empty(L), np.empty(L), np.empty(L), np.empty(L)
        inertia, momentum = np.empty(L), np.empty(L)  # m_a / dt and m_a u*_a / dt
        current, new = np.empty(L), np.empty(L)
        bulk_factor, bulk_offset, wall_factor, wall_offset = (
            np.empty(L),
            np.empty(L),
            np.empty(L),
            np.empty(L),
        )
        # columns in blocks: the coefficients of a block are gathered row by row (each row
        # of the (L, N) arrays read in contiguous runs) into column-contiguous buffers
        bm, bk, bw, bp, bs = (
            np.empty((BLOCK, L)),
            np.empty((BLOCK, L)),
            np.empty((BLOCK, L)),
            np.empty((BLOCK, L)),
            np.empty((BLOCK, L)),
        )
        bwp, bu, bg, bo = (
            np.empty((BLOCK, L)),
            np.empty((BLOCK, L)),
            np.empty((BLOCK, L)),
            np.empty((BLOCK, L)),
        )
        bv = np.empty((BLOCK, L), np.bool_)
        start, stop = k * n // chunks, (k + 1) * n // chunks
        for j0 in range(start, stop, BLOCK):
            size = min(BLOCK, stop - j0)
            for a in range(L):
                for jj in range(size):
                    j = j0 + jj
                    col = wet[j]
                    bm[jj, a] = m[a, j]
                    bk[jj, a] = kappa0[a, j]
                    bw[jj, a] = w0[a, j]
                    bp[jj, a] = pressure[a, j]
                    bs[jj, a] = spacing[a, j]
                    bv[jj, a] = viscous[a, j]
                    bwp[jj, a] = wall_pressure[a, j]
                    bu[jj, a] = ustar[a, col]
                    bg[jj, a] = guess[a, col]
            for jj in range(size):
                j = j0 + jj
                for a in range(L):
                    mc[a] = bm[jj, a]
                    inertia[a] = bm[jj, a] / dt
                    momentum[a] = bm[jj, a] * bu[jj, a] / dt
                    current[a] = bg[jj, a]
                    bulk_factor[a], bulk_offset[a] = _pressure_part(bulk_form, bulk_params, bp[jj, a])
                    if width > 0.0:
                        wall_factor[a], wall_offset[a] = _pressure_part(wall_form, wall_params, bwp[jj, a])
                iterations[j] = -1
                fallbacks[j] = 0
                fault = 0
                for iteration in range(1, max_iterations + 1):
                    # the Newton model at the current velocities (StressModel.linearise)
                    below = 0.0
                    for a in range(L):
                        s = bs[jj, a]
                        s_safe = s if s > 0.0 else 1.0
                        rate = abs(current[a] - below) / s_safe
                        below = current[a]
                        ka, t = _newton_model(
                            bulk_form, bulk_params, bk[jj, a], rate, bulk_factor[a], bulk_offset[a]
                        )
                        if not (t >= 0.0 and t < np.inf) and fault == 0:  # the plugin contract
                            fault = a + 1
                            fault_values[j, 0], fault_values[j, 1] = t, rate
                        kc[a] = ka if bv[jj, a] else bk[jj, a]
                        cc[a] = t / s_safe if (bv[jj, a] and s > 0.0) else 0.0
                        if width > 0.0:
                            half = 0.5 * width
                            per_area = (2.0 / width) * mc[a] / density
                            threshold_a = bw[jj, a] / max(per_area, 1e-300)
                            wa, ta = _newton_model(
                                wall_form, wall_params, threshold_a, abs(current[a]) / half,
                                wall_factor[a], wall_offset[a],
                            )  # fmt: skip
                            if not (ta >= 0.0 and ta < np.inf) and fault == 0:
                                fault = -(a + 1)
                                fault_values[j, 0], fault_values[j, 1] = ta, abs(current[a]) / half
                            wc[a] = per_area * wa
                            cwc[a] = per_area * ta / half
                        else:
                            wc[a] = bw[jj, a]
                            cwc[a] = 0.0
                    if fault != 0:
                        break
                    if mc[0] <= 0.0:
                        for a in range(L):
                            new[a] = 0.0
                    elif not _active_set(
                        inertia, momentum, kc, cc, wc, cwc, current, new, first, grounded, U, diag, low, rhs
                    ):
                        _dynamic_programme(inertia, momentum, kc, cc, wc, cwc, new, ws)
                        fallbacks[j] += 1
                    change = 0.0
                    for a in range(L):
                        change = max(change, abs(new[a] - current[a]))
                        current[a] = new[a]
                    if change <= threshold:
                        iterations[j] = iteration
                        break
                faults[j] = fault
                for a in range(L):
                    bo[jj, a] = current[a]
            for a in range(L):
                for jj in range(size):
                    u_out[a, wet[j0 + jj]] = bo[jj, a]


_serial = njit(cache=True)(_columns)
_parallel = njit(cache=True, parallel=True)(_columns)


class CompiledStep:
    """The compiled implicit step of a stress model, for laws that have compiled forms.

    The laws are read from the stress model at each use, so a law swapped on a running
    simulation is honoured (and without a compiled form sends the step to numpy).
    """

    def __init__(self, stresses: StressModel):
        self.stresses = stresses
        self.solves = 0  # column solves so far
        self.fallbacks = 0  # of which by the O(L^2) dynamic programme (the active set failed)
        self._out: np.ndarray | None = None  # the result, reused from step to step

    def laws(self) -> tuple[tuple[int, np.ndarray], tuple[int, np.ndarray] | None] | None:
        """(bulk, walls) compiled forms, None when some law has none."""
        s = self.stresses
        bulk = law_of(s.bulk, s.material)
        walls = law_of(s.walls, s.material) if s.walls is not None else None
        if bulk is None or (s.walls is not None and walls is None):
            return None
        return bulk, walls

    def __call__(
        self,
        h: np.ndarray,
        ustar: np.ndarray,
        u_guess: np.ndarray,
        dt: float,
        *,
        threshold: float,
        max_iterations: int,
        threads: int = 1,
        rest: np.ndarray | None = None,
        yield_gravity: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """New velocities (L, N) and the Newton iterations of each wet column (-1: not
        converged within ``max_iterations``).  The velocities are overwritten by the next
        call.  ``rest`` and ``yield_gravity`` go to ``StressModel.columns``."""
        laws = self.laws()
        if laws is None:
            raise ValueError("a law of this stress model has no compiled form (see laws())")
        (bulk_form, bulk_params), walls = laws
        wet = np.flatnonzero(h > 0)
        cs: ColumnStresses = self.stresses.columns(h, wet, rest, yield_gravity)
        if self._out is None or self._out.shape != ustar.shape:
            self._out = np.zeros_like(ustar)
        u = self._out
        u.fill(0.0)
        iterations = np.empty(wet.size, np.int64)
        fallbacks = np.empty(wet.size, np.int64)
        faults, fault_values = np.empty(wet.size, np.int64), np.empty((wet.size, 2))
        wall_form, wall_params = walls if walls is not None else (0, np.zeros(1))
        width = float(self.stresses.width) if walls is not None else 0.0
        chunks = max(1, min(wet.size, 4 * threads))
        kernel = _parallel if threads > 1 else _serial
        kernel(
            chunks if threads > 1 else 1, wet, cs.m, cs.kappa, cs.w, cs.pressure, cs.spacing, cs.viscous,
            cs.wall_pressure, np.ascontiguousarray(ustar), np.ascontiguousarray(u_guess), float(dt),
            bulk_form, bulk_params, wall_form, wall_params, width, float(self.stresses.material.density),
            float(threshold), int(max_iterations), u, iterations, fallbacks, faults, fault_values,
        )  # fmt: skip
        if faults.any():
            raise self._fault(cs, faults, fault_values)
        self.solves += int(np.where(iterations < 0, max_iterations, iterations).sum())
        self.fallbacks += int(fallbacks.sum())
        return u, iterations

    def _fault(self, cs: ColumnStresses, faults: np.ndarray, values: np.ndarray) -> PluginOutputError:
        """The error naming the law, the viscosity and where, for the first column whose
        compiled viscosity was outside the plugin contract (``faults`` of ``_columns``)."""
        j = int(np.flatnonzero(faults)[0])
        bulk, a = faults[j] > 0, abs(int(faults[j])) - 1
        pressure = cs.pressure[a, j] if bulk else cs.wall_pressure[a, j]
        return outside_contract(
            self.stresses.bulk if bulk else self.stresses.walls, "viscosity()", float(values[j, 0]),
            x=float(cs.x[j]), where=(INTERFACE if bulk else LAYER).format(index=a, number=a + 1),
            t=self.stresses.t, given={"shear rate": float(values[j, 1]), "pressure": float(pressure)},
            note=f"its compiled form, viscosity_kernel; {int(np.count_nonzero(faults))} column(s) affected",
        )  # fmt: skip
