"""Benchmark control: a kernel with no serial part, run the way the engine runs its kernels.

A probe kernel (pieces of 20 000 multiply-adds ``x <- 0.999999 x + 1``, handed out one at
a time, as the engine's parallel kernels hand out their chunks) is run ``--repeats`` times
with the settings of ``threads.numba_threads`` on the threads the engine would use for a large step
(``auto``: every core), about 19 ms per run: as long as one of the chute's parallel
kernels.
benchmarks/threads.py runs it beside the dam break and the chute: a run whose work is
all parallel shows what two threads can get beside a busy process on this machine, the
limit for the others.  Check: every piece ends at the geometric sum
``(1 - 0.999999^20000) / (1 - 0.999999)``.

    python benchmarks/parallel_limit.py [--threads auto] [--repeats 100]
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np
from numba import njit, prange

from multilayer.engine import threads

PIECES_PER_THREAD = 512
"""About 19 ms per run of the kernel, as long as the chute's parallel kernels."""
STEPS, FACTOR = 20_000, 0.999999
"""Each piece of the probe kernel: ``x <- FACTOR x + 1``, ``STEPS`` times from 0."""


@njit(cache=True, parallel=True)
def probe(work: np.ndarray) -> None:
    """``work.size`` pieces of ``STEPS`` multiply-adds (about 40 microseconds each)."""
    for k in prange(work.size):
        x = 0.0
        for _ in range(STEPS):
            x = x * FACTOR + 1.0
        work[k] = x


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", default="auto")
    parser.add_argument("--repeats", type=int, default=100, help="runs of the kernel (default 100)")
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error("--repeats takes an integer >= 1")
    policy = threads.ThreadPolicy(args.threads if args.threads == "auto" else int(args.threads))
    count = policy.threads(threads.PARALLEL_CELLS)  # as for a large step
    work = np.zeros(PIECES_PER_THREAD * count)
    threads.load_tbb()  # numba's settings as threads.numba_threads makes them for a parallel kernel
    numba.set_num_threads(count)
    numba.set_parallel_chunksize(1)
    probe(work)  # compiled or loaded, untimed
    start, cpu = time.perf_counter(), time.process_time()
    for _ in range(args.repeats):
        probe(work)
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    layer = numba.threading_layer()
    exact = (1.0 - FACTOR**STEPS) / (1.0 - FACTOR)
    error = float(np.abs(work / exact - 1.0).max())
    print(f"parallel limit: {work.size} pieces of {STEPS} multiply-adds, {args.repeats} runs")
    print(f"time to solution {seconds:.3f} s (CPU {cpu:.3f} s), steps {args.repeats}")
    print(f"threads: {count} in {args.repeats} steps (a step: a run of the kernel); threading layer {layer}")
    print(f"check: every piece within {error:.1e} of the geometric sum {exact:.6f}")


if __name__ == "__main__":
    main()
