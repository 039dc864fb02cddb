"""A property study of layered grain–fluid mixtures: many short valid runs drawn at random
(seeded), each checked for what the model and the scheme promise (docs/mixture.md).

Three families, drawn from the shipped mixture scenarios with overrides:

- ``collapse``: a column collapsing between walls (scenarios/submarine_collapse_*.yaml),
  2 to 16 layers, a packing anywhere validation accepts it, a slope of 0 to 35 degrees;
- ``layer``: a uniform layer in a periodic domain (scenarios/immersed_layer_*.yaml) whose
  layers hold packings of their own (set through the API), thick or near the dry threshold;
- ``heap``: a heap below the angle of repose on a flat bed, between walls, dense enough to
  hold (the yield stress of ``dilatant_coulomb``, ``tan(delta) + K (phi - phi_c)``, falls
  to zero below 0.48 with the constants of the shipped files: a looser heap flows).

Each is run with one of the fluids of the shipped files or a water-like one, with or
without ``fluid.compressibility``, at ``numerics.order`` 1 or 2 and a CFL number up to
0.95, for at most ``--steps`` steps.  Checked after every step: no NaN, thickness and
packings in ``[0, 1)`` (a layer of a wet column may hold fluid only), the solid conserved to
round-off; a heap stays exactly at rest
(``u == 0.0``, ``h`` and the solid bit for bit); the energy of a uniform column at order 1
without compressibility does not grow (``engine/mixture/exchange.py``, Notes).  A run that
stops must stop with a :class:`~multilayer.errors.RunError`; its message is printed.  A
run that reaches a packing beyond the densest packing of spheres without stopping is counted
apart (``dense``): in a film thinner than ``numerics.dry_threshold``, which the run does not
check before its local step (the columns it steps stop the run there).

    .venv/bin/python benchmarks/mixture_robustness.py --runs 200 --seed 1
"""

from __future__ import annotations

import argparse
import math
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import multilayer
from multilayer.errors import InputError, RunError

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
FLUIDS = {
    "water-ucon-12": (1010.0, 0.0121),  # submarine_collapse_*.yaml
    "water-ucon-96": (1041.0, 0.096),  # immersed_layer_*.yaml
    "water": (1000.0, 1.0e-3),
}
DENSEST = math.pi / math.sqrt(18.0)


@dataclass
class Case:
    """One drawn configuration."""

    family: str
    layers: int
    phi: float
    slope: float
    fluid: str
    compressibility: float | None
    order: int
    cfl: float
    thickness: float = 0.0
    packings: list[float] = field(default_factory=list)

    def overrides(self) -> dict[str, Any]:
        rho, eta = FLUIDS[self.fluid]
        sets: dict[str, Any] = {}
        if self.family == "heap":  # a profile of surface slope 0.08 (4.6 degrees), below tan(22.5 degrees)
            points = [[0.0, 0.0], [0.05, 0.004], [0.1, 0.0]]
            sets["initial.0"] = {"shape": "profile", "points": points, "phi": self.phi}
        else:
            sets["initial.0.phi"] = self.phi
        sets |= {
            "domain.layers": self.layers,
            "fluid.density": rho,
            "fluid.viscosity": eta,
            "numerics.order": self.order,
            "time.cfl": self.cfl,
            "slope_deg": 0.0 if self.family == "heap" else self.slope,
        }
        if self.compressibility is not None:
            sets["fluid.compressibility"] = self.compressibility
        if self.family == "collapse":
            sets |= {"domain.cells": 16, "domain.x_max": 0.16, "boundaries.right": "wall"}
        elif self.family == "layer":
            sets |= {"initial.0.thickness": self.thickness}
        else:
            sets |= {"domain.cells": 10, "domain.x_max": 0.1, "boundaries.right": "wall"}
        return sets

    def base(self) -> Path:
        name = "submarine_collapse_loose" if self.family in ("collapse", "heap") else "immersed_layer_loose"
        return SCENARIOS / f"{name}.yaml"


def draw(rng: np.random.Generator) -> Case:
    family = str(rng.choice(["collapse", "layer", "layer", "heap"]))
    layers = int(rng.integers(2, 17))
    # loose to dense, within (0, DENSEST): mostly near the critical state, sometimes far
    phi = float(rng.choice([rng.uniform(0.5, 0.66), rng.uniform(0.02, DENSEST - 1e-3)], p=[0.7, 0.3]))
    case = Case(
        family=family,
        layers=layers,
        phi=round(phi, 4),
        slope=round(float(rng.uniform(0.0, 35.0)), 2),
        fluid=str(rng.choice(list(FLUIDS))),
        compressibility=None if rng.random() < 0.6 else float(10.0 ** rng.uniform(-7, -3)),
        order=int(rng.choice([1, 2])),
        cfl=round(float(rng.choice([0.45, rng.uniform(0.1, 0.95)])), 3),
    )
    if family == "heap":  # held: tan(delta) + K (phi - phi_c) above the surface slope 0.08 at rest
        case.phi = round(float(rng.uniform(0.51, DENSEST - 1e-3)), 4)
    if family == "layer":
        case.thickness = float(rng.choice([4.9e-3, 10.0 ** rng.uniform(-5.7, -3)]))
        if rng.random() < 0.6:
            low = max(0.02, case.phi - 0.1)
            high = min(DENSEST - 1e-3, case.phi + 0.1)
            case.packings = [round(float(p), 4) for p in rng.uniform(low, high, layers)]
    return case


