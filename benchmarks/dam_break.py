"""Benchmark: the multilayer mu(I) dam break of docs/performance.md (the peer problem).

Reduced units (g = 1): 2500 cells x 32 layers on x in [0, 50], a bed falling 0.45 per
unit length, a unit-height column on [0, 2], Jop mu(I) with mu_s = 0.35, mu_2 = 0.56,
I_0 = 0.4, grain diameter 1/32, densities 1, no-slip base, wall on the left, outflow on
the right, run to t = 5.  The check: mass conserved (2 up to what left through the
outflow, none here) and the front position, about x = 10 at second order (x = 9.0 for
the first-order C code with regularised yield that docs/performance.md times beside it).

    python benchmarks/dam_break.py [--cells 2500] [--layers 32] [--order 2] [--threads auto] [--profile]
        [--pressure hydrostatic | bim2016 | non_hydrostatic] [--pressure-layers N] [--compare]
        [--peer COMMAND [--pairs N]] [--overhead]

``--compare`` runs the hydrostatic model and then the ``--pressure`` option in the same
invocation and prints the ratio of their times to solution (the cost of the pressure).
``--pressure-layers`` sets ``model.pressure_layers`` of the non-hydrostatic option
(default: the scenario default, docs/nonhydrostatic.md).  ``--peer`` times a peer code
(a shell command, run in a temporary directory, its output discarded) right before each
of ``--pairs`` runs of the dam break, and prints the ratio of each pair and their median:
the machine's speed drifts within minutes, so only runs close in time compare.
``--overhead`` runs the problem once more and prints its CPU time per step and the part of
it inside the compiled kernels called from Python: the rest is the fixed cost of a step
outside them, most of a step on a small mesh (``--cells 250``).
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from functools import partial
from typing import Any

import numpy as np
from common import timed
from numba.core.registry import CPUDispatcher

from multilayer.app.simulation import Simulation
from multilayer.scenario import Scenario, from_dict

WARM_UP_COLUMN = 20.0
"""Length of the column of the warm-up problem (the benchmark's is 2): ten times the
benchmark's, so that its window of moving columns is long enough for two threads to cut
it into chunks at 500 cells and more, and the warm-up compiles the parallel transport."""


def simulation(problem: Callable[..., Scenario], **changes: Any) -> Simulation:
    """A simulation of ``problem(**changes)``."""
    return Simulation(problem(**changes))


def scenario(
    cells: int,
    layers: int,
    order: int,
    end: float,
    threads="auto",
    pressure: str = "hydrostatic",
    pressure_layers: int | None = None,
    column: float = 2.0,
):
    model: dict = {"pressure": pressure}
    if pressure == "non_hydrostatic" and pressure_layers is not None:
        model["pressure_layers"] = pressure_layers
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
            "initial": [{"shape": "rectangle", "x_min": 0.0, "x_max": column, "height": 1.0}],
            "boundaries": {"left": "wall", "right": "outflow"},
            "time": {"end": end, "output_interval": end},
            "numerics": {"order": order, "threads": threads},
            "model": model,
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
    parser.add_argument("--pressure-layers", type=int, default=None)
    parser.add_argument("--threads", default="auto")
    parser.add_argument(
        "--compare", action="store_true", help="run the hydrostatic model first and print the cost ratio"
    )
    parser.add_argument("--profile", action="store_true", help="print the 15 costliest functions")
    parser.add_argument("--peer", metavar="COMMAND", help="a peer code to time before each run")
    parser.add_argument("--pairs", type=int, default=1, help="runs of the peer and the dam break (default 1)")
    parser.add_argument("--overhead", action="store_true", help="the CPU time per step outside the kernels")
    args = parser.parse_args()
    if args.pairs < 1 or (args.pairs > 1 and args.peer is None):
        parser.error("--pairs takes an integer >= 1, and more than 1 only with --peer")
    if args.peer is not None and args.compare:
        parser.error("--peer and --compare time different things: use one of them")
    threads = args.threads if args.threads == "auto" else int(args.threads)
    pressures = ["hydrostatic", args.pressure] if args.compare else [args.pressure] * args.pairs
    seconds = {}
    ratios = []
    size = (args.cells, args.layers, args.order, args.end, threads)
    for pressure in pressures:
        if args.peer is not None:
            peer = time_peer(args.peer)
            print(f"peer: {args.peer!r} took {peer:.3f} s (wall)")
        problem = partial(scenario, *size, pressure, args.pressure_layers)
        sim, timing = timed(
            partial(simulation, problem),
            args.end,
            profile=args.profile,
            # the same problem with a longer column (WARM_UP_COLUMN)
            warm_up=partial(simulation, problem, column=WARM_UP_COLUMN),
        )
        seconds[pressure] = timing.seconds
        d = sim.diagnostics()
        print(
            f"dam break: {args.cells} cells x {args.layers} layers, order {args.order}, "
            f"pressure {pressure}"
            + (
                f" on {sim.config.pressure.options['pressure_layers']} pressure layers"
                if pressure == "non_hydrostatic"
                else ""
            )
            + f", t = {sim.t:g}"
        )
        print("\n".join(timing.lines()))
        print(
            f"check: front x = {d['front']:.3f} (threshold {sim.front_threshold:g}), mass {d['mass']:.12f} "
            f"(initially 2), max |u| {np.abs(sim.u).max():.3f}"
        )
        if args.overhead:
            print(overhead(partial(simulation, problem), args.end))
        if args.peer is not None:
            ratios.append(peer / timing.seconds)
            print(f"pair {len(ratios)}: the peer took {ratios[-1]:.2f} times the time to solution")
    if args.compare:
        ratio = seconds[args.pressure] / seconds["hydrostatic"]
        print(f"cost of pressure {args.pressure}: {ratio:.2f} times the hydrostatic time to solution")
    if len(ratios) > 1:
        listed = ", ".join(f"{r:.2f}" for r in ratios)
        median = statistics.median(ratios)
        print(f"peer / multilayer over {len(ratios)} pairs: median {median:.2f} ({listed})")


def overhead(make: Callable[[], Simulation], end: float) -> str:
    """The CPU time per step of ``make()`` run to ``end`` (its kernels compiled by a run
    before), and its part inside the compiled kernels called from Python."""
    spent = [0.0]
    sim = make()
    with kernels_timed(spent):
        start = time.process_time()
        sim.advance(end)
        total = time.process_time() - start
    per_step = 1e6 / sim.steps
    return (
        f"per step: CPU {total * per_step:.0f} us, of which {spent[0] * per_step:.0f} us in the compiled "
        f"kernels called from Python and {(total - spent[0]) * per_step:.0f} us outside them"
    )


@contextlib.contextmanager
def kernels_timed(spent: list[float]) -> Iterator[None]:
    """Within, each numba dispatcher of the engine's modules (and each partial of one) is
    wrapped in a timer that adds its calls' CPU time to ``spent[0]`` (the timer's own cost,
    about a microsecond a call, counted inside); the modules are given back after."""
    wrapped: dict[int, Callable[..., Any]] = {}

    def timer(kernel: Any) -> Callable[..., Any]:
        def call(*args: Any) -> Any:
            start = time.process_time()
            try:
                return kernel(*args)
            finally:
                spent[0] += time.process_time() - start

        return wrapped.setdefault(id(kernel), call)

    replaced: list[tuple[Any, str, Any]] = []
    for name, module in list(sys.modules.items()):
        if name.startswith("multilayer.engine") and module is not None:
            for attribute, value in list(vars(module).items()):
                if isinstance(value, CPUDispatcher):
                    replaced.append((module, attribute, value))
                    setattr(module, attribute, timer(value))
                elif isinstance(value, partial) and isinstance(value.func, CPUDispatcher):
                    replaced.append((module, attribute, value))
                    setattr(module, attribute, partial(timer(value.func), *value.args))
    try:
        yield
    finally:
        for module, attribute, value in replaced:
            setattr(module, attribute, value)


def time_peer(command: str) -> float:
    """Wall time of a shell command run in a temporary directory (a peer code writes its
    output files where it runs); a failure stops the benchmark with its message."""
    with tempfile.TemporaryDirectory() as directory:
        start = time.perf_counter()
        done = subprocess.run(command, shell=True, cwd=directory, capture_output=True, text=True)
        seconds = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"peer command {command!r} failed (exit {done.returncode}): {done.stderr.strip()}")
    return seconds


if __name__ == "__main__":
    main()
