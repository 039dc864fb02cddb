"""Shared timing and reporting of the benchmark scripts (not a benchmark itself).

Every benchmark prints the time to solution, the steps, the cell-steps per second counted
two ways (the whole mesh, and the cells holding material, h > 0, after each step: what
was actually computed) and the load average of the machine at the end of the timing.
"""

from __future__ import annotations

import cProfile
import os
import pstats
import resource
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from multilayer.app.simulation import Simulation
from multilayer.engine.threads import ThreadPolicy, available_cores


@dataclass
class Timing:
    seconds: float
    cpu_seconds: float  # CPU time of this process (all threads)
    steps: int
    cells: int  # cells of the whole mesh
    computed: int  # cell-steps on cells holding material
    newton: float  # Newton iterations per step
    load: float  # 1-minute load average at the end
    peak_bytes: int  # peak resident memory of the process
    fallback_share: float  # column solves that needed the O(L^2) dynamic programme
    side_by_side_share: float  # column steps solved side by side (engine/sheared_columns.py)
    threads: dict[int, int]  # steps run with each thread count
    layer: str  # numba's threading layer (threads.py: TBB steals work)

    def lines(self) -> list[str]:
        return [
            f"time to solution {self.seconds:.3f} s (CPU {self.cpu_seconds:.3f} s), steps {self.steps}, "
            f"Newton iterations per step {self.newton:.2f}, "
            f"O(L^2) fallback in {100 * self.fallback_share:.3f} % of the column solves, "
            f"{100 * self.side_by_side_share:.1f} % of the column steps solved side by side",
            f"cell-steps/s: {self.cells * self.steps / self.seconds / 1e6:.2f} M (whole mesh), "
            f"{self.computed / self.seconds / 1e6:.2f} M (cells holding material)",
            f"peak memory {self.peak_bytes / 2**20:.0f} MiB "
            f"({self.peak_bytes / self.cells:.0f} bytes per mesh cell), load average {self.load:.2f}",
            "threads: "
            + ", ".join(f"{n} in {k} steps" for n, k in sorted(self.threads.items()))
            + f"; threading layer {self.layer}",
        ]


def threading_layer() -> str:
    """numba's threading layer, if a parallel kernel has run."""
    import numba

    try:
        return str(numba.threading_layer())
    except ValueError:  # no parallel kernel ran
        return "not started"


def peak_memory() -> int:
    """Peak resident memory of this process so far, bytes (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def timed(
    make: Callable[[], Simulation],
    end: float,
    *,
    profile: bool = False,
    warm_up: Callable[[], Simulation] | None = None,
) -> tuple[Simulation, Timing]:
    """Run ``make()`` to ``end`` and time it.  ``warm_up()`` makes a problem whose steps
    run the kernels of the timed one: a step of it on one thread and, on a machine with
    several cores, one on two compile them first, outside the timing (the parallel ones
    are compiled and cached apart).  On two threads the transport cuts its window of
    moving columns into chunks only from ``2 x 64`` columns on (``threads.parallel_chunks``):
    a smaller window would leave the parallel transport to compile within the timing."""
    if warm_up is not None:
        for threads in sorted({1, min(2, available_cores())}):
            probe = warm_up()
            probe.thread_policy = ThreadPolicy(threads)
            probe.step(probe.t + 1e-9)
            del probe
    sim = make()
    sim.thread_policy.chosen.clear()
    layers = sim.fractions.size
    computed = [0]

    def count(s: Any, dt: float) -> None:
        # a read-only view: sim.h would be checked at the next step
        computed[0] += layers * int(np.count_nonzero(s.read_only("h") > 0.0))

    # the profile counts CPU time of this process: on a shared machine wall time also
    # counts the other processes
    profiler = cProfile.Profile(time.process_time) if profile else None
    start, cpu = time.perf_counter(), time.process_time()
    if profiler:
        profiler.enable()
    sim.advance(end, on_step=count)
    if profiler:
        profiler.disable()
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    compiled = sim.vertical.compiled
    timing = Timing(
        seconds,
        cpu,
        sim.steps,
        sim.cells,
        computed[0],
        sim.newton_iterations / max(sim.steps, 1),
        os.getloadavg()[0],
        peak_memory(),
        compiled.fallbacks / max(compiled.solves, 1) if compiled else float("nan"),
        compiled.columns_side_by_side / max(compiled.columns, 1) if compiled else float("nan"),
        dict(sim.thread_policy.chosen),
        threading_layer(),
    )
    if profiler:
        pstats.Stats(profiler).sort_stats("tottime").print_stats(15)
    return sim, timing