def energy(sim: Any, solid: np.ndarray, rho_s: float, rho_f: float, theta: float) -> float:
    """``sum_a m_a v_a^2 / 2 + h P_bar`` of the first column (engine/mixture/exchange.py)."""
    l = sim.mixture.fractions
    h, v = float(sim.h[0]), sim.u[:, 0]
    mass = rho_s * solid + rho_f * (l * h - solid)
    centre = np.cumsum(l) - l / 2
    weight = (rho_s - rho_f) * 9.81 * math.cos(theta) * solid * centre
    return float(np.sum(mass * v * v) / 2.0 + h * np.sum(weight))


def run(case: Case, steps: int) -> tuple[str, str]:
    """Run ``case``: ("ok" | "dense" | "stopped" | "FAIL" | "invalid", detail)."""
    try:
        scenario = multilayer.load(case.base(), case.overrides())
    except InputError as error:
        return "invalid", str(error).splitlines()[0]
    sim = multilayer.Simulation(scenario)
    mix = sim.mixture
    assert mix is not None  # a scenario with fluid
    if case.packings:
        l = mix.fractions
        mix.solid[...] = (np.array(case.packings) * l)[:, None] * sim.h
        mix.reset(0)
    rho_s, rho_f = mix.rho_s, mix.rho_f
    theta = math.radians(case.slope)
    h0, solid0, total0 = sim.h.copy(), mix.solid.copy(), float(mix.solid.sum())
    check_energy = case.family == "layer" and case.order == 1 and case.compressibility is None
    work, densest = 0.0, 0.0
    try:
        for n in range(steps):
            s = mix.solid[:, 0].copy()
            before = energy(sim, s, rho_s, rho_f, theta) - work if check_energy else 0.0
            v0, hh = sim.u[:, 0].copy(), float(sim.h[0])
            dt = sim.step()
            if check_energy:
                l = mix.fractions
                F = (rho_s - rho_f) * 9.81 * math.sin(theta) * s
                m = rho_s * s + rho_f * (l * hh - s)
                work += dt * float(np.sum(F * (v0 + dt * F / m)))
                after = energy(sim, mix.solid[:, 0], rho_s, rho_f, theta) - work
                if after - before > 1e-9 * max(abs(before), 1e-300):
                    return "FAIL", f"energy grows at step {n}: {before!r} -> {after!r}"
            solid = mix.solid
            if not (np.isfinite(sim.h).all() and np.isfinite(sim.u).all() and np.isfinite(solid).all()):
                return "FAIL", f"not finite at step {n}"
            if np.any(sim.h < 0.0):
                return "FAIL", f"negative thickness at step {n}"
            wet = sim.h > 0.0
            phi = mix.phi_layers(sim.h)[:, wet]
            if not np.all((phi >= 0.0) & (phi < 1.0)):
                return "FAIL", f"packing out of [0, 1) at step {n}: {phi.min()!r} .. {phi.max()!r}"
            densest = max(densest, float(phi.max(initial=0.0)))
            if abs(float(solid.sum()) - total0) > 1e-12 * total0:
                return "FAIL", f"solid not conserved at step {n}: {(solid.sum() - total0) / total0:.3g}"
            if case.family == "heap" and not (
                np.all(sim.u == 0.0) and np.array_equal(sim.h, h0) and np.array_equal(solid, solid0)
            ):
                return "FAIL", f"heap moved at step {n}: |u| {np.abs(sim.u).max():.3g}"
    except RunError as error:
        return "stopped", str(error)
    except Exception:  # noqa: BLE001 - anything else is a failure of the engine
        return "FAIL", traceback.format_exc().splitlines()[-1]
    if densest > DENSEST * (1.0 + 1e-12):
        return "dense", f"a packing of {densest:.4g} (beyond pi / sqrt(18)) at t = {sim.t:.4g} s"
    return "ok", f"t = {sim.t:.4g} s"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--steps", type=int, default=60)
    parser.add_argument("--only", type=int, default=None, help="run only the case of this index")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    counts: dict[str, int] = {}
    for i in range(args.runs):
        case = draw(rng)
        if args.only is not None and i != args.only:
            continue
        status, detail = run(case, args.steps)
        counts[status] = counts.get(status, 0) + 1
        if status != "ok":
            print(f"[{i}] {status}: {case}\n    {detail}", flush=True)
    print(counts)


if __name__ == "__main__":
    main()
