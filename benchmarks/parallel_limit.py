"""Benchmark control: a kernel with no serial part, run the way the engine runs its kernels.

The probe kernel of multilayer/engine/threads.py (pieces of 20 000 multiply-adds
``x <- 0.999999 x + 1``, handed out one at a time) is run ``--repeats`` times through
``threads.run_bound`` on the threads the engine would use for a large step (``auto``:
every core, each thread bound to one), about 19 ms per run: as long as one of the
chute's parallel kernels.
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

from multilayer.engine import threads

PIECES_PER_THREAD = 512
"""About 19 ms per run of the kernel, as long as the chute's parallel kernels."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", default="auto")
    parser.add_argument("--repeats", type=int, default=100, help="runs of the kernel (default 100)")
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error("--repeats takes an integer >= 1")
    threads.steals_work()  # numba's TBB layer, as the engine starts it
    policy = threads.ThreadPolicy(args.threads if args.threads == "auto" else int(args.threads))
    count = policy.threads(threads.PARALLEL_CELLS)  # as for a large step
    numba.set_num_threads(count)  # (the engine runs a serial kernel on one thread)
    work = np.zeros(PIECES_PER_THREAD * count)
    threads.run_bound(threads._probe, (work,))  # compiled or loaded, and threads bound, untimed
    start, cpu = time.perf_counter(), time.process_time()
    for _ in range(args.repeats):
        threads.run_bound(threads._probe, (work,))
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    exact = (1.0 - threads.PROBE_FACTOR**threads.PROBE_STEPS) / (1.0 - threads.PROBE_FACTOR)
    error = float(np.abs(work / exact - 1.0).max())
    print(f"parallel limit: {work.size} pieces of {threads.PROBE_STEPS} multiply-adds, {args.repeats} runs")
    print(f"time to solution {seconds:.3f} s (CPU {cpu:.3f} s), steps {args.repeats}")
    print(
        f"threads: {count} in {args.repeats} passes (a pass: a run of the kernel); threading layer "
        f"{'tbb' if threads.steals_work() else 'not tbb'}"
        + (", threads bound to cores" if threads.workers_bound() and count > 1 else "")
    )
    print(f"check: every piece within {error:.1e} of the geometric sum {exact:.6f}")


if __name__ == "__main__":
    main()
