"""Study: the channel collapse with and without the longitudinal normal stress.

Runs the recommended collapse (``scenarios/column_collapse_channel.yaml`` as the validation
case ``collapse_channel`` sets it up) at aspect ratio ``a`` with cells ``dx``, with
``model.normal_stress`` off (to the case's end time) or on (to twice that: the flow lasts
longer), and prints one line of the case's measures: the tip run-out 3 grain diameters
above the bed (L_f - L0)/L0 and its ratio to the glass beads' law (law B, Lajeunesse,
Monnier & Homsy 2005), the 95 %-mass run-out, the stopping time of the tip over
sqrt(H0/g), the largest speed at the end, the steps and the CPU time.

    python benchmarks/normal_stress_study.py [--ratios 2 4 7] [--dx 2e-3 1e-3 5e-4] [--modes off on]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from multilayer.app.simulation import Simulation
from multilayer.io import observables
from multilayer.validation.cases import collapse_channel
from multilayer.validation.runs import Run


def study(a: float, dx: float, on: bool) -> str:
    """The line of measures of one run."""
    base = collapse_channel.run(a, dx)
    end = collapse_channel.end_time(a) * (2 if on else 1)
    sets = (f"model.normal_stress={'true' if on else 'false'}", f"time.end={end:g}")
    sim = Simulation(Run(base.name, base.scenario, (*base.overrides, *sets)).load())
    grain = sim.vertical.stresses.material.grain_diameter
    cpu = time.process_time()
    times, tips = [0.0], [observables.tip(sim.x, sim.h, grain)]
    for t in np.arange(1, round(end / 0.01) + 1) * 0.01:  # the case's output interval
        sim.advance(float(t))
        times.append(float(t))
        tips.append(observables.tip(sim.x, sim.h, grain))
    tip = (tips[-1] - collapse_channel.L0) / collapse_channel.L0
    mass = (observables.mass_front(sim.x, sim.h) - collapse_channel.L0) / collapse_channel.L0
    law = collapse_channel.law(a, collapse_channel.LAWS["B"])
    stop = observables.front_stop_time(np.array(times), np.array(tips)) / math.sqrt(
        a * collapse_channel.L0 / 9.81
    )
    return (
        f"a = {a:g}, dx = {dx * 1e3:g} mm, normal stress {'on' if on else 'off'}: tip {tip:.3f} "
        f"({tip / law:.3f} x law B), 95 %-mass {mass:.3f}, t_stop {stop:.2f} sqrt(H0/g), "
        f"max |u| at the end {np.abs(sim.u).max():.1e} m/s, {sim.steps} steps, "
        f"CPU {time.process_time() - cpu:.0f} s"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ratios", type=float, nargs="+", default=[2.0, 4.0, 7.0], help="aspect ratios a")
    parser.add_argument("--dx", type=float, nargs="+", default=[2e-3, 1e-3, 5e-4], help="cell sizes (m)")
    parser.add_argument("--modes", nargs="+", choices=["off", "on"], default=["off", "on"])
    args = parser.parse_args()
    for dx in args.dx:
        for a in args.ratios:
            for mode in args.modes:
                print(study(a, dx, mode == "on"), flush=True)


if __name__ == "__main__":
    main()
