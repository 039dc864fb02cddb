"""Analysis: the energy budget of the channel collapse, and the power the longitudinal normal
stress would dissipate if the model had it.

Runs the recommended collapse (``scenarios/column_collapse_channel.yaml`` as the validation
case ``collapse_channel`` sets it up at aspect ratio ``a`` with cells ``dx``) and, every
``--interval`` seconds, evaluates on the state the engine holds (h, u, w and the yield
pressures with the non-hydrostatic part q):

- the shear power of the model, ``P_xz = sum_k tau_k |u_k - u_(k-1)|`` over the interfaces
  (``k = 0`` the no-slip bed), ``tau_k = kappa_k + |tau_v,k|`` of the bulk law, and the side
  walls' ``sum_a (w_a + |F_v,a|) |u_a|`` (Jop, Forterre & Pouliquen 2005), per unit width,
  with the velocities of the last vertical step (those the stresses act on; the projection
  of the pressure then moves the layers of a plug apart a little);
- the power of the deviatoric normal stresses the model leaves out, ``P_xx = sum 2 mu(I) p
  D_xx^2 / |D|`` (``tau_xx D_xx + tau_zz D_zz`` of the Drucker-Prager / mu(I) stress
  ``tau = mu(I) p D / |D|``, Lagree, Staron & Popinet 2011, eq. 2.1-2.3), ``|D| = sqrt(D_xx^2 +
  D_xz^2)``, ``D_xz = du/dz / 2`` and ``I = 2 |D| d / sqrt(p / rho_p)``, with ``D_xx = du/dx`` at
  fixed ``z`` from the sigma coordinates, ``du/dx|_sigma - (dz/dx|_sigma) du/dz``, on the faces
  between two columns holding material;
- on the same faces, the bulk shear power ``mu(I) p |du/dz|`` of the model and the dissipation
  ``2 mu(I) p |D|`` of the tensor law, which is less than their sum (``tau_xz`` falls to
  ``mu(I) p D_xz / |D|`` where the material stretches);
- the potential energy ``rho g sum h^2/2 dx`` (flat bed) and the kinetic energy
  ``rho/2 sum l_a h (u_a^2 + w_a^2) dx``; what the shear power does not account for of their
  loss is dissipated by the numerics (transport, projection of the pressure).

Phases: the fall, up to the largest kinetic energy, and the spreading, after it.

    python benchmarks/collapse_budget.py [--ratios 2 7] [--dx 1e-3] [--interval 0.001]
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from multilayer.app.simulation import Simulation
from multilayer.engine.vertical.stresses import ColumnStresses
from multilayer.validation.cases import collapse_channel
from multilayer.validation.runs import Run


@dataclass
class Sample:
    """The budget at one time (W per metre of channel width; J per metre)."""

    t: float
    potential: float
    kinetic: float
    bed: float
    internal: float
    walls: float
    normal: float
    along_sigma: float
    """``P_xx`` with ``D_xx = du/dx|_sigma`` (without the slope of the layers)."""
    face_shear: float
    """The bulk shear power ``mu(I) p |du/dz|`` on the same faces as ``P_xx``."""
    tensor: float
    """The dissipation ``2 mu(I) p |D|`` of the tensor law on those faces (``I`` from ``2|D|``)."""


@dataclass
class Faces:
    """The faces between two columns holding material (thicker than the dry threshold)."""

    left: np.ndarray
    """(F,) the column left of each face."""
    h: np.ndarray
    """(F,) the mean thickness of its two columns."""
    x: np.ndarray
    """(F,) its position."""
    pressure: np.ndarray
    """(L, F) the mean layer pressures of its two columns (the layers' mean of their interfaces)."""
    dudz: np.ndarray
    """(L, F) du/dz at the layer centres, the mean of its two columns."""
    along: np.ndarray
    """(L, F) ``du/dx`` along each layer (at fixed sigma)."""
    slope: np.ndarray
    """(L, F) ``dz/dx`` of the layer centres."""
    centre_pressure: np.ndarray
    """(L, W) the mean layer pressures of the wet columns (W of them)."""


def faces(sim: Simulation, cs: ColumnStresses, uw: np.ndarray) -> Faces:
    """The faces of the state of ``sim`` with the column stresses ``cs`` and velocities ``uw``
    (L, W) of its wet columns."""
    h, wet = sim.h, sim.h > sim.dry
    hw, bw = h[wet], sim.bed[wet]
    pairs = wet[:-1] & wet[1:]
    left = np.flatnonzero(pairs)
    p_centre = 0.5 * (cs.pressure + np.vstack([cs.pressure[1:], np.zeros((1, hw.size))]))
    spacing = np.where(cs.spacing > 0, cs.spacing, 1.0)
    gradient = np.diff(uw, axis=0, prepend=0.0) / spacing  # du/dz at the interfaces
    dudz = 0.5 * (gradient + np.vstack([gradient[1:], np.zeros((1, hw.size))]))  # layer centres
    index = np.cumsum(wet) - 1  # column -> its position among the wet ones
    i, j = index[left], index[left + 1]
    return Faces(
        left=left,
        h=0.5 * (hw[i] + hw[j]),
        x=0.5 * (sim.vertical.stresses.x[wet][i] + sim.vertical.stresses.x[wet][j]),
        pressure=0.5 * (p_centre[:, i] + p_centre[:, j]),
        dudz=0.5 * (dudz[:, i] + dudz[:, j]),
        along=(uw[:, j] - uw[:, i]) / sim.dx,
        slope=(bw[j] - bw[i] + sim.sigma[:, None] * (hw[j] - hw[i])) / sim.dx,
        centre_pressure=p_centre,
    )


def sample(sim: Simulation) -> Sample:
    """The budget of the state of ``sim`` now (module docstring)."""
    stresses, rho = sim.vertical.stresses, sim.vertical.stresses.material.density
    h, u, w, dx, l = sim.h, sim.u, sim.w, sim.dx, sim.fractions[:, None]
    wet = h > sim.dry
    cs = stresses.columns(h, wet, rest=sim.state.rest, yield_gravity=sim.pressure.yield_gravity(sim.state, h))
    held = sim.state.fields.get("newton_seed", u)  # the vertical step's velocities
    jump = np.abs(np.diff(held[:, wet], axis=0, prepend=0.0))
    tau = cs.kappa + stresses.viscous_stresses(cs, held[:, wet])[0]
    shear = tau * jump * dx
    threshold, viscous = stresses.wall_forces(h, held)
    uw = u[:, wet]
    f = faces(sim, cs, uw)
    hf, xf, p_f, dudz_f, along = f.h, f.x, f.pressure, f.dudz, f.along

    def power(d_xx: np.ndarray) -> float:
        norm = np.sqrt(d_xx**2 + (0.5 * dudz_f) ** 2)
        mu_p = stresses.bulk_stress(2.0 * norm, p_f, hf, xf)
        return float(
            np.sum(2.0 * mu_p * np.divide(d_xx**2, norm, out=np.zeros_like(norm), where=norm > 0) * l * hf)
            * dx
        )

    d_xx = along - f.slope * dudz_f
    norm = np.sqrt(d_xx**2 + (0.5 * dudz_f) ** 2)
    rate = np.abs(dudz_f)
    return Sample(
        t=sim.t,
        potential=float(rho * sim.g_n * np.sum(0.5 * h**2 + sim.bed * h) * dx),
        kinetic=float(0.5 * rho * np.sum(l * h * (u**2 + w**2)) * dx),
        bed=float(shear[0].sum()),
        internal=float(shear[1:].sum()),
        walls=float(np.sum((threshold + viscous) * np.abs(held)) * dx),
        normal=power(d_xx),
        along_sigma=power(along),
        face_shear=float(np.sum(stresses.bulk_stress(rate, p_f, hf, xf) * rate * l * hf) * dx),
        tensor=float(np.sum(2.0 * stresses.bulk_stress(2.0 * norm, p_f, hf, xf) * norm * l * hf) * dx),
    )


def budget(a: float, dx: float, interval: float, sets: Sequence[str] = ()) -> list[Sample]:
    """The samples of the run at aspect ratio ``a`` with cells ``dx`` (collapse_channel.run)
    and the overrides ``sets``."""
    r = collapse_channel.run(a, dx)
    sim = Simulation(Run(r.name, r.scenario, (*r.overrides, *sets)).load())
    end = collapse_channel.end_time(a)
    samples = [sample(sim)]
    for t in np.arange(1, round(end / interval) + 1) * interval:
        sim.advance(float(t))
        samples.append(sample(sim))
    return samples


def integral(samples: list[Sample], name: str, start: int, stop: int) -> float:
    """The trapezoidal time integral of the power ``name`` over samples ``start..stop``."""
    part = samples[start : stop + 1]
    return float(np.trapezoid([getattr(s, name) for s in part], [s.t for s in part]))


def report(a: float, dx: float, samples: list[Sample]) -> None:
    peak = int(np.argmax([s.kinetic for s in samples]))
    first, last = samples[0], samples[-1]
    print(
        f"a = {a:g}, dx = {dx * 1e3:g} mm: E_p(0) = {first.potential:.4g} J/m, largest kinetic energy "
        f"{samples[peak].kinetic:.4g} J/m at t = {samples[peak].t:.3f} s, end t = {last.t:.3f} s"
    )
    powers = ("bed", "internal", "walls", "normal", "along_sigma", "face_shear", "tensor")
    for label, (start, stop) in (("fall", (0, peak)), ("spreading", (peak, len(samples) - 1))):
        released = samples[start].potential + samples[start].kinetic
        lost = released - samples[stop].potential - samples[stop].kinetic
        e = {name: integral(samples, name, start, stop) for name in powers}
        shear = e["bed"] + e["internal"] + e["walls"]
        print(
            f"  {label:9s} t = {samples[start].t:.3f}-{samples[stop].t:.3f} s: energy lost {lost:.4g} J/m; "
            f"shear bed {e['bed']:.4g}, internal {e['internal']:.4g}, walls {e['walls']:.4g} "
            f"(sum {shear:.4g}, {shear / lost:.0%} of the loss; numerics {1 - shear / lost:.0%}); "
            f"normal stress would add {e['normal']:.4g} = {e['normal'] / shear:.1%} of the shear, "
            f"{e['normal'] / samples[peak].kinetic:.1%} of the largest kinetic energy "
            f"(with D_xx = du/dx|_sigma: {e['along_sigma'] / shear:.1%} of the shear); on the faces, the "
            f"tensor law dissipates {e['tensor']:.4g} = "
            f"{e['tensor'] / (e['face_shear'] + e['normal']):.0%} of shear + normal there "
            f"({e['face_shear']:.4g} + {e['normal']:.4g})"
        )
    ratios = [s.normal / (s.bed + s.internal + s.walls) for s in samples if s.bed + s.internal + s.walls > 0]
    print(
        f"  instantaneous P_xx / P_xz (walls included): largest {max(ratios):.1%}, "
        f"median {np.median(ratios):.1%}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ratios", type=float, nargs="+", default=[2.0, 7.0], help="aspect ratios a")
    parser.add_argument(
        "--dx", type=float, default=1e-3, help="cell size (m), one of collapse_channel.X_MAX's divisors"
    )
    parser.add_argument("--interval", type=float, default=0.001, help="time between samples (s)")
    parser.add_argument("--set", action="append", default=[], help="an override KEY=VALUE of the scenario")
    args = parser.parse_args()
    for a in args.ratios:
        report(a, args.dx, budget(a, args.dx, args.interval, args.set))


if __name__ == "__main__":
    main()
