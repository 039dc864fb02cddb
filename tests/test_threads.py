"""Thread policy of the compiled kernels, and what a CLI call that runs nothing imports."""

from __future__ import annotations

import importlib.metadata
import json
import os
import subprocess
import sys

import pytest

from multilayer.engine import threads
from multilayer.errors import InputError


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


def test_without_work_stealing_auto_starts_on_one_thread_until_the_idle_cores_are_measured(monkeypatch):
    monkeypatch.delenv(threads.ENVIRONMENT, raising=False)
    monkeypatch.setattr(threads, "steals_work", lambda: False)
    assert threads.ThreadPolicy("auto").threads(10**9) == 1


def test_with_work_stealing_auto_runs_large_steps_on_every_core(monkeypatch):
    import numba

    monkeypatch.delenv(threads.ENVIRONMENT, raising=False)
    monkeypatch.setattr(threads, "steals_work", lambda: True)
    policy = threads.ThreadPolicy("auto")
    expected = min(policy.cores, numba.config.NUMBA_NUM_THREADS)
    try:
        assert policy.threads(10**9) == expected
        assert numba.get_parallel_chunksize() == (1 if expected > 1 else 0)
    finally:
        numba.set_parallel_chunksize(0)
    assert policy.threads(threads.PARALLEL_CELLS - 1) == 1


def test_work_is_cut_into_chunks_per_thread_of_a_least_the_smallest_size():
    assert threads.parallel_chunks(2, 20_000, 64) == 2 * threads.CHUNKS_PER_THREAD
    assert threads.parallel_chunks(2, 200, 64) == 3  # 64 columns at least
    assert threads.parallel_chunks(2, 5) == 5
    assert threads.parallel_chunks(4, 0) == 1


@pytest.mark.skipif(not _installed("tbb"), reason="the tbb package is not installed")
def test_the_installed_tbb_is_numbas_threading_layer():
    """pip's tbb puts libtbb where numba's TBB layer does not look: loaded by threads.load_tbb
    in a fresh process (where NUMBA_THREADING_LAYER is not set), numba starts TBB."""
    code = "from multilayer.engine import threads\nprint(threads.load_tbb(), threads.steals_work())\n"
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


def test_binding_is_on_unless_its_environment_variable_is_0_and_other_values_are_refused(monkeypatch):
    monkeypatch.delenv(threads.ENVIRONMENT, raising=False)
    for value, wanted in (("", True), ("1", True), ("0", False)):
        monkeypatch.setenv(threads.BIND_ENVIRONMENT, value)
        assert threads.binding_wanted() is wanted
    monkeypatch.setenv(threads.BIND_ENVIRONMENT, "false")
    with pytest.raises(InputError, match=r"MULTILAYER_BIND_THREADS='false'; accepted: 0 \(off\) or 1"):
        threads.ThreadPolicy("auto")


@pytest.mark.parametrize("argv", [["--help"], ["plugins"], ["validate", "scenarios/bagnold_chute.yaml"]])
def test_commands_that_run_nothing_import_neither_fipy_nor_numba(argv):
    code = (
        "import sys\n"
        "from multilayer.app.cli import main\n"
        "try:\n"
        f"    main({argv!r})\n"
        "except SystemExit:\n"
        "    pass\n"
        "print(sorted(m for m in ('fipy', 'numba') if m in sys.modules))\n"
    )
    # numba's cache in the package (where it is without NUMBA_CACHE_DIR): found without numba
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_CACHE_LOCATOR_CLASSES")}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert done.stdout.strip().splitlines()[-1] == "[]"


def test_each_parallel_kernel_is_cached_apart_from_its_serial_compilation():
    """numba's on-disk cache names a compilation by the function's qualified name and line
    and keys it by signature only: compiled from the same function, a parallel kernel and
    its serial twin shared one entry and both loaded whichever was compiled last.  (The
    Newton step on one thread is its chunk kernel itself, ``newton_kernel._chunk``, which
    its parallel kernel calls per chunk: nothing is compiled twice there.)"""
    from multilayer.engine import column_kernel, transport_kernel

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


