"""Benchmark: the transport's shock and rarefaction errors, measured (deterministic, no times).

The measures that a change of the face flux (docs/model.md, "Transport numerics") must
keep, on a horizontal frictionless bed of 10 m, one layer, g = 9.81, to t = 0.6 s:

- Ritter's dam break (1 m behind x = 5 m, dry ahead): the L1 error of h and its observed
  order at each order of the scheme;
- Stoker's wet dam break (1 m behind x = 5 m, ``--downstream`` ahead, Stoker 1957, "Water
  Waves", ch. 10.8: a rarefaction, a uniform state ``h_m``, a shock): the L1 error of h,
  its observed order, the overshoot of h over ``h_m`` and of u over ``u_m`` on the half of
  the uniform state next to the shock (oscillations behind a shock would show there; the
  half next to the fan holds the fan's smeared tail), the shock's position (the middle of
  the cell where h crosses ``(h_m + h_r) / 2``) against the exact one;
- a lake at rest over a bump: the largest velocity after 500 steps.

    python benchmarks/face_pressure.py [--cells 100 200 400 800] [--downstream 0.1]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from multilayer.app.simulation import Simulation
from multilayer.reference.exact import StokerDamBreak, ritter
from multilayer.scenario import from_dict

G = 9.81
T = 0.6
DAM = 5.0
RECTANGLE = {"shape": "rectangle", "x_min": 0.0, "x_max": DAM}


def simulation(cells: int, order: int, initial: list, bed: dict | None = None) -> Simulation:
    """One layer of frictionless material between walls (outflow on the right) on [0, 10] m."""
    data = {
        "name": "face-pressure",
        "gravity": G,
        "slope_deg": 0.0,
        "domain": {"x_min": 0.0, "x_max": 10.0, "cells": cells, "layers": 1},
        "material": {"density": 1000.0, "grain_diameter": 1.0e-3},
        "rheology": {"name": "drucker_prager", "mu_s": 0.0, "nu": 0.0},
        "base": [{"condition": "free_slip"}],
        "initial": initial,
        "boundaries": {"left": "wall", "right": "outflow"},
        "time": {"end": T, "output_interval": T},
        "numerics": {"order": order, "dry_threshold": 1e-10},
    }
    if bed is not None:
        data["bed"] = bed
    return Simulation(from_dict(data))


def orders(errors: list[float]) -> list[float]:
    """Observed orders of successive errors on meshes refined by two."""
    return [math.log2(a / b) for a, b in zip(errors[:-1], errors[1:], strict=True)]


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--cells", type=int, nargs="+", default=[100, 200, 400, 800])
    parser.add_argument("--downstream", type=float, default=0.1, help="Stoker's depth ahead of the dam (m)")
    args = parser.parse_args()
    hr = args.downstream
    for order in (1, 2):
        errors = []
        for cells in args.cells:
            sim = simulation(
                cells, order, [{"shape": "rectangle", "x_min": 0.0, "x_max": DAM, "height": 1.0}]
            )
            sim.advance(T)
            errors.append(float(np.sum(np.abs(sim.h - ritter(sim.x, T, 1.0, DAM))) * sim.dx))
        print(f"ritter order {order}: L1 {' '.join(f'{e:.4e}' for e in errors)}")
        print(f"  observed orders {' '.join(f'{o:.3f}' for o in orders(errors))}")
    for order in (1, 2):
        errors, lines = [], []
        for cells in args.cells:
            dam = [{"shape": "layer", "thickness": hr}, {**RECTANGLE, "height": 1.0 - hr}]
            sim = simulation(cells, order, dam)
            sim.advance(T)
            exact = StokerDamBreak(1.0, hr, x0=DAM)
            h_exact, _ = exact.solution(sim.x, T)
            (hm, um), shock = exact.middle, exact.shock_speed
            errors.append(float(np.sum(np.abs(sim.h - h_exact)) * sim.dx))
            tail = um - math.sqrt(G * hm)
            plateau = (sim.x > DAM + 0.5 * (tail + shock) * T) & (sim.x < DAM + shock * T)
            crossing = np.flatnonzero(sim.h > 0.5 * (hm + hr))[-1]
            lines.append(
                f"  {cells} cells: max h / h_m - 1 {sim.h[plateau].max() / hm - 1:+.2e}, "
                f"max u / u_m - 1 {sim.u[0][plateau].max() / um - 1:+.2e}, "
                f"shock at {sim.x[crossing] + 0.5 * sim.dx:.4f} m (exact {DAM + shock * T:.4f})"
            )
        print(f"stoker h_r = {hr} order {order}: L1 {' '.join(f'{e:.4e}' for e in errors)}")
        print(f"  observed orders {' '.join(f'{o:.3f}' for o in orders(errors))}")
        print("\n".join(lines))
    bump = {"points": [[0.0, 0.0], [4.0, 0.0], [5.0, 0.5], [6.0, 0.0], [10.0, 0.0]]}
    surface = [[0.0, 1.0], [4.0, 1.0], [5.0, 0.5], [6.0, 1.0], [10.0, 1.0]]
    for order in (1, 2):
        sim = simulation(100, order, [{"shape": "profile", "points": surface}], bed=bump)
        for _ in range(500):
            sim.step()
        print(f"lake at rest over a bump, order {order}: max |u| after 500 steps {np.abs(sim.u).max():.3e}")


if __name__ == "__main__":
    main()
