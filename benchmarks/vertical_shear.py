"""Benchmark: what ``model.vertical_shear`` (the shear stress on vertical planes,
docs/model.md) does to the channel collapse's run-out, per mesh.

Runs the validation case collapse_channel at each aspect ratio and cell size to the case's
end time with the option off and on, each in its own process, one at a time, and prints the
tip run-out (x_tip - L0) / L0 and the 95 %-mass run-out (x_95 - L0) / L0, their ratios to the
glass beads' 2D law (B, Lajeunesse, Monnier & Homsy 2005), the largest speed at the end and
the CPU time (``time.process_time``, loading or compiling the kernels included) of each run,
and with the option the kinetic energy its steps take from the vertical velocities (all
dissipated: docs/model.md) as a fraction of the initial potential energy ("taken"); with
``--history`` also the tip, the 95 %-mass front and the kinetic energy (of u and w, over the
initial potential energy) of each run at 0.05 to 0.3 s.
Each run stops at the case's output times (every 0.01 s), as the validation runs do: its
steps are cut there, and the deposit is the case's (``--no-stops``: only at those times and
the end, other steps).

    python benchmarks/vertical_shear.py [--ratios 2 7 10] [--cells 2e-3 1e-3 5e-4] [--history] [--no-stops]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from typing import Any, cast

HISTORY = (0.05, 0.1, 0.15, 0.2, 0.3)
"""The times (s) of the history: output times of the case's runs."""


def one(a: float, dx: float, sheared: bool, stops: bool = True) -> dict[str, Any]:
    """The run-outs, the speed at the end, the CPU time (s, compiling or loading the kernels
    included), the steps, the energy taken by the option and the history of one run: tip,
    95 %-mass front and kinetic energy (of u and w, over the initial potential energy) at the
    times :data:`HISTORY`.  The run stops at every output time of the validation case (its
    steps are cut there, as the runner cuts them), so its deposit is the case's; ``stops``
    false: only at the history's times and the end."""
    import numpy as np

    import multilayer
    from multilayer.app.runner import output_times
    from multilayer.engine.pressure.non_hydrostatic import NonHydrostatic
    from multilayer.io import observables
    from multilayer.validation.cases import collapse_channel as case
    from multilayer.validation.runs import Run

    base = case.run(a, dx)
    extra = ("model.vertical_shear=true",) if sheared else ()
    scenario = Run(base.name, base.scenario, (*base.overrides, *extra)).load()
    start = time.process_time()
    sim = multilayer.Simulation(scenario)
    layers = sim.fractions[:, None]
    removed = [0.0]  # the kinetic energy the shear step takes from w, per unit density and width
    if sheared:
        projection = cast(NonHydrostatic, sim.pressure).projection
        step = projection.shear
        assert step is not None

        def measured(h, u, start, dt, columns, w_star):
            before = w_star.copy()
            step(h, u, start, dt, columns, w_star)
            removed[0] += 0.5 * float((layers * h * (before**2 - w_star**2)).sum()) * sim.dx

        projection.shear = measured  # type: ignore[assignment]
    potential = sim.g_n * float((sim.h**2).sum()) * sim.dx / 2

    def fronts() -> tuple[float, float]:
        tip = observables.tip(sim.x, sim.h, scenario.material.grain_diameter)
        return (tip - case.L0) / case.L0, (observables.mass_front(sim.x, sim.h) - case.L0) / case.L0

    history = []
    times = (
        output_times(scenario.time.end, scenario.time.output_interval)
        if stops
        else (*HISTORY, case.end_time(a))
    )
    for t in times:
        sim.advance(float(t))
        if np.isclose(t, HISTORY).any():
            kinetic = 0.5 * float((layers * sim.h * (sim.u**2 + sim.w**2)).sum()) * sim.dx
            history.append((float(t), *fronts(), kinetic / potential))
    cpu = time.process_time() - start
    tip, mass = fronts()
    return {
        "tip": tip,
        "mass": mass,
        "law": case.law(a, case.LAWS[case.REFERENCE]),
        "speed": float(np.abs(sim.u).max()),
        "cpu": cpu,
        "steps": sim.steps,
        "removed": removed[0] / potential,
        "history": history,
    }


def child(a: float, dx: float, sheared: bool, stops: bool) -> dict[str, Any]:
    """:func:`one` in a child process."""
    arguments = [sys.executable, __file__, "--one", str(a), str(dx), "on" if sheared else "off"]
    arguments += [] if stops else ["--no-stops"]
    done = subprocess.run(arguments, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ratios", type=float, nargs="+", default=[2.0, 7.0, 10.0], help="aspect ratios a")
    parser.add_argument("--cells", type=float, nargs="+", default=[2e-3, 1e-3, 5e-4], help="cell sizes (m)")
    parser.add_argument("--history", action="store_true", help="also print the history of each run")
    parser.add_argument(
        "--no-stops", action="store_true", help="stop only at the history's times, not every output time"
    )
    parser.add_argument("--one", nargs=3, metavar=("A", "DX", "ON"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one is not None:
        print(json.dumps(one(float(args.one[0]), float(args.one[1]), args.one[2] == "on", not args.no_stops)))
        return
    print("a   | dx (mm) | option | tip   | tip/B | 95 % mass | mass/B | end speed | CPU (s) | steps | taken")
    for a in args.ratios:
        for dx in args.cells:
            for sheared in (False, True):
                r = child(a, dx, sheared, not args.no_stops)
                print(
                    f"{a:<3g} | {dx * 1e3:<7g} | {'on' if sheared else 'off':<6} | {r['tip']:5.2f} | "
                    f"{r['tip'] / r['law']:5.2f} | {r['mass']:9.2f} | {r['mass'] / r['law']:6.2f} | "
                    f"{r['speed']:9.2g} | {r['cpu']:7.1f} | {r['steps']:5d} | {r['removed']:.2%}",
                    flush=True,
                )
                for t, tip, mass, kinetic in r["history"] if args.history else ():
                    print(
                        f"    t = {t:g} s: tip {tip:.2f}, 95 % mass {mass:.2f}, kinetic energy {kinetic:.2%}"
                    )


if __name__ == "__main__":
    main()
