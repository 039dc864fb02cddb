"""Benchmark: the cost of a grain–fluid mixture run against a dry run of the same size.

Runs ``scenarios/submarine_collapse_loose.yaml`` (one layer, the mixture's local step)
and the same column without the fluid (the same cells, layer and simulated time; the
Coulomb law ``drucker_prager`` with ``mu_s = tan(delta)`` and the bulk density
``rho_s phi0``), alternating ``--repeat`` times, and prints the median time to solution,
the steps and the time per step of each, and their ratios (docs/mixture.md).  The dry
column collapses faster (no buoyancy, no viscous friction): it takes other steps, so the
ratio per step is the cost of the mixture's step and the total ratio that of the run.

    python benchmarks/mixture_cost.py [--cells 60] [--end 4] [--repeat 3]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time
from pathlib import Path

import yaml

import multilayer
from multilayer.app.simulation import Simulation

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "submarine_collapse_loose.yaml"


def scenarios(cells: int, end: float) -> dict[str, multilayer.Scenario]:
    """The mixture scenario and its dry counterpart."""
    data = yaml.safe_load(SCENARIO.read_text(encoding="utf-8"))
    data["domain"]["cells"] = cells
    data["time"]["end"] = end
    data.pop("expect", None)
    dry = {k: v for k, v in data.items() if k not in ("fluid", "mixture")}
    phi = data["initial"][0]["phi"]
    dry["initial"] = [{k: v for k, v in entry.items() if k != "phi"} for entry in data["initial"]]
    dry["material"] = {**data["material"], "density": data["material"]["particle_density"] * phi}
    dry["rheology"] = {
        "name": "drucker_prager",
        "mu_s": math.tan(math.radians(data["rheology"]["delta_deg"])),
        "nu": 0.0,
    }
    return {"mixture": multilayer.load(data), "dry": multilayer.load(dry)}


def timed(scenario: multilayer.Scenario) -> tuple[float, int]:
    sim = Simulation(scenario)
    sim.step()  # compiles the kernels outside the timing
    start = time.perf_counter()
    sim.advance(scenario.time.end)
    return time.perf_counter() - start, sim.steps - 1


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--cells", type=int, default=60)
    parser.add_argument("--end", type=float, default=4.0)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    runs = scenarios(args.cells, args.end)
    times: dict[str, list[float]] = {name: [] for name in runs}
    steps: dict[str, int] = {}
    for _ in range(args.repeat):
        for name, scenario in runs.items():
            seconds, steps[name] = timed(scenario)
            times[name].append(seconds)
    median = {name: statistics.median(t) for name, t in times.items()}
    for name in runs:
        print(
            f"{name:8s} {median[name]:.3f} s, {steps[name]} steps, "
            f"{1e3 * median[name] / steps[name]:.3f} ms per step "
            f"({args.cells} cells x 1 layer, {args.end:g} s)"
        )
    per_step = (median["mixture"] / steps["mixture"]) / (median["dry"] / steps["dry"])
    print(f"mixture / dry: {median['mixture'] / median['dry']:.2f} per run, {per_step:.2f} per step")
    print(f"load average {os.getloadavg()[0]:.2f} (a shared machine makes the times uncertain)")


if __name__ == "__main__":
    main()
