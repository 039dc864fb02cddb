"""Analysis: how large the longitudinal deviatoric normal stress of the mu(I) tensor law is
against the pressure that spreads the channel collapse, and where it acts; and the run-outs
with and without it (``model.normal_stress``).

Diagnosis, a posteriori: runs the recommended collapse (``scenarios/column_collapse_channel.yaml``
as the validation case ``collapse_channel`` sets it up at aspect ratio ``a`` with cells ``dx``,
stepped as the validation runs it) and, after the first step past every ``--interval`` seconds,
evaluates on the state the engine holds, per layer ``l`` on
each face between two columns holding material (``collapse_budget.faces``)::

    tau_xx,l = mu(I_l) p_l D_xx,l / |D_l|,   D_xx = d_x u_l (along the layer),
    |D| = sqrt(D_xx^2 + D_xz^2),   D_xz = d_z u / 2,   I from the rate 2 |D|,

``mu(I) p`` the stress norm of the bulk law (``StressModel.bulk_stress``) at the layer's mean
yield pressure ``p`` (with the non-hydrostatic part), zero where the material is at rest
(``D = 0``).  The stress the shallow model leaves out is ``sigma_xx - sigma_zz = 2 tau_xx``
(``sigma_xx = -P + 2 tau_xx`` with ``P = -sigma_zz``, Lagree, Staron & Popinet 2011, eq.
2.1-2.3; the active and passive states of Savage & Hutter 1989): the x-force on a cell is
``T_i = Z_(i+1/2) - Z_(i-1/2)``, ``Z = sum_l 2 h_l tau_xx,l`` (N per metre of width), against
the pressure's ``G_i = -(Pi_(i+1) - Pi_(i-1)) / 2``, ``Pi = sum_l h_l p_l`` (the left wall
mirrors, dry columns hold none).  Per sample: the L1 norms ``sum |T|`` and ``sum |G|`` over the
flowing columns (``u != 0`` in a layer), split into the column (``x <= L0``) and the front
(``x > L0``); the net x-force on the front region (``sum T`` and ``sum G`` over it: positive
pushes the front forward), and the power of each force on it with the depth-averaged velocity.
Phases: the fall, up to the largest kinetic energy, and the spreading, after it; their
time integrals.  The stress is taken at the pressure ``P`` the model has, not at the mean
pressure ``P - tau_xx`` the option uses (whose active limit is ``mu P / (1 + mu)``): an upper
bound of the option's stress by about ``1 + mu``.  ``--stressed`` evaluates the same on the
runs with the option (``model.normal_stress``), whose state is that of the option's
velocities.

Run-outs: the validation case's runs with and without the option at ``--ratios`` on
``--cells``; the deposit tip (h = 1.5 mm) and the 95 %-mass front over L0, their ratios to
the glass beads' 2D law (law B), the volume change and the largest |u| at the end.

    python benchmarks/longitudinal_stress.py [--ratios 2 7] [--dx 2e-3] [--interval 0.005]
        [--cells 2e-3 1e-3] [--runs DIR] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from collapse_budget import faces, on_own_steps

from multilayer.app.simulation import Simulation
from multilayer.io import observables
from multilayer.validation.cases import collapse_channel
from multilayer.validation.cases.column_collapse import L0
from multilayer.validation.runs import Context


@dataclass
class Sample:
    """The two forces at one time (N per metre of channel width; W per metre)."""

    t: float
    kinetic: float
    term: float
    """``sum |T|`` over the flowing columns."""
    pressure: float
    """``sum |G|`` over the flowing columns."""
    term_column: float
    """``sum |T|`` over the flowing columns at ``x <= L0``."""
    pressure_column: float
    term_front: float
    """``sum T`` over the front region ``x > L0`` (its net x-force)."""
    pressure_front: float
    term_power: float
    """``sum T u_bar`` over the front region."""
    pressure_power: float
    front_faces: float
    """``sum h_l`` over the faces at ``x > L0`` where the material deforms (``|D| > 0``)."""
    front_compressed: float
    """The part of it where ``D_xx < 0`` (the passive state: ``sigma_xx`` above ``sigma_zz``)."""
    pairs: float
    """Pairs of neighbouring faces of a layer where the material deforms."""
    flips: float
    """Those where ``D_xx`` changes sign (the explicit ``tau_xx`` jumps by ``2 mu p``)."""
    head: float
    """The net x-force of the normal stress on the head, the material beyond ``x_h = L0 + 3/4
    (x_tip - L0)``: ``-Z(x_h)``, with the option that of its stress (``tau_xx`` of the cell at
    ``x_h``), without it ``T``'s."""
    head_pressure: float
    """The pressure's push on the head, ``Pi(x_h)``."""


