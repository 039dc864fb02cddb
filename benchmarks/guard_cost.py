"""Benchmark: the cost of the run guards on the mu(I) dam break of benchmarks/dam_break.py.

Times the same run with the guards (state guard every step, plugin-output checks, kernel
input checks) and with them replaced by no-ops, alternating ``--repeat`` times, and
prints the median of each and the relative cost (docs/reliability.md).

    python benchmarks/guard_cost.py [--cells 1000] [--layers 16] [--end 2] [--repeat 3]
"""

from __future__ import annotations

import argparse
import statistics
import time
from contextlib import contextmanager
from unittest import mock

import numpy as np
from dam_break import scenario

from multilayer.app.simulation import Simulation
from multilayer.engine import state_check
from multilayer.engine.vertical import column_solve as column_kernel


def _unchecked_call(plugin, method, args, **_):
    return np.asarray(getattr(plugin, method)(*args), dtype=float)


@contextmanager
def guards_off():
    """The guards replaced by no-ops (the plugin call itself is kept)."""
    with (
        mock.patch.object(state_check.StateGuard, "check_step", lambda *a, **k: None),
        mock.patch.object(state_check.StateGuard, "check_state", lambda *a, **k: None),
        mock.patch.object(column_kernel, "_require_finite", lambda *a: None),
        mock.patch("multilayer.engine.vertical.stresses.call", _unchecked_call),
    ):
        yield


def timed(args: argparse.Namespace) -> tuple[float, int]:
    sim = Simulation(scenario(args.cells, args.layers, 2, args.end))
    start = time.perf_counter()
    sim.advance(args.end)
    return time.perf_counter() - start, sim.steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=1000)
    parser.add_argument("--layers", type=int, default=16)
    parser.add_argument("--end", type=float, default=2.0)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    Simulation(scenario(args.cells, args.layers, 2, args.end)).step(1e-9)  # compile the kernels
    with_guards, without = [], []
    for repeat in range(args.repeat):
        for guarded in (True, False) if repeat % 2 else (False, True):  # alternate the order
            if guarded:
                elapsed, steps = timed(args)
                with_guards.append(elapsed)
            else:
                with guards_off():
                    elapsed, steps_off = timed(args)
                without.append(elapsed)
    assert steps == steps_off
    on, off = statistics.median(with_guards), statistics.median(without)
    size = f"{args.cells} cells x {args.layers} layers"
    print(f"{size} to t = {args.end:g}: {steps} steps, {args.repeat} repeats")
    print(f"with guards {on:.3f} s, without {off:.3f} s (medians): cost {100 * (on - off) / off:+.2f} %")
    print(f"per step: {1e3 * (on - off) / steps:+.3f} ms of {1e3 * on / steps:.2f} ms")


if __name__ == "__main__":
    main()
