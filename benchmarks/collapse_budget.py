"""Analysis: the energy budget of the channel collapse, and the power the stresses of the
mu(I) tensor law that the model leaves out (the longitudinal normal stress, the shear stress
on vertical planes) would dissipate if the model had them.

Runs the recommended collapse (``scenarios/column_collapse_channel.yaml`` as the validation
case ``collapse_channel`` sets it up at aspect ratio ``a`` with cells ``dx``, stepped as the
validation runs it, to its output times) and, after the first step past every ``--interval``
seconds, evaluates on the state the engine holds (h, u, w and the yield pressures with the
non-hydrostatic part q).  ``--clip`` cuts the steps at the sample times instead, which
changes the run: a step of 1e-7 s leaves a non-hydrostatic pressure of up to 1e4 m^2/s^2,
which enters the next vertical step's yield stresses.  The measures:

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
- on the same faces, the dissipation ``2 mu(I) p |D|`` of the tensor law with the full shear
  rate ``D_xz = (du/dz + dw/dx) / 2`` (the stress ``tau_zx`` on vertical planes, which the
  model's vertical momentum lacks), without ``D_xx`` and with it; ``w`` is the layer-mean
  vertical velocity of the non-hydrostatic pressure (at the layer centres, like ``u``;
  Stelling & Zijlema 2003), ``dw/dx`` at fixed ``z`` like ``du/dx``, and ``w = 0`` at the
  flat no-slip bed;
- the potential energy ``rho g sum h^2/2 dx`` (flat bed) and the kinetic energy
  ``rho/2 sum l_a h (u_a^2 + w_a^2) dx``; what the shear power does not account for of their
  loss is dissipated by the numerics (transport, projection of the pressure).

Phases: the fall, up to the largest kinetic energy, and the spreading, after it.  Energies
are given as fractions of the initial potential energy; the dissipation the tensor law would
add is its dissipation on the faces less the model's shear power there.  The front is the
point where ``h`` falls through ``numerics.front_threshold``, as the validation measures it.

    python benchmarks/collapse_budget.py [--ratios 2 7] [--dx 1e-3 5e-4] [--interval 0.001]
        [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import subprocess
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, TypeVar

import numpy as np

from multilayer.app.runner import output_times
from multilayer.app.simulation import Simulation
from multilayer.engine.vertical.stresses import ColumnStresses
from multilayer.io import observables
from multilayer.validation.cases import collapse_channel
from multilayer.validation.cases.column_collapse import L0
from multilayer.validation.runs import Run


class Timed(Protocol):
    """A sample at its time ``t`` (s)."""

    @property
    def t(self) -> float: ...


S = TypeVar("S", bound=Timed)


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
    vertical_shear: float
    """The same with ``D_xx = 0`` and ``D_xz = (du/dz + dw/dx) / 2``."""
    full: float
    """The same with ``D_xx`` and ``D_xz = (du/dz + dw/dx) / 2``: the full tensor law."""
    front: float
    """The deposit tip (m), 3 grain diameters above the bed as the validation measures it."""


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
    dwdx: np.ndarray
    """(L, F) dw/dx at fixed z, ``dw/dx|_sigma - (dz/dx|_sigma) dw/dz``."""
    along: np.ndarray
    """(L, F) ``du/dx`` along each layer (at fixed sigma)."""
    slope: np.ndarray
    """(L, F) ``dz/dx`` of the layer centres."""
    centre_pressure: np.ndarray
    """(L, W) the mean layer pressures of the wet columns (W of them)."""


def centres(values: np.ndarray) -> np.ndarray:
    """The means over the layers of ``values`` (L, W) on their bottom interfaces (zero above
    the top one)."""
    return 0.5 * (values + np.vstack([values[1:], np.zeros((1, values.shape[1]))]))


def faces(sim: Simulation, cs: ColumnStresses, uw: np.ndarray, ww: np.ndarray) -> Faces:
    """The faces of the state of ``sim`` with the column stresses ``cs`` and the velocities
    ``uw``, ``ww`` (L, W) of its wet columns."""
    h, wet = sim.h, sim.h > sim.dry
    hw, bw = h[wet], sim.bed[wet]
    pairs = wet[:-1] & wet[1:]
    left = np.flatnonzero(pairs)
    p_centre = centres(cs.pressure)
    spacing = np.where(cs.spacing > 0, cs.spacing, 1.0)
    index = np.cumsum(wet) - 1  # column -> its position among the wet ones
    i, j = index[left], index[left + 1]
    slope = (bw[j] - bw[i] + sim.sigma[:, None] * (hw[j] - hw[i])) / sim.dx

    def vertical(v: np.ndarray) -> np.ndarray:
        """d/dz at the faces' layer centres of ``v`` (zero at the no-slip flat bed)."""
        at_centres = centres(np.diff(v, axis=0, prepend=0.0) / spacing)
        return 0.5 * (at_centres[:, i] + at_centres[:, j])

    return Faces(
        left=left,
        h=0.5 * (hw[i] + hw[j]),
        x=0.5 * (sim.vertical.stresses.x[wet][i] + sim.vertical.stresses.x[wet][j]),
        pressure=0.5 * (p_centre[:, i] + p_centre[:, j]),
        dudz=vertical(uw),
        dwdx=(ww[:, j] - ww[:, i]) / sim.dx - slope * vertical(ww),
        along=(uw[:, j] - uw[:, i]) / sim.dx,
        slope=slope,
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
    f = faces(sim, cs, uw, w[:, wet])
    hf, xf, p_f, dudz_f, along = f.h, f.x, f.pressure, f.dudz, f.along

    def power(d_xx: np.ndarray) -> float:
        norm = np.sqrt(d_xx**2 + (0.5 * dudz_f) ** 2)
        mu_p = stresses.bulk_stress(2.0 * norm, p_f, hf, xf)
        return float(
            np.sum(2.0 * mu_p * np.divide(d_xx**2, norm, out=np.zeros_like(norm), where=norm > 0) * l * hf)
            * dx
        )

    def dissipation(d_xx: np.ndarray, d_xz: np.ndarray) -> float:
        """``2 mu(I) p |D|`` of the tensor law on the faces (``I`` from ``2 |D|``)."""
        norm = np.sqrt(d_xx**2 + d_xz**2)
        return float(np.sum(2.0 * stresses.bulk_stress(2.0 * norm, p_f, hf, xf) * norm * l * hf) * dx)

    d_xx = along - f.slope * dudz_f
    d_xz = 0.5 * (dudz_f + f.dwdx)
    return Sample(
        t=sim.t,
        potential=float(rho * sim.g_n * np.sum(0.5 * h**2 + sim.bed * h) * dx),
        kinetic=float(0.5 * rho * np.sum(l * h * (u**2 + w**2)) * dx),
        bed=float(shear[0].sum()),
        internal=float(shear[1:].sum()),
        walls=float(np.sum((threshold + viscous) * np.abs(held)) * dx),
        normal=power(d_xx),
        along_sigma=power(along),
        face_shear=dissipation(np.zeros_like(d_xx), 0.5 * dudz_f),
        tensor=dissipation(d_xx, 0.5 * dudz_f),
        vertical_shear=dissipation(np.zeros_like(d_xx), d_xz),
        full=dissipation(d_xx, d_xz),
        front=observables.tip(sim.x, h, stresses.material.grain_diameter),
    )


def budget(
    a: float, dx: float, interval: float, sets: Sequence[str] = (), clip: bool = False
) -> list[Sample]:
    """The samples of the run at aspect ratio ``a`` with cells ``dx`` (collapse_channel.run)
    and the overrides ``sets``: after the first step past every ``interval``, the steps those
    of the validation run (to its output times, runner.output_times); with ``clip``, at every
    ``interval`` exactly, the steps cut there (which changes the run: module docstring)."""
    r = collapse_channel.run(a, dx)
    scenario = Run(r.name, r.scenario, (*r.overrides, *sets)).load()
    sim = Simulation(scenario)
    end = collapse_channel.end_time(a)
    if clip:
        samples = [sample(sim)]
        for t in np.arange(1, round(end / interval) + 1) * interval:
            sim.advance(float(t))
            samples.append(sample(sim))
        return samples
    return on_own_steps(sim, end, interval, sample)


def on_own_steps(sim: Simulation, end: float, interval: float, measure: Callable[[Simulation], S]) -> list[S]:
    """``measure`` of ``sim`` now, after the first step past every ``interval`` and at
    ``end``, ``sim`` stepped as the validation run steps it (to its output times,
    runner.output_times): sampling changes nothing of the run, where a step cut short at a
    sample time would."""
    samples = [measure(sim)]

    def record(sim: Simulation, dt: float) -> None:
        if sim.t >= samples[-1].t + interval:
            samples.append(measure(sim))

    for t in output_times(end, sim.scenario.time.output_interval):
        sim.advance(float(t), on_step=record)
    if samples[-1].t < sim.t:
        samples.append(measure(sim))
    return samples


def integral(samples: list[Sample], name: str, start: int, stop: int) -> float:
    """The trapezoidal time integral of the power ``name`` over samples ``start..stop``."""
    part = samples[start : stop + 1]
    return float(np.trapezoid([getattr(s, name) for s in part], [s.t for s in part]))


POWERS = ("bed", "internal", "walls", "normal", "face_shear", "tensor", "vertical_shear", "full")
"""The powers of :class:`Sample` integrated over the phases."""
ADDED = {"vertical_shear": "dw/dx in D_xz", "tensor": "D_xx", "full": "both"}
"""The dissipations of the tensor law on the faces, less the model's shear power there."""


def phases(a: float, samples: list[Sample]) -> dict[str, dict[str, float]]:
    """The budget of the fall, the spreading and the whole run, in fractions of the initial
    potential energy (module docstring); the tips over L0."""
    peak = int(np.argmax([s.kinetic for s in samples]))
    scale = samples[0].potential
    out = {}
    for label, (start, stop) in (
        ("fall", (0, peak)),
        ("spreading", (peak, len(samples) - 1)),
        ("run", (0, len(samples) - 1)),
    ):
        first, last = samples[start], samples[stop]
        lost = first.potential + first.kinetic - last.potential - last.kinetic
        e = {name: integral(samples, name, start, stop) for name in POWERS}
        model = e["bed"] + e["internal"] + e["walls"]
        out[label] = {
            "start": first.t,
            "end": last.t,
            "kinetic_end": last.kinetic / scale,
            "lost": lost / scale,
            **{name: e[name] / scale for name in ("bed", "internal", "walls")},
            "model": model / scale,
            "numerics": (lost - model) / scale,
            "face_shear": e["face_shear"] / scale,
            "normal": e["normal"] / scale,
            **{f"added_{name}": (e[name] - e["face_shear"]) / scale for name in ADDED},
            "tip_start": (first.front - L0) / L0 if start else 0.0,
            "tip_end": (last.front - L0) / L0,
        }
    spreading, run = out["spreading"], out["run"]
    excess = run["tip_end"] - collapse_channel.law(a, collapse_channel.LAWS[collapse_channel.REFERENCE])
    per_l0 = spreading["lost"] / (spreading["tip_end"] - spreading["tip_start"])
    run |= {"excess_over_law": excess, "spreading_loss_per_l0": per_l0, "excess_energy": excess * per_l0}
    return out


def report(a: float, dx: float, samples: list[Sample]) -> dict[str, dict[str, float]]:
    """Print the budget of ``phases`` and return it."""
    out = phases(a, samples)
    peak = max(samples, key=lambda s: s.kinetic)
    print(
        f"a = {a:g}, dx = {dx * 1e3:g} mm: E_p(0) = {samples[0].potential:.4g} J/m, largest kinetic energy "
        f"{peak.kinetic / samples[0].potential:.1%} of it at t = {peak.t:.3f} s; fractions of E_p(0):"
    )
    for label, e in out.items():
        added = ", ".join(f"{text} {e['added_' + name]:.2%}" for name, text in ADDED.items())
        print(
            f"  {label:9s} t = {e['start']:.3f}-{e['end']:.3f} s: lost {e['lost']:.1%}; "
            f"model {e['model']:.1%} "
            f"(bed {e['bed']:.1%}, internal {e['internal']:.1%}, walls {e['walls']:.1%}), numerics "
            f"{e['numerics']:.1%}; shear on the faces {e['face_shear']:.1%}, tensor law adds: {added} "
            f"(power of tau_xx {e['normal']:.2%}); tip (x - L0)/L0 {e['tip_start']:.2f} -> {e['tip_end']:.2f}"
        )
    run = out["run"]
    print(
        f"  run-out {run['tip_end']:.2f} L0, {run['excess_over_law']:+.2f} L0 over law B; "
        f"the spreading loses "
        f"{run['spreading_loss_per_l0']:.1%} of E_p(0) per L0 of the tip's advance: the excess is "
        f"{run['excess_energy']:.1%} of E_p(0), the full tensor law adds {run['added_full']:.1%} "
        f"({out['fall']['added_full']:.1%} in the fall)"
    )
    ratios = [s.normal / (s.bed + s.internal + s.walls) for s in samples if s.bed + s.internal + s.walls > 0]
    print(
        f"  instantaneous P_xx / P_xz (walls included): largest {max(ratios):.1%}, "
        f"median {np.median(ratios):.1%}"
    )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ratios", type=float, nargs="+", default=[2.0, 7.0], help="aspect ratios a")
    parser.add_argument(
        "--dx",
        type=float,
        nargs="+",
        default=[1e-3],
        help="cell sizes (m), divisors of collapse_channel.X_MAX",
    )
    parser.add_argument("--interval", type=float, default=0.001, help="time between samples (s)")
    parser.add_argument(
        "--clip", action="store_true", help="cut the steps at the sample times (changes the run)"
    )
    parser.add_argument("--set", action="append", default=[], help="an override KEY=VALUE of the scenario")
    parser.add_argument("--json", type=Path, help="write the budgets here, with the commit")
    args = parser.parse_args()
    records = []
    for a in args.ratios:
        for dx in args.dx:
            samples = budget(a, dx, args.interval, args.set, args.clip)
            records.append({"a": a, "dx": dx, "sets": args.set, "clip": args.clip, **report(a, dx, samples)})
            if args.json:  # after every run: a long study keeps what it measured
                commit = subprocess.run(
                    ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True
                )
                what = {"command": "python benchmarks/collapse_budget.py", "commit": commit.stdout.strip()}
                args.json.write_text(
                    json.dumps({**what, "interval": args.interval, "runs": records}, indent=1) + "\n"
                )


if __name__ == "__main__":
    main()
