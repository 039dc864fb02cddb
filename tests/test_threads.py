"""Thread policy of the compiled kernels, and what a CLI call that runs nothing imports."""

from __future__ import annotations

import importlib.metadata
import os
import subprocess
import sys
from pathlib import Path

import pytest

from multilayer.engine import threads
from multilayer.errors import InputError

ROOT = Path(__file__).resolve().parents[1]


def _installed(distribution: str) -> bool:
    try:
        importlib.metadata.distribution(distribution)
    except importlib.metadata.PackageNotFoundError:
        return False
    return True


def test_small_steps_run_on_one_thread_and_fixed_counts_are_kept(monkeypatch):
    monkeypatch.delenv(threads.ENVIRONMENT, raising=False)
    assert threads.ThreadPolicy("auto").threads(threads.PARALLEL_CELLS - 1) == 1
    assert threads.ThreadPolicy(1).threads(10**9) == 1


def test_auto_runs_large_steps_on_every_core(monkeypatch):
    import numba

    monkeypatch.delenv(threads.ENVIRONMENT, raising=False)
    policy = threads.ThreadPolicy("auto")
    assert policy.threads(10**9) == min(policy.cores, numba.config.NUMBA_NUM_THREADS)
    assert policy.threads(threads.PARALLEL_CELLS - 1) == 1
    assert policy.chosen[1] == 1


def test_the_thread_count_is_numbas_for_the_kernel_calls_only():
    """``numba_threads`` sets numba's thread count (and a chunk per task) for the calls of
    its block, and gives the caller's settings back; on one thread it touches nothing."""
    import numba

    before = numba.get_num_threads(), numba.get_parallel_chunksize()
    with threads.numba_threads(1):
        assert (numba.get_num_threads(), numba.get_parallel_chunksize()) == before
    if numba.config.NUMBA_NUM_THREADS >= 2:
        with threads.numba_threads(2):
            assert (numba.get_num_threads(), numba.get_parallel_chunksize()) == (2, 1)
    assert (numba.get_num_threads(), numba.get_parallel_chunksize()) == before


IMPORT_PROBE = """
import threading
from numba.core import event
registered = sum(len(listeners) for listeners in event._registered.values())
running = threading.active_count()
import multilayer.engine.simulation, multilayer.app.runner, multilayer.app.simulation
from multilayer.engine.vertical import column_solve
after = sum(len(listeners) for listeners in event._registered.values())
print(registered == after, threading.active_count() == running, column_solve._solve_serial.signatures == [])
"""