INTEGRATED = (
    "term",
    "pressure",
    "term_column",
    "pressure_column",
    "term_front",
    "pressure_front",
    "term_power",
    "pressure_power",
    "front_faces",
    "front_compressed",
    "pairs",
    "flips",
    "head",
    "head_pressure",
)
"""The fields of :class:`Sample` integrated over time."""


def sample(sim: Simulation) -> Sample:
    """The forces of the state of ``sim`` now (module docstring)."""
    stresses = sim.vertical.stresses
    h, u, l = sim.h, sim.u, sim.fractions[:, None]
    wet = h > sim.dry
    cs = stresses.columns(h, wet, rest=sim.state.rest, yield_gravity=sim.pressure.yield_gravity(sim.state, h))
    f = faces(sim, cs, u[:, wet], sim.w[:, wet])
    norm = np.sqrt(f.along**2 + (0.5 * f.dudz) ** 2)
    mu_p = stresses.bulk_stress(2.0 * norm, f.pressure, f.h, f.x)
    tau_xx = mu_p * np.divide(f.along, norm, out=np.zeros_like(norm), where=norm > 0)
    z = np.zeros(h.size + 1)
    z[f.left + 1] = np.sum(2.0 * l * f.h * tau_xx, axis=0)
    term = np.diff(z)
    pi = np.zeros(h.size + 2)
    pi[1:-1][wet] = np.sum(l * h[wet] * f.centre_pressure, axis=0)
    pi[0] = pi[1]
    push = -(pi[2:] - pi[:-2]) / 2.0
    flowing = wet & np.any(u != 0.0, axis=0)
    column = flowing & (stresses.x <= L0)
    front = wet & (stresses.x > L0)
    mean = np.sum(l * u, axis=0)
    deforms = norm > 0
    weight = np.where(deforms & (f.x > L0), l * f.h, 0.0)
    neighbours = np.flatnonzero(np.diff(f.left) == 1)  # face k and k + 1 share a column
    both = deforms[:, neighbours] & deforms[:, neighbours + 1]
    flip = both & (f.along[:, neighbours] * f.along[:, neighbours + 1] < 0)
    tip = observables.tip(stresses.x, h, sim.scenario.material.grain_diameter)
    k = int(np.argmin(np.abs(stresses.x - (L0 + 0.75 * (tip - L0)))))
    option = sim.normal_stress
    head = z[k] if option is None else 2.0 * np.sum(l[:, 0] * h[k] * option.tau_xx[:, k])
    rho = stresses.material.density
    return Sample(
        t=sim.t,
        kinetic=float(0.5 * rho * np.sum(l * h * (u**2 + sim.w**2)) * sim.dx),
        term=float(np.abs(term[flowing]).sum()),
        pressure=float(np.abs(push[flowing]).sum()),
        term_column=float(np.abs(term[column]).sum()),
        pressure_column=float(np.abs(push[column]).sum()),
        term_front=float(term[front].sum()),
        pressure_front=float(push[front].sum()),
        term_power=float((term * mean)[front].sum()),
        pressure_power=float((push * mean)[front].sum()),
        front_faces=float(weight.sum()),
        front_compressed=float(weight[f.along < 0].sum()),
        pairs=float(both.sum()),
        flips=float(flip.sum()),
        head=float(-head),
        head_pressure=float(pi[k + 1]),
    )


def diagnose(a: float, dx: float, interval: float, stressed: bool) -> list[Sample]:
    """The samples of the run at aspect ratio ``a`` with cells ``dx`` (collapse_channel.run),
    with the option if ``stressed``, after the first of its own steps past every ``interval``."""
    other = collapse_channel.STRESSED if stressed else None
    sim = Simulation(collapse_channel.run(a, dx, other).load())
    return on_own_steps(sim, collapse_channel.end_time(a, other), interval, sample)


def integral(samples: list[Sample], name: str) -> float:
    """The trapezoidal time integral of ``name`` over ``samples``."""
    return float(np.trapezoid([getattr(s, name) for s in samples], [s.t for s in samples]))


def phases(samples: list[Sample]) -> dict[str, dict[str, float]]:
    """Per phase (fall, spreading), the time-integrated ratios of the term to the pressure."""
    peak = int(np.argmax([s.kinetic for s in samples]))
    out = {}
    for label, part in (("fall", samples[: peak + 1]), ("spreading", samples[peak:])):
        e = {name: integral(part, name) for name in INTEGRATED}
        out[label] = {
            "start": part[0].t,
            "end": part[-1].t,
            "l1_ratio": e["term"] / e["pressure"],
            "column_share_of_term": e["term_column"] / e["term"],
            "column_share_of_pressure": e["pressure_column"] / e["pressure"],
            "front_force_ratio": e["term_front"] / e["pressure_front"],
            "front_work_ratio": e["term_power"] / e["pressure_power"],
            "front_compressed": e["front_compressed"] / e["front_faces"],
            "sign_flips": e["flips"] / e["pairs"],
            "head_force_ratio": e["head"] / e["head_pressure"],
            "head_largest_push": max(s.head / s.head_pressure for s in part if s.head_pressure > 0),
        }
    return out


