"""Benchmark: what sets the resting deposit of the loose submarine collapse moving again.

Runs ``scenarios/submarine_collapse_loose.yaml`` on ``--cells`` cells to ``--start`` and
steps it to ``--end``.  For each column of the deposit (thicker than 5 mm) that a step
sets moving (at rest at the step's start, moving at its end) it prints:

- the mean of its two discrete free-surface slopes at the step's start over its static
  friction ``tan(delta) + K (phi - phi_c)`` (docs/model.md, "Rest": a column at rest
  feels its weight times that mean);
- the drive the transport gives it in each of Heun's stages of the first attempt (the
  column at rest), in units of the buoyant weight, ``u* / (g' dt)`` (twice that in the
  second stage, whose local step is over ``dt/2``), against the mean slope of the state
  the stage starts from: the difference is the momentum its face with the moving
  neighbour passes (the HLL flux's upwinding of ``h u``, about ``c h_R u_R / 2`` with
  ``c = sqrt(g' h)``: docs/model.md, "Transport numerics").

Then, once per output interval of the stepped one, the basal excess pore pressure of
the moving columns of the body (thicker than 1 cm) against the steady flowing state of
the closure, ``p_e / P = 1 - K2 tan(theta) / (K1 (phi_c - phi) + K2 tan(delta))``
(docs/mixture.md), ``tan(theta)`` the column's free-surface slope: the friction of that
state equals the drive at any speed, so a moving body creeps until it is flat or a local
step takes it to its rest root.

Deterministic (model quantities only):

    python benchmarks/loose_restarts.py [--cells 480] [--start 2.55] [--end 2.65] [--shown 6]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np

import multilayer
from multilayer.app.simulation import Simulation

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "submarine_collapse_loose.yaml"
DEPOSIT = 5e-3  # m: the columns of the deposit whose starts are reported
BODY = 1e-2  # m: the moving columns whose pore pressure is compared with the closure


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--cells", type=int, default=480)
    parser.add_argument("--start", type=float, default=2.55, help="s: run to here first")
    parser.add_argument("--end", type=float, default=2.65, help="s: step to here")
    parser.add_argument("--shown", type=int, default=6, help="starts printed in full")
    args = parser.parse_args()
    scenario = multilayer.load(SCENARIO, [f"domain.cells={args.cells}", f"time.end={args.end}"])
    params = scenario.rheology.params
    mixture = scenario.mixture
    assert mixture is not None  # the scenario is a mixture's
    tan_delta = math.tan(math.radians(params["delta_deg"]))
    sim = Simulation(scenario)
    flow = sim.mixture
    assert flow is not None
    sim.advance(args.start)
    g, dx = sim.g_n, sim.dx
    stages: list[tuple[float, np.ndarray, np.ndarray]] = []  # (dt, h, u*) of each transport
    transport = sim._transport

    def recorded(dt: float, threads: int, **options: Any) -> tuple[np.ndarray, np.ndarray]:
        h, ustar = transport(dt, threads, **options)
        stages.append((dt, h.copy(), ustar[0].copy()))
        return h, ustar

    def mean_slope(h: np.ndarray, j: Any) -> float:
        return float(h[j - 1] - h[j + 1]) / (2 * dx)

    ratios, excess = [], []
    closure: list[float] = []
    measured: list[float] = []
    moved = sim.u[0] != 0.0  # the columns moving at the last output interval passed
    outputs = math.floor(sim.t / scenario.time.output_interval)
    with mock.patch.object(sim, "_transport", recorded):
        while sim.t < args.end:
            h0, u0 = sim.h.copy(), sim.u[0].copy()
            phi0 = flow.phi(h0)
            stages.clear()
            dt = sim.step(args.end)
            started = (u0 == 0.0) & (sim.u[0] != 0.0) & (h0 > DEPOSIT)
            started[[0, -1]] = False  # the end columns: their mean slope needs the boundary's
            for j in np.flatnonzero(started):
                friction = tan_delta + mixture.dilatancy * (phi0[j] - mixture.phi_critical)
                slope = mean_slope(h0, j)
                (dt0, _, u1), (_, h1, u2) = stages[:2]  # the first attempt: the column at rest
                drives = (u1[j] / (g * dt0), 2 * u2[j] / (g * dt0))
                ratios.append(slope / friction)
                excess.append(drives[1] - mean_slope(h1, j))
                if len(ratios) <= args.shown:
                    print(
                        f"t = {sim.t:.5f} s (dt {dt:.3g} s): column {j} (h {h0[j] * 1e3:.2f} mm) "
                        f"set moving: mean slope {slope:.4f} = {slope / friction:.3f} of its static "
                        f"friction {friction:.4f}; transport drive {drives[0]:.4f} (stage 1, mean slope "
                        f"{slope:.4f}), {drives[1]:.4f} (stage 2, mean slope {mean_slope(h1, j):.4f}); "
                        f"neighbour u {u0[j + 1]:.2e} m/s; u at the end {sim.u[0][j]:.2e} m/s"
                    )
            passed = math.floor(sim.t / scenario.time.output_interval)
            if passed > outputs:  # an output interval passed: the pressures of the body
                outputs = passed
                pressure_ratios(sim, flow, scenario, tan_delta, moved, closure, measured)
                moved = sim.u[0] != 0.0
    if ratios:
        print(
            f"{len(ratios)} columns set moving: mean slope over static friction median "
            f"{np.median(ratios):.3f}, min {min(ratios):.3f}, max {max(ratios):.3f}; drive of the "
            f"second stage beyond its mean slope median {np.median(excess):.4f}, max "
            f"{max(excess):.4f} (units of the buoyant weight)"
        )
    if measured:
        gap = np.array(measured) - np.array(closure)
        print(
            f"moving body (h > {BODY * 1e3:.0f} mm), {gap.size} column-times: p_e / P "
            f"{np.median(measured):.3f} (median), minus the steady flowing closure: median "
            f"{np.median(gap):+.4f}, 5-95 % {np.percentile(gap, 5):+.4f} to {np.percentile(gap, 95):+.4f}"
        )


def pressure_ratios(
    sim: Simulation,
    flow: Any,
    scenario: Any,
    tan_delta: float,
    moved: np.ndarray,
    closure: list[float],
    measured: list[float],
) -> None:
    """Append ``p_e / P`` of the columns of the body moving now and at the last output
    interval passed (``moved``), and the flowing closure's value."""
    params, mixture = scenario.rheology.params, scenario.mixture
    h = sim.h
    phi = flow.phi(h)
    g_n = scenario.gravity * math.cos(math.radians(scenario.slope_deg))
    weight = (scenario.material.particle_density - scenario.fluid.density) * g_n * phi * h  # P
    slope = -np.gradient(h, sim.dx)
    body = np.flatnonzero((sim.u[0] != 0.0) & moved & (h > BODY))
    body = body[(body > 1) & (body < h.size - 2)]
    shift = mixture.critical_shift
    for j in body:
        measured.append(float(flow.pore_pressure[0, j] / weight[j]))
        friction = params["K1"] * (mixture.phi_critical - phi[j]) + shift * tan_delta
        closure.append(1 - shift * slope[j] / friction)


if __name__ == "__main__":
    main()
