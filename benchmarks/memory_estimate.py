"""The memory estimate of ``multilayer validate`` against the peak of a run
(multilayer/app/resources.py): three steps of a layer flowing on every column, per
pressure model, the normal stress and a mixture, in a child process each.

    python benchmarks/memory_estimate.py [--columns 30000] [--layers 10]

Prints per case the estimate, the peak resident memory and their ratio; the estimate
must be above the peak (ratio > 1) and is meant to stay within about twice it.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

CHILD = """
import json, resource, sys
from multilayer.app import resources
from multilayer.app.simulation import Simulation
from multilayer.scenario import from_dict
scenario = from_dict(json.loads(sys.argv[1]))
sim = Simulation(scenario)
for _ in range(3):
    sim.step(1.0)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(resources.estimate(scenario).memory, peak)
"""

MODELS: dict[str, dict] = {
    "hydrostatic": {},
    "bim2016": {"model": {"pressure": "bim2016"}},
    "non_hydrostatic (every layer)": {"model": {"pressure": "non_hydrostatic", "pressure_layers": "layers"}},
    "normal stress": {"model": {"normal_stress": True}},
    "mixture": {
        "fluid": {"density": 1000.0, "viscosity": 1e-3},
        "mixture": {"phi_critical": 0.58, "dilatancy": 4.0, "critical_shift": 25.0},
    },
}


def scenario(columns: int, layers: int, changes: dict) -> dict:
    """A 1 cm layer flowing down 35 degrees on ``columns`` columns of ``layers`` layers."""
    layer = {"shape": "layer", "thickness": 0.01, **({"phi": 0.58} if "fluid" in changes else {})}
    model = dict(changes.get("model", {}))
    if model.get("pressure_layers") == "layers":
        model["pressure_layers"] = layers
    return {
        "name": "memory",
        "slope_deg": 35.0,
        "domain": {"x_min": 0.0, "x_max": columns * 1e-3, "cells": columns, "layers": layers},
        "material": {"density": 1500.0, "grain_diameter": 1e-3},
        "rheology": {"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.28},
        "initial": [layer],
        "boundaries": {"left": "wall", "right": "outflow"},
        "time": {"end": 1.0, "output_interval": 0.5},
        **{key: value for key, value in changes.items() if key != "model"},
        **({"model": model} if model else {}),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--columns", type=int, default=30_000)
    parser.add_argument("--layers", type=int, default=10)
    args = parser.parse_args()
    for name, changes in MODELS.items():
        text = json.dumps(scenario(args.columns, args.layers, changes))
        done = subprocess.run([sys.executable, "-c", CHILD, text], capture_output=True, text=True, check=True)
        estimate, peak = (float(v) for v in done.stdout.split())
        mib = f"estimate {estimate / 2**20:8.0f} MiB  peak {peak / 2**20:8.0f} MiB"
        print(f"{name:32s} {mib}  ratio {estimate / peak:5.2f}")


if __name__ == "__main__":
    main()