BIND_PROBE = """
import json, os, sys, threading
os.sched_setaffinity(0, sorted(os.sched_getaffinity(0))[:2])  # two cores, before numba starts
sys.path.insert(0, {tests!r})
import numpy as np
from test_transport_kernel import random_state
from multilayer.engine import threads, transport_kernel
h, u, b, fractions = random_state(seed=1)
kw = dict(dx=0.1, dt=0.004, g_n=9.0, g_t=1.5, left="wall", right="outflow", dry=1e-6, order=2)
one = [a.copy() for a in transport_kernel.transport(h, u, b, fractions, threads=1, **kw)]

def where():
    two = transport_kernel.transport(h, u, b, fractions, threads=2, **kw)
    same = all(np.array_equal(x, y) for x, y in zip(one, two))
    bound = threads.workers_bound()  # by the transport step
    held = threads.run_bound(lambda: sorted(os.sched_getaffinity(0)), ())  # where a kernel runs
    cores = {{int(t): sorted(os.sched_getaffinity(int(t))) for t in os.listdir("/proc/self/task")}}
    caller = cores.pop(threading.get_native_id())
    return dict(bound=bound, same=same, held=held, caller=caller, others=sorted(cores.values()))

os.environ[threads.BIND_ENVIRONMENT] = "0"
off = where()
del os.environ[threads.BIND_ENVIRONMENT]
print(json.dumps(dict(tbb=threads.steals_work(), off=off, on=where())))
"""


@pytest.fixture(scope="module")
def bind_probe() -> dict:
    """Where the threads of a fresh process on two cores run after a transport step on two
    threads, with ``MULTILAYER_BIND_THREADS=0`` (``off``), then without it (``on``), and
    whether each step gave the bits of the one-thread step."""
    code = BIND_PROBE.format(tests=os.path.dirname(os.path.abspath(__file__)))
    environment = {**os.environ, "NUMBA_NUM_THREADS": "2"}
    for name in (threads.ENVIRONMENT, threads.BIND_ENVIRONMENT):
        environment.pop(name, None)
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=environment
    )
    return dict(json.loads(out.stdout.strip().splitlines()[-1]))


needs_two_cores_and_tbb = pytest.mark.skipif(
    not _installed("tbb") or threads.available_cores() < 2, reason="needs TBB and two cores"
)


@needs_two_cores_and_tbb
def test_a_kernel_on_every_core_runs_each_thread_on_a_core_of_its_own(bind_probe):
    """The TBB worker is bound to the second core; the calling thread runs each parallel
    kernel on the first and may run on both between kernels."""
    probe = bind_probe["on"]
    assert bind_probe["tbb"] and probe["bound"] and probe["same"]
    both = probe["caller"]
    assert len(both) == 2 and probe["held"] == both[:1]
    assert probe["others"].count(both[1:]) == 1  # the worker, alone on the second core
    assert all(cores == both for cores in probe["others"] if cores != both[1:])  # the others untouched


@needs_two_cores_and_tbb
def test_binding_is_turned_off_by_its_environment_variable(bind_probe):
    probe = bind_probe["off"]
    assert not probe["bound"] and probe["same"]
    assert probe["held"] == probe["caller"] and len(probe["caller"]) == 2
    assert all(cores == probe["caller"] for cores in probe["others"])


@needs_two_cores_and_tbb
def test_a_kernel_compiled_inside_a_held_call_compiles_on_every_core(monkeypatch):
    """numba compiles a kernel inside its first call with new argument types, for seconds
    on the calling thread: held on one core, two processes compiling at once would share
    it.  At the start of a compilation the held caller gets every core back."""
    from numba.core import event

    allowed = os.sched_getaffinity(0)
    binding = threads._Binding()
    binding.bound = binding.probed = True
    monkeypatch.setattr(threads, "_binding", binding)
    seen = []
    try:
        os.sched_setaffinity(0, {binding.core})
        binding.held = True
        with event.trigger_event("numba:compile", data={}):
            seen.append(os.sched_getaffinity(0))
    finally:
        os.sched_setaffinity(0, allowed)
    assert seen == [allowed] and not binding.held
