"""Benchmark: a fully wet mu(I) chute fed by a Bagnold inflow, checked against Bagnold.

The glass-bead chute of scenarios/bagnold_chute.yaml (Jop mu(I), mu_s = 0.4770,
mu_2 = 0.7265, I_0 = 0.279, d = 0.7 mm, rho = 1550 kg/m^3, rho_p = 2500 kg/m^3, 28 deg,
h = 1 cm, no-slip base) made long: 20 000 columns x 64 layers over 40 m, inflow of the
exact Bagnold profile on the left, outflow on the right, started from the same uniform
Bagnold flow everywhere.  Every cell holds material, so skipping dry cells gains
nothing.  The check: the layer velocities against the exact Bagnold profile averaged
over each layer (GDR MiDi 2004; Tsang et al. 2019, eq. 4.1) and the thickness against
1 cm, everywhere.

``--start rest``: the same layer released from rest on a periodic chute (the onset of a
flow: every column leaves rest in the first step).  The check: the flow stays uniform
(every column equal to the first, to the bit) and the mass is that of the start.

    python benchmarks/chute.py [--cells 20000] [--layers 64] [--steps 40] [--order 2]
        [--start bagnold|rest] [--profile]
"""

from __future__ import annotations

import argparse

import numpy as np
from common import timed

from multilayer.app.simulation import Simulation
from multilayer.reference.exact import BagnoldFlow, jop_inertial_number
from multilayer.scenario import from_dict

THETA, DEPTH, D, RHO, RHO_P = 28.0, 0.01, 0.7e-3, 1550.0, 2500.0
MU_S, MU_2, I_0 = 0.4770, 0.7265, 0.279


EXACT = BagnoldFlow(DEPTH, jop_inertial_number(THETA, MU_S, MU_2, I_0), D, THETA, 9.81, RHO / RHO_P)


def scenario(cells: int, layers: int, order: int, end: float, threads="auto", start: str = "bagnold"):
    """The chute started from the exact Bagnold flow with its inflow, or (``start="rest"``)
    at rest, periodic."""
    bagnold = {"profile": "bagnold", "surface_speed": EXACT.surface_velocity}
    if start == "rest":
        initial: dict = {"shape": "layer", "thickness": DEPTH}
        boundaries: dict = {"left": "periodic", "right": "periodic"}
    else:
        initial = {"shape": "layer", "thickness": DEPTH, "velocity": bagnold}
        boundaries = {
            "left": "inflow",
            "right": "outflow",
            "inflow": {"thickness": DEPTH, "velocity": bagnold},
        }
    return from_dict(
        {
            "name": "benchmark-bagnold-chute",
            "slope_deg": THETA,
            "domain": {"x_min": 0.0, "x_max": 0.002 * cells, "cells": cells, "layers": layers},
            "material": {"density": RHO, "grain_diameter": D, "particle_density": RHO_P},
            "rheology": {"name": "jop_mu_i", "mu_s": MU_S, "mu_2": MU_2, "I_0": I_0},
            "base": [{"condition": "no_slip"}],
            "initial": [initial],
            "boundaries": boundaries,
            "time": {"end": end, "output_interval": end},
            "numerics": {"order": order, "threads": threads},
        }
    )


def bagnold_error(sim: Simulation) -> np.ndarray:
    """|u - exact| / exact surface speed per column (largest over the layers), the exact
    profile averaged over each layer."""
    exact = EXACT.layer_means(sim.mesh.interfaces * DEPTH)
    return np.abs(sim.u - exact[:, None]).max(axis=0) / EXACT.surface_velocity


def interior(sim: Simulation) -> slice:
    """The columns that no signal from the boundaries reached (at most two cells per step)."""
    return slice(2 * sim.steps, -2 * sim.steps)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=20000)
    parser.add_argument("--layers", type=int, default=64)
    parser.add_argument("--steps", type=int, default=40, help="time steps to run (fixed Courant step)")
    parser.add_argument("--order", type=int, default=2, choices=(1, 2))
    parser.add_argument("--threads", default="auto")
    parser.add_argument("--start", default="bagnold", choices=("bagnold", "rest"))
    parser.add_argument("--profile", action="store_true", help="print the 15 costliest functions")
    args = parser.parse_args()
    threads = args.threads if args.threads == "auto" else int(args.threads)

    probe = Simulation(scenario(8, args.layers, args.order, 1.0, threads))
    end = args.steps * probe.time_step() * (1 - 1e-9)  # the wave speed is that of the inflow

    def make() -> Simulation:
        return Simulation(scenario(args.cells, args.layers, args.order, end, threads, args.start))

    sim, timing = timed(make, end, profile=args.profile, warm_up=make)  # fully wet: the window is the mesh
    print(f"Bagnold chute: {args.cells} cells x {args.layers} layers, order {args.order}, t = {sim.t:.4g} s")
    print("\n".join(timing.lines()))
    if args.start == "rest":
        spread = max(np.abs(sim.u - sim.u[:, :1]).max(), np.abs(sim.h - sim.h[0]).max())
        mass = abs(sim.h.sum() / (args.cells * DEPTH) - 1.0)
        print(
            f"check: largest difference between columns {spread:.1e} (uniform: 0), relative mass change "
            f"{mass:.1e}, surface speed {sim.u[-1].max():.4g} m/s"
        )
        return
    error, far = bagnold_error(sim), interior(sim)
    print(
        f"check: max |u - Bagnold| / surface speed = {error[far].max():.2e} away from the ends, "
        f"{error.max():.2e} everywhere (largest at column {error.argmax()}); "
        f"max |h - 1 cm| = {np.abs(sim.h - DEPTH)[far].max():.2e} m away from the ends, "
        f"{np.abs(sim.h - DEPTH).max():.2e} m everywhere"
    )


if __name__ == "__main__":
    main()
