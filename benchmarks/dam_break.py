"""Benchmark: the multilayer mu(I) dam break of docs/performance.md.

Reduced units (g = 1): 2500 cells x 32 layers on x in [0, 50], a bed falling 0.45 per
unit length, a unit-height column on [0, 2], Jop mu(I) with mu_s = 0.35, mu_2 = 0.56,
I_0 = 0.4, grain diameter 1/32, densities 1, no-slip base, wall on the left, outflow on
the right, run to t = 5.  Prints the time to solution, the cell-steps per second and the
front position.  Reference: a standalone first-order C multilayer code with regularised
yield takes 16.5 s on a 2-core machine of this project (about 10 M cell-steps/s), front
at x = 9.0.

    python benchmarks/dam_break.py [--cells 2500] [--layers 32] [--order 2] [--profile]
        [--pressure hydrostatic | bim2016 | non_hydrostatic]
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time

import numpy as np

from multilayer.engine.simulation import Simulation
from multilayer.io.scenario import from_dict


def scenario(cells: int, layers: int, order: int, end: float, pressure: str = "hydrostatic"):
    return from_dict(
        {
            "name": "benchmark-mu-i-dam-break",
            "gravity": 1.0,
            "slope_deg": 0.0,
            "domain": {"x_min": 0.0, "x_max": 50.0, "cells": cells, "layers": layers},
            "material": {"density": 1.0, "grain_diameter": 1.0 / 32.0, "particle_density": 1.0},
            "rheology": {"name": "jop_mu_i", "mu_s": 0.35, "mu_2": 0.56, "I_0": 0.4},
            "base": [{"condition": "no_slip"}],
            "bed": {"points": [[0.0, 0.0], [50.0, -22.5]]},
            "initial": [{"shape": "rectangle", "x_min": 0.0, "x_max": 2.0, "height": 1.0}],
            "boundaries": {"left": "wall", "right": "outflow"},
            "time": {"end": end, "output_interval": end},
            "numerics": {"order": order},
            "model": {"pressure": pressure},
        }
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=2500)
    parser.add_argument("--layers", type=int, default=32)
    parser.add_argument("--order", type=int, default=2, choices=(1, 2))
    parser.add_argument("--end", type=float, default=5.0)
    parser.add_argument(
        "--pressure", default="hydrostatic", choices=("hydrostatic", "bim2016", "non_hydrostatic")
    )
    parser.add_argument("--profile", action="store_true", help="print the 15 costliest functions")
    args = parser.parse_args()

    sim = Simulation(scenario(args.cells, args.layers, args.order, args.end, args.pressure))
    sim.step(1e-9)  # compile the numba kernels outside the timing
    sim = Simulation(scenario(args.cells, args.layers, args.order, args.end, args.pressure))
    profiler = cProfile.Profile() if args.profile else None
    start = time.perf_counter()
    if profiler:
        profiler.enable()
    sim.advance(args.end)
    if profiler:
        profiler.disable()
    elapsed = time.perf_counter() - start
    d = sim.diagnostics()
    cell_steps = sim.cells * sim.steps
    print(
        f"cells {args.cells} x layers {args.layers}, transport order {args.order}, "
        f"pressure {args.pressure}, t = {sim.t:g}"
    )
    print(f"steps {sim.steps}, Newton iterations per step {sim.newton_iterations / sim.steps:.2f}")
    print(f"time to solution {elapsed:.2f} s, {cell_steps / elapsed / 1e6:.2f} M cell-steps/s")
    print(
        f"front x = {d['front']:.3f} (threshold {sim.front_threshold:g}), mass {d['mass']:.6f}, "
        f"max |u| {np.abs(sim.u).max():.3f}"
    )
    if profiler:
        pstats.Stats(profiler).sort_stats("tottime").print_stats(15)


if __name__ == "__main__":
    main()