def share(part: float, whole: float) -> str:
    """``part / whole`` as a signed percentage, ``n/a`` where ``whole`` is zero (a front at rest)."""
    return f"{part / whole:+6.1%}" if whole else "   n/a"


def report(a: float, dx: float, stressed: bool, samples: list[Sample]) -> dict[str, dict[str, float]]:
    found = phases(samples)
    print(f"a = {a:g}, dx = {dx * 1e3:g} mm, {'with' if stressed else 'without'} model.normal_stress:")
    for label, v in found.items():
        print(
            f"  {label:9s} t = {v['start']:.3f}-{v['end']:.3f} s: |T|/|G| (L1, time-integrated) "
            f"{v['l1_ratio']:.1%}; in the column {v['column_share_of_term']:.0%} of |T| "
            f"({v['column_share_of_pressure']:.0%} of |G|); net x-force on the front T/G "
            f"{v['front_force_ratio']:+.1%}; work on the front {v['front_work_ratio']:+.1%}; front "
            f"compressed {v['front_compressed']:.0%} (h-weighted); D_xx changes sign between "
            f"{v['sign_flips']:.0%} of the neighbouring faces; on the head {v['head_force_ratio']:+.1%} "
            f"(largest {v['head_largest_push']:+.1%})"
        )
    step = max(1, len(samples) // 12)
    for s in samples[step::step]:
        print(
            f"    t = {s.t:.3f} s: |T|/|G| {s.term / max(s.pressure, 1e-300):6.1%}, front force "
            f"{share(s.term_front, s.pressure_front)}, front power {share(s.term_power, s.pressure_power)}, "
            f"head {share(s.head, s.head_pressure)}"
        )
    return found


def runouts(ratios: list[float], cells: list[float], runs: Path) -> list[dict[str, float]]:
    """The deposit of the validation case's runs with and without the option."""
    context = Context(runs=runs)
    scenario = context.load(collapse_channel.SCENARIO)
    grain, gravity = scenario.material.grain_diameter, scenario.gravity
    out: list[dict[str, float]] = []
    for dx in cells:
        for a in ratios:
            target = collapse_channel.law(a, collapse_channel.LAWS[collapse_channel.REFERENCE])
            for other in (None, collapse_channel.STRESSED):
                r = collapse_channel.run(a, dx, other)
                result = context.execute([r])[r.name]
                if isinstance(result, str):
                    print(f"{r.name}: failed: {result}")
                    continue
                d = collapse_channel.Deposit.of(result, a, grain, gravity)
                row = {"a": a, "dx": dx, "normal_stress": float(other is not None)}
                row |= {"tip": d.tip, "mass_front": d.mass}
                row |= {"tip_law_b": d.tip / target, "mass_front_law_b": d.mass / target}
                row |= {"volume_change": d.mass_change, "max_speed_end": d.speed, "t_stop": d.stop}
                print(
                    f"a = {a:g}, dx = {dx * 1e3:g} mm, normal stress {'on ' if other else 'off'}: tip "
                    f"{d.tip:.2f} ({d.tip / target:.2f} law B), 95 % {d.mass:.2f} ({d.mass / target:.2f}), "
                    f"volume {d.mass_change:+.1e}, max |u| end {d.speed:.1e} m/s"
                )
                out.append(row)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ratios", type=float, nargs="+", default=[2.0, 7.0], help="aspect ratios a")
    parser.add_argument("--dx", type=float, default=2e-3, help="cell size (m) of the diagnosis")
    parser.add_argument("--interval", type=float, default=0.005, help="time between samples (s)")
    parser.add_argument("--cells", type=float, nargs="*", default=[2e-3, 1e-3], help="run-outs' cells")
    parser.add_argument("--runs", type=Path, default=Path("results/longitudinal_stress"), help="their runs")
    parser.add_argument("--json", type=Path, help="write the numbers here")
    args = parser.parse_args()
    diagnosis = [
        {"a": a, "dx": args.dx, "normal_stress": stressed}
        | report(a, args.dx, stressed, diagnose(a, args.dx, args.interval, stressed))
        for stressed in (False, True)
        for a in args.ratios
    ]
    rows = runouts(args.ratios, args.cells, args.runs)
    if args.json:
        args.json.write_text(json.dumps({"diagnosis": diagnosis, "runouts": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
