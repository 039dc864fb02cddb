"""Benchmark: what ``model.vertical_shear`` (the shear stress on vertical planes,
docs/model.md) does to the channel collapse's run-out, per mesh.

Runs the validation case collapse_channel at each aspect ratio and cell size to the case's
end time with the option off and on, each in its own process, one at a time, and prints the
tip run-out (x_tip - L0) / L0 and the 95 %-mass run-out (x_95 - L0) / L0, their ratios to the
glass beads' 2D law (B, Lajeunesse, Monnier & Homsy 2005), the largest speed at the end and
the CPU time (``time.process_time``) of each run, and with the option the kinetic energy its
steps take from the vertical velocities (all dissipated: docs/model.md) as a fraction of the
initial potential energy ("taken").

    python benchmarks/vertical_shear.py [--ratios 2 7 10] [--cells 2e-3 1e-3 5e-4]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from typing import cast


def one(a: float, dx: float, sheared: bool) -> dict[str, float]:
    """The run-outs, the speed at the end, the CPU time (s) and the steps of one run."""
    import numpy as np
    from common import run_to

    import multilayer
    from multilayer.engine.pressure.non_hydrostatic import NonHydrostatic
    from multilayer.io import observables
    from multilayer.validation.cases import collapse_channel as case
    from multilayer.validation.runs import Run

    base = case.run(a, dx)
    extra = ("model.vertical_shear=true",) if sheared else ()
    scenario = Run(base.name, base.scenario, (*base.overrides, *extra)).load()
    sim = multilayer.Simulation(scenario)
    removed = [0.0]  # the kinetic energy the shear step takes from w, per unit density and width
    if sheared:
        projection = cast(NonHydrostatic, sim.pressure).projection
        step = projection.shear
        assert step is not None
        layers = sim.fractions[:, None]

        def measured(h, u, start, dt, columns, w_star):
            before = w_star.copy()
            step(h, u, start, dt, columns, w_star)
            removed[0] += 0.5 * float((layers * h * (before**2 - w_star**2)).sum()) * sim.dx

        projection.shear = measured  # type: ignore[assignment]
    potential = sim.g_n * float((sim.h**2).sum()) * sim.dx / 2
    cpu = run_to(sim, case.end_time(a))
    tip = observables.tip(sim.x, sim.h, scenario.material.grain_diameter)
    mass = observables.mass_front(sim.x, sim.h)
    return {
        "tip": (tip - case.L0) / case.L0,
        "mass": (mass - case.L0) / case.L0,
        "law": case.law(a, case.LAWS[case.REFERENCE]),
        "speed": float(np.abs(sim.u).max()),
        "cpu": cpu,
        "steps": sim.steps,
        "removed": removed[0] / potential,
    }


def child(a: float, dx: float, sheared: bool) -> dict[str, float]:
    """:func:`one` in a child process."""
    arguments = [sys.executable, __file__, "--one", str(a), str(dx), "on" if sheared else "off"]
    done = subprocess.run(arguments, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ratios", type=float, nargs="+", default=[2.0, 7.0, 10.0], help="aspect ratios a")
    parser.add_argument("--cells", type=float, nargs="+", default=[2e-3, 1e-3, 5e-4], help="cell sizes (m)")
    parser.add_argument("--one", nargs=3, metavar=("A", "DX", "ON"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one is not None:
        print(json.dumps(one(float(args.one[0]), float(args.one[1]), args.one[2] == "on")))
        return
    print("a   | dx (mm) | option | tip   | tip/B | 95 % mass | mass/B | end speed | CPU (s) | steps | taken")
    for a in args.ratios:
        for dx in args.cells:
            for sheared in (False, True):
                r = child(a, dx, sheared)
                print(
                    f"{a:<3g} | {dx * 1e3:<7g} | {'on' if sheared else 'off':<6} | {r['tip']:5.2f} | "
                    f"{r['tip'] / r['law']:5.2f} | {r['mass']:9.2f} | {r['mass'] / r['law']:6.2f} | "
                    f"{r['speed']:9.2g} | {r['cpu']:7.1f} | {r['steps']:5d} | {r['removed']:.2%}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
