"""Linear stability of the one-layer grain–fluid mixture in x about a uniform layer: its
Fourier symbol, its dispersion relation and its well-posedness (docs/mixture.md,
"Well-posedness of the closure").

The equations are those the time loop solves in one layer (docs/mixture.md, "The mixture
in x"; Bouchut, Fernández-Nieto, Mangeney & Narbona-Reina 2016, J. Fluid Mech. 801, with
the relaxing pore pressure of George & Iverson 2014, Proc. R. Soc. A 470, 20130820), on a
bed inclined at ``theta``, in the unknowns ``q = (h, phi, u, p_e)``::

    d_t h   + u d_x h + h d_x u = h V
    d_t phi + u d_x phi         = -phi V
    d_t u   + u d_x u + g' d_x h = r(phi) g sin(theta) - tau_b / (rho_m h) - rho_f V u / (2 rho_m)
                                   + nu d_xx u
    alpha (d_t p_e + u d_x p_e) = -p_e / (B F) - Phi

with ``V = -p_e / (B F)`` the rate at which the mixture loses the fluid its excess pore
pressure drives out (``= Phi`` where ``alpha = 0``), ``g' = r0 g cos(theta)`` the
transport's buoyant gravity, ``r(phi) = phi (rho_s - rho_f) / rho_m``,
``rho_m = rho_s phi + rho_f (1 - phi)``, and the closure at the effective pressure
``p_s = P - p_e``, ``P = (rho_s - rho_f) g cos(theta) phi h``::

    gamma = 2 |u| / h                  (the time loop's shear rate in one layer)
    Phi   = gamma K (phi - phi_c + K2 eta_f gamma / p_s)
    tau_b = (tan(delta) + K (phi - phi_c)) p_s + (K1 + K K2) eta_f gamma
    B     = beta h^2 / (2 (1 - phi)^2)

At ``alpha = 0`` the last equation is the closure, ``p_e = -B F Phi``, an algebraic
constraint.  Two terms the model does not have are carried as options, each off by
default: ``F = F(k h) = 2 (1 - sech(k h)) / (k h)^2``, the lateral drainage of the excess
pore pressure (Darcy's law in x as well as in z, a dilation rate uniform over the depth:
``d_zz p + d_xx p = beta Phi / (1 - phi)^2``, ``p = 0`` at the top, no flux through the
bed; ``F = 1`` is the model's vertical drainage), and ``nu`` a depth-averaged in-plane
viscosity (the term of Gray & Edwards 2014, J. Fluid Mech. 755, 503, eq. 2.13, linearised).

Linearising about a uniform state ``q0`` (``u0 > 0``), perturbations ``exp(i k x + lambda t)``
satisfy ``lambda E q = (-i k A - nu k^2 e_u e_u^T + J(k)) q``, with ``A`` the advection
matrix (eigenvalues ``u0 +- c``, ``u0``, ``u0``, ``c = sqrt(g' h0)``), ``J`` the Jacobian of
the source terms, computed here by central differences of the closure of
:mod:`multilayer.engine.mixture.closure` (:func:`~multilayer.engine.mixture.closure.closure_at`),
and ``E = diag(1, 1, 1, alpha)``.  At ``alpha = 0`` the pore pressure is eliminated (a
Schur complement).  The state is not steady: a loose layer compacts at the rate
``V0 = -p_e0 / B0``, a few thousandths per second here, against growth rates of tens to
thousands per second, so the coefficients are frozen at ``q0`` (the base state's own
drift is left out; it is the ``k -> 0`` limit of the ``h`` and ``phi`` rows).

Well-posedness (Hadamard; Barker, Schaeffer, Bohórquez & Gray 2015, J. Fluid Mech. 779,
794, section 3): the initial-value problem is ill posed when the growth rate
``max Re lambda`` is unbounded as ``k -> infinity``.  Here ``A`` has real eigenvalues and
the sources depend on ``q`` and not on its derivatives, so
``lambda = -i k a_j + l_j J r_j + O(1/k)`` (``a_j, l_j, r_j`` the eigenvalues and left and
right eigenvectors of ``A``): the growth rate is bounded for every ``alpha``, and tends to
``(J_hh + J_uu) / 2 +- (c J_hu / h0 + h0 J_uh / c) / 2`` on the two waves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from multilayer.engine.config import InitialEntry, MixtureConfig, Numerics, SimulationConfig
from multilayer.engine.mixture.closure import (
    BasalClosure,
    MixtureMaterial,
    closure_at,
    closure_pressure,
    darcy_coefficient,
)
from multilayer.engine.mixture.flow import buoyant_fraction
from multilayer.engine.simulation import Simulation
from multilayer.plugins.builtins import DilatantCoulomb
from multilayer.plugins.contract import Material

SHEAR = 2.0
"""``gamma = SHEAR |u| / h``: the shear rate at the bed of one layer in the time loop
(``u / (h / 2)``; the uniform layer's ``3 |v| / h`` is that of a linear profile)."""

RELATIVE_STEP = 1e-6
"""Relative increment of the central differences of the Jacobian."""


def lateral_drainage(kh: np.ndarray | float) -> np.ndarray | float:
    """``F(kh) = 2 (1 - sech(kh)) / (kh)^2``: the basal excess pore pressure of a mode of
    wavenumber ``k`` over that of the vertical drainage alone (``F(0) = 1``,
    ``F ~ 2 / (kh)^2`` for ``kh >> 1``)."""
    kh = np.abs(np.asarray(kh, dtype=float))
    decay = np.exp(-kh)
    # 1 - sech(kh) = (1 - e^-kh)^2 / (1 + e^-2kh), without cancellation at small kh
    safe = np.where(kh > 0.0, kh, 1.0)
    value = np.where(kh > 0.0, 2.0 * np.expm1(-kh) ** 2 / (1.0 + decay * decay) / safe**2, 1.0)
    return float(value) if value.ndim == 0 else value


@dataclass(frozen=True)
class UniformMixture:
    """A uniform one-layer mixture of ``mat`` (its fluid's density and viscosity included),
    ``h`` (m) thick at the packing ``phi``, sliding at ``u > 0`` (m/s) on a bed inclined so
    that the buoyant weight along it balances the basal stress and the fluid's exchange
    (:attr:`slope`), under gravity ``g``.  ``alpha`` (1/Pa) the skeleton's compressibility
    (0: the closure), ``nu`` (m^2/s) an in-plane viscosity and ``drainage`` the lateral
    drainage of the pore pressure, which the model does not have (off by default)."""

    mat: MixtureMaterial
    h: float
    phi: float
    u: float
    g: float = 9.81
    alpha: float = 0.0
    nu: float = 0.0
    drainage: bool = False

    def __post_init__(self) -> None:
        if not (self.h > 0.0 and 0.0 < self.phi < 1.0 and self.u > 0.0):
            raise ValueError(f"a uniform flowing layer needs h > 0, 0 < phi < 1, u > 0: {self!r}")
        if self.alpha < 0.0 or self.nu < 0.0:
            raise ValueError(f"alpha and nu must be >= 0: {self!r}")

    @property
    def slope(self) -> float:
        """``theta`` (radians) at which the layer slides steadily at ``u`` (its drive
        balances ``tau_b`` and the fluid exchange), by fixed-point iteration in ``theta``
        (``cos(theta)`` enters the weight)."""
        theta = 0.0
        for _ in range(60):
            rho_m = self.density(self.phi)
            cl, rate = self._closure(self.h, self.phi, self.u, None, theta)
            drive = cl.tau_b / (rho_m * self.h) + self.mat.rho_f * rate * self.u / (2.0 * rho_m)
            new = math.asin(min(drive / (self.reduction(self.phi) * self.g), 1.0))
            if abs(new - theta) <= 1e-15:
                break
            theta = new
        return theta

    def density(self, phi: float) -> float:
        """``rho_m = rho_s phi + rho_f (1 - phi)``."""
        return self.mat.rho_s * phi + self.mat.rho_f * (1.0 - phi)

    def reduction(self, phi: float) -> float:
        """``r(phi) = phi (rho_s - rho_f) / rho_m``: the buoyant weight over the mixture's."""
        return float(buoyant_fraction(phi, self.mat.rho_s, self.mat.rho_f))

    def weight(self, h: float, phi: float, theta: float) -> float:
        """``P = (rho_s - rho_f) g cos(theta) phi h`` (Pa)."""
        return (self.mat.rho_s - self.mat.rho_f) * self.g * math.cos(theta) * phi * h

    def _closure(
        self, h: float, phi: float, u: float, p_e: float | None, theta: float
    ) -> tuple[BasalClosure, float]:
        """The closure at ``(h, phi, u)`` and its volume rate ``V = -p_e / B``: with ``p_e =
        None`` the closure's root (``p_e = -B Phi``), otherwise at that pore pressure."""
        P = self.weight(h, phi, theta)
        gamma = SHEAR * abs(u) / h
        beta = self.mat.drag(phi)
        B = darcy_coefficient(beta, h, phi)
        p_s = closure_pressure(self.mat, phi, gamma, B, P) if p_e is None else P - p_e
        cl = closure_at(self.mat, phi, gamma, beta, P, p_s)
        return cl, -cl.p_e / B

    @property
    def base(self) -> np.ndarray:
        """``q0 = (h, phi, u, p_e)`` with the closure's pore pressure."""
        return np.array(
            [self.h, self.phi, self.u, self._closure(self.h, self.phi, self.u, None, self.slope)[0].p_e]
        )

    def rates(self, q: np.ndarray, theta: float) -> np.ndarray:
        """The source terms ``(h V, -phi V, du/dt, relaxation)`` at ``q = (h, phi, u, p_e)``:
        the last is ``-(p_e / B + Phi)`` (``alpha d_t p_e``; ``0`` defines the closure)."""
        h, phi, u, p_e = (float(v) for v in q)
        cl, V = self._closure(h, phi, u, p_e, theta)
        rho_m = self.density(phi)
        du = (
            self.reduction(phi) * self.g * math.sin(theta)
            - cl.tau_b / (rho_m * h)
            - self.mat.rho_f * V * u / (2.0 * rho_m)
        )
        return np.array([h * V, -phi * V, du, V - cl.dilation])

    def jacobian(self, F: float = 1.0) -> np.ndarray:
        """``J = d(rates)/dq`` (4 x 4) at the base state, by central differences; with
        ``F != 1`` the Darcy outflow of a perturbation of the pore pressure is that of a
        mode drained laterally too, ``d V / d p_e = -1 / (B F)``."""
        theta, q0 = self.slope, self.base
        scale = np.array([self.h, self.phi, self.u, self.weight(self.h, self.phi, theta)])
        J = np.empty((4, 4))
        for j in range(4):
            step = RELATIVE_STEP * scale[j]
            up, down = q0.copy(), q0.copy()
            up[j] += step
            down[j] -= step
            J[:, j] = (self.rates(up, theta) - self.rates(down, theta)) / (2.0 * step)
        if F != 1.0:
            B = darcy_coefficient(self.mat.drag(self.phi), self.h, self.phi)
            rho_m = self.density(self.phi)
            by_volume_rate = np.array([self.h, -self.phi, -self.mat.rho_f * self.u / (2.0 * rho_m), 1.0])
            J[:, 3] += by_volume_rate * (1.0 - 1.0 / F) / B
        return J

    def wave_speed(self) -> float:
        """``c = sqrt(g' h)``, ``g' = r0 g cos(theta)`` (``r0 = r(phi)`` of the layer)."""
        return math.sqrt(self.reduction(self.phi) * self.g * math.cos(self.slope) * self.h)

    def symbol(self, k: float) -> np.ndarray:
        """The linearised operator of the mode ``exp(i k x)``: ``lambda q = S q`` in
        ``(h, phi, u)`` at ``alpha = 0`` (the pore pressure eliminated), in
        ``(h, phi, u, p_e)`` otherwise (3 x 3 or 4 x 4, complex)."""
        F = float(lateral_drainage(k * self.h)) if self.drainage else 1.0
        J = self.jacobian(F)
        c2 = self.wave_speed() ** 2
        A = np.zeros((4, 4))
        A[0, 0] = A[1, 1] = A[2, 2] = A[3, 3] = self.u
        A[0, 2], A[2, 0] = self.h, c2 / self.h
        S = -1j * k * A + J.astype(complex)
        S[2, 2] -= self.nu * k * k
        if self.alpha > 0.0:
            S[3] = (-1j * k * A[3] * self.alpha + J[3]) / self.alpha
            return S
        # alpha = 0: J[3] q = 0 is the closure's constraint; eliminate p_e
        column = S[:3, 3]
        return S[:3, :3] - np.outer(column, J[3, :3]) / J[3, 3]

    def growth(self, k: np.ndarray | float) -> np.ndarray:
        """``max Re lambda`` (1/s) over the modes at each wavenumber ``k`` (1/m)."""
        ks = np.atleast_1d(np.asarray(k, dtype=float))
        return np.array([np.linalg.eigvals(self.symbol(kk)).real.max() for kk in ks])

    def eigenvalues(self, k: float) -> np.ndarray:
        """The eigenvalues of :meth:`symbol` at ``k``, by decreasing real part."""
        lam = np.linalg.eigvals(self.symbol(k))
        return lam[np.argsort(-lam.real)]

    def short_wave_limit(self) -> float:
        """``lim_{k -> oo} Re lambda`` of the faster-growing of the two waves at
        ``alpha = 0``, ``nu = 0`` and without lateral drainage:
        ``(J_hh + J_uu) / 2 + |c J_hu / h + h J_uh / c| / 2`` of the Jacobian with the pore
        pressure eliminated."""
        Jfull = self.jacobian()
        J = Jfull[:3, :3] - np.outer(Jfull[:3, 3], Jfull[3, :3]) / Jfull[3, 3]
        c = self.wave_speed()
        return 0.5 * (J[0, 0] + J[2, 2]) + 0.5 * abs(c * J[0, 2] / self.h + self.h * J[2, 0] / c)

    def with_(self, **changes: float | bool) -> UniformMixture:
        """This state with ``changes`` (``alpha``, ``nu``, ``drainage``, ``u``, ...)."""
        return replace(self, **changes)  # type: ignore[arg-type]


def stress_slope(state: UniformMixture) -> tuple[float, float]:
    """``(d tau_b / d gamma, (K1 + K K2) eta_f)`` (Pa s) of the closure at the base state
    (``h``, ``phi`` held): the slope of the basal stress with the shear rate and its viscous
    part, by central differences."""
    theta = state.slope
    step = RELATIVE_STEP * state.u
    up = state._closure(state.h, state.phi, state.u + step, None, theta)[0].tau_b
    down = state._closure(state.h, state.phi, state.u - step, None, theta)[0].tau_b
    viscous = (state.mat.K1 + state.mat.K * state.mat.K2) * state.mat.eta_f
    return (up - down) / (2.0 * step) * state.h / SHEAR, viscous


def cutoff(state: UniformMixture, k_min: float = 1e-2, k_max: float = 1e10) -> float:
    """The smallest wavenumber (1/m) above which no mode grows (``max Re lambda <= 0``),
    by bisection in ``log k`` from a scan of ``[k_min, k_max]``; ``inf`` where the
    growth rate stays positive up to ``k_max`` (no short-wave cut-off), ``k_min`` where no
    mode grows there."""
    ks = np.geomspace(k_min, k_max, 81)
    rates = state.growth(ks)
    if rates[-1] > 0.0:
        return math.inf
    growing = np.flatnonzero(rates > 0.0)
    if not growing.size:
        return k_min
    lo, hi = ks[growing[-1]], ks[growing[-1] + 1]
    for _ in range(50):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if state.growth(mid)[0] > 0.0 else (lo, mid)
    return hi


RONDON_2011_BEADS = MixtureMaterial(
    rho_s=2500.0, d=225e-6, rho_f=1010.0, eta_f=0.0121, delta_deg=22.5, phi_c=0.582, K=4.09, K1=90.5, K2=25.0
)
"""The grains, fluid and closure constants of ``scenarios/submarine_collapse_loose.yaml``
(Rondon, Pouliquen & Aussillous 2011, with the closure constants of Pailha & Pouliquen 2009)."""


def deposit_state(alpha: float = 0.0, **changes: float | bool) -> UniformMixture:
    """The loose deposit of the submarine collapse as a uniform layer: 16 mm at 0.552 (the
    body of the final deposit on 240 cells, docs/mixture.md), sliding at 0.2 mm/s, where the
    closure's basal stress has fallen to about half its static value."""
    return UniformMixture(RONDON_2011_BEADS, 0.016, 0.552, 2e-4, alpha=alpha).with_(**changes)


@dataclass(frozen=True)
class Measured:
    """A growth rate measured on the time loop: ``rate`` (1/s) the slope of
    ``log |u_k|`` over the second half of the run, ``predicted`` the mode's
    ``Re lambda``, ``steps`` taken, ``drift`` the relative change of the unperturbed
    run's velocity (the uniform state's own instability and compaction)."""

    rate: float
    predicted: float
    steps: int
    drift: float


def measured_growth(
    state: UniformMixture,
    wavelength: float,
    cells: int,
    dt: float,
    e_folds: float = 4.0,
    amplitude: float = 1e-6,
) -> Measured:
    """Run the time loop (one layer, periodic, ``cells`` cells over one ``wavelength``,
    steps of ``dt``, Newton tolerance 1e-13) from the uniform ``state`` perturbed by
    ``amplitude`` times its fastest-growing mode at ``k = 2 pi / wavelength`` (the
    eigenvector of :meth:`UniformMixture.symbol`, relative to the state, cell-averaged),
    and beside it from the state unperturbed, for ``e_folds / Re lambda`` seconds; the
    rate is that of the ``k`` Fourier coefficient of the difference of their velocities."""
    k = 2.0 * math.pi / wavelength
    lam, vectors = np.linalg.eig(state.symbol(k))
    mode = int(np.argmax(lam.real))
    q0 = state.base
    n = vectors.shape[0]
    shape = vectors[:, mode] / q0[:n]
    shape /= np.abs(shape).max()
    left = np.arange(cells) * wavelength / cells
    average = (np.exp(1j * k * (left + wavelength / cells)) - np.exp(1j * k * left)) / (
        1j * k * wavelength / cells
    )
    runs = [
        _periodic_run(state, wavelength, cells, [(eps * s * average).real for s in shape])
        for eps in (0.0, amplitude)
    ]
    base, perturbed = runs
    end = e_folds / lam[mode].real
    times, logs = [], []
    while perturbed.t < end:
        until = perturbed.t + dt
        base.step(until)
        perturbed.step(until)
        coefficient = np.sum((perturbed.u[0] - base.u[0]) * np.conj(average)) / cells
        times.append(perturbed.t)
        logs.append(math.log(abs(coefficient)))
    half = len(times) // 2
    rate = float(np.polyfit(times[half:], logs[half:], 1)[0])
    drift = abs(float(base.u[0, 0]) - state.u) / state.u
    return Measured(rate, float(lam[mode].real), len(times), drift)


def _periodic_run(state: UniformMixture, length: float, cells: int, relative: list[np.ndarray]) -> Simulation:
    """The time loop of ``state`` on a periodic domain of ``cells`` cells over ``length``,
    on the bed slope of :attr:`UniformMixture.slope`, its unknowns ``(h, phi, u[, p_e])``
    multiplied by ``1 + relative``."""
    mat = state.mat
    fluid = MixtureConfig(
        fluid_density=mat.rho_f, fluid_viscosity=mat.eta_f, phi_critical=mat.phi_c, dilatancy=mat.K,
        critical_shift=mat.K2, kozeny=mat.kozeny, compressibility=state.alpha if state.alpha > 0.0 else None,
    )  # fmt: skip
    grains = Material(density=mat.rho_s * state.phi, grain_diameter=mat.d, particle_density=mat.rho_s)
    config = SimulationConfig(
        x_min=0.0, x_max=length, cells=cells, fractions=(1.0,), material=grains, gravity=state.g,
        slope_deg=math.degrees(state.slope), left="periodic", right="periodic", mixture=fluid,
        initial=(InitialEntry("layer", thickness=state.h, phi=state.phi),),
        numerics=Numerics(tolerance=1e-13),
    )  # fmt: skip
    sim = Simulation(config, DilatantCoulomb(delta_deg=mat.delta_deg, K1=mat.K1))
    mixture = sim.mixture
    assert mixture is not None  # a config with a mixture
    q0 = state.base
    h = q0[0] * (1.0 + relative[0])
    sim.h[:] = h
    mixture.solid[0, :] = q0[1] * (1.0 + relative[1]) * h
    sim.u[0, :] = q0[2] * (1.0 + relative[2])
    if state.alpha > 0.0:
        mixture.pore_pressure[0, :] = q0[3] * (1.0 + relative[3])
    mixture.reset(0)
    return sim