def test_importing_the_engine_registers_nothing_and_starts_no_thread():
    """No listener of numba's events, no thread and no kernel loaded or compiled at import."""
    done = subprocess.run([sys.executable, "-c", IMPORT_PROBE], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["True", "True", "True"]


def test_work_is_cut_into_chunks_per_thread_of_a_least_the_smallest_size():
    assert threads.parallel_chunks(2, 20_000, 64) == 2 * threads.CHUNKS_PER_THREAD
    assert threads.parallel_chunks(2, 200, 64) == 3  # 64 columns at least
    assert threads.parallel_chunks(2, 5) == 5
    assert threads.parallel_chunks(4, 0) == 1


@pytest.mark.skipif(not _installed("tbb"), reason="the optional tbb package is not installed")
def test_the_installed_tbb_is_numbas_threading_layer():
    """pip's tbb puts libtbb where numba's TBB layer does not look: loaded by threads.load_tbb
    before a parallel kernel in a fresh process (where NUMBA_THREADING_LAYER is not set),
    numba starts TBB."""
    code = (
        "import numba\nfrom multilayer.engine import threads\n"
        "with threads.numba_threads(2):\n    numba.get_num_threads()\n"
        "print(threads.load_tbb(), numba.threading_layer() == 'tbb')\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_THREADING_LAYER"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert out.stdout.split() == ["True", "True"]


def test_the_environment_overrides_the_scenario(monkeypatch):
    monkeypatch.setenv(threads.ENVIRONMENT, "1")
    assert threads.ThreadPolicy(2).fixed == 1
    monkeypatch.setenv(threads.ENVIRONMENT, "auto")
    assert threads.ThreadPolicy(2).fixed is None
    monkeypatch.setenv(threads.ENVIRONMENT, "two")
    with pytest.raises(InputError, match="MULTILAYER_THREADS='two'"):
        threads.ThreadPolicy("auto")


@pytest.mark.parametrize(
    "argv",
    [
        pytest.param(["--help"], marks=pytest.mark.slow),
        pytest.param(["plugins"], marks=pytest.mark.slow),
        ["validate", "scenarios/bagnold_chute.yaml"],
    ],
)
def test_commands_that_run_nothing_import_neither_fipy_nor_numba(argv):
    code = (
        "import sys\n"
        "from multilayer.app.cli import main\n"
        "try:\n"
        f"    code = main({argv!r})\n"
        "except SystemExit as exc:\n"
        "    code = exc.code\n"
        "print(code, sorted(m for m in ('fipy', 'numba') if m in sys.modules))\n"
    )
    # numba's cache in the package (where it is without NUMBA_CACHE_DIR): found without numba
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_CACHE_LOCATOR_CLASSES")}
    done = subprocess.run(  # from the repository: the scenario's path is relative to it
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env, cwd=ROOT
    )
    assert done.stdout.strip().splitlines()[-1] in ("0 []", "None []")  # the command did its work


def test_each_parallel_kernel_is_cached_apart_from_its_serial_compilation():
    """numba's on-disk cache names a compilation by the function's qualified name and line
    and keys it by signature only: compiled from the same function, a parallel kernel and
    its serial twin shared one entry and both loaded whichever was compiled last.  (The
    Newton step on one thread is its chunk kernel itself, ``newton_kernel._chunk``, which
    its parallel kernel calls per chunk: nothing is compiled twice there.)"""
    from multilayer.engine.transport import kernel as transport_kernel
    from multilayer.engine.vertical import column_solve as column_kernel

    pairs = [
        (column_kernel._solve_serial, column_kernel._solve_parallel),
        (transport_kernel._stages_serial, transport_kernel._stages_parallel),
    ]
    for serial, parallel in pairs:
        assert parallel.targetoptions.get("parallel") and not serial.targetoptions.get("parallel")
        assert parallel.py_func.__qualname__ == serial.py_func.__qualname__ + "_parallel"
        assert parallel.py_func.__code__.co_code == serial.py_func.__code__.co_code  # the same kernel
        names = {d._cache._cache_file._index_name for d in (serial, parallel)}  # the cache files
        assert len(names) == 2, names


_SIDE_BY_SIDE = """
import sys, threading
import numpy as np, multilayer
scenario = multilayer.load(sys.argv[1], {"numerics.threads": 2})
alone = multilayer.Simulation(scenario)
alone.advance(0.05)
same = []
def advance():
    sim = multilayer.Simulation(scenario)
    sim.advance(0.05)
    same.append(np.array_equal(sim.h, alone.h) and np.array_equal(sim.u, alone.u))
stepping = [threading.Thread(target=advance) for _ in range(3)]
[thread.start() for thread in stepping]
[thread.join() for thread in stepping]
print(same)
"""


@pytest.mark.slow  # 1-3 s of a child process or a large input, no physics
def test_simulations_in_threads_run_their_parallel_kernels_on_numbas_workqueue_layer(tmp_path, tiny_scenario):
    """numba's workqueue threading layer, where neither TBB nor OpenMP is found, is not
    thread-safe: three simulations on two kernel threads each, stepped side by side in three
    threads as docs/api.md allows, terminated the process (SIGABRT, "Concurrent access has
    been detected").  The parallel kernels' launches now take turns: each simulation ends
    with the state of one alone, to the bit."""
    import yaml

    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(tiny_scenario))
    env = {**os.environ, "NUMBA_THREADING_LAYER": "workqueue"}
    command = [sys.executable, "-c", _SIDE_BY_SIDE, str(path)]
    done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0 and done.stdout.strip() == "[True, True, True]", done.stderr


def test_a_fork_of_a_process_that_ran_gnu_openmp_threads_steps_on_one_thread(monkeypatch):
    """numba's GNU OpenMP layer cannot run in a forked process: its first parallel launch
    there sends the process SIGTERM (a child of multiprocessing's fork context, after a
    threaded run of its parent, stopped as if the user had).  Such a child's steps run on
    one thread, with one warning; the process that launched the threads, and another
    layer, keep their count."""
    import numba
    from numba.np.ufunc import omppool

    monkeypatch.delenv(threads.ENVIRONMENT, raising=False)
    monkeypatch.setattr(numba, "threading_layer", lambda: "omp")
    monkeypatch.setattr(omppool, "openmp_vendor", "GNU", raising=False)
    monkeypatch.setattr(threads, "_launched_in", os.getpid())
    threads._warn_forked.cache_clear()
    two = min(2, numba.config.NUMBA_NUM_THREADS)
    assert threads.ThreadPolicy(2).threads(10) == two
    monkeypatch.setattr(threads, "_launched_in", os.getppid())  # launched by the parent, before the fork
    with pytest.warns(UserWarning, match="a fork of one that ran numba's GNU OpenMP threads"):
        assert threads.ThreadPolicy(2).threads(10) == 1
    monkeypatch.setattr(numba, "threading_layer", lambda: "tbb")
    assert threads.ThreadPolicy(2).threads(10) == two
    threads._warn_forked.cache_clear()


FORKED_AFTER_THREADS = """
import multiprocessing, sys, warnings
import multilayer
def go(outdir):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        result = multilayer.run(sys.argv[1], outdir=outdir, overrides={'numerics.threads': 2})
    return result.attrs['run_status'], float(result['mass'][-1]), [str(w.message)[:40] for w in caught]
if __name__ == '__main__':
    parent = go(sys.argv[2] + '/parent')
    with multiprocessing.get_context('fork').Pool(1) as pool:
        child = pool.apply_async(go, (sys.argv[2] + '/child',)).get(timeout=600)
    print(parent[:2] == child[:2], child[2])
"""


@pytest.mark.slow  # compiles the parallel kernels on a cold cache
def test_a_run_on_two_threads_in_a_child_forked_after_a_threaded_run_completes(
    tmp_path, write_scenario, tiny_scenario
):
    script = tmp_path / "forked.py"
    script.write_text(FORKED_AFTER_THREADS)
    done = subprocess.run(
        [sys.executable, str(script), str(write_scenario(tiny_scenario)), str(tmp_path)],
        capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "Terminating" not in done.stderr
    same, warned = done.stdout.split(" ", 1)
    assert same == "True"  # the child's records are the parent's
    assert all(w.startswith("this process is a fork of one") for w in eval(warned))  # GNU OpenMP's only
