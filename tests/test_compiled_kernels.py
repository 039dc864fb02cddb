"""Which numba kernels a run compiles: only those of what it uses (the first run after
installing compiles them, docs/performance.md).  Counts, never timings."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
from numba.core.errors import TypingError

from multilayer.engine.compiled import jit
from multilayer.engine.threads import available_cores

ROOT = Path(__file__).resolve().parents[1]

LISTENER = r"""
from numba.core import event

compiled = []

class Listener(event.Listener):
    def on_start(self, e):
        d = e.data.get("dispatcher")
        if d is not None and d.py_func.__module__.startswith("multilayer"):
            compiled.append(f"{d.py_func.__module__}.{d.py_func.__qualname__}")

    def on_end(self, e):
        pass
"""
"""The engine's functions numba compiles in a child process (``compiled``, once per
compilation), the script's first lines."""

CHILD = (
    LISTENER
    + r"""
import gc, json, sys
from numba.core.registry import CPUDispatcher
import multilayer

overrides = {"domain.cells": 40, "time.end": 0.01, **json.loads(sys.argv[2])}
with event.install_listener("numba:compile", Listener()):
    sim = multilayer.Simulation(multilayer.load(sys.argv[1], overrides=overrides))
    sim.advance(0.01)
entries = sorted(
    f"{d.py_func.__module__}.{d.py_func.__qualname__}"
    for d in gc.get_objects()
    if isinstance(d, CPUDispatcher) and d.overloads and d.py_func.__module__.startswith("multilayer")
)
print(json.dumps({"entries": entries, "compiled": compiled}))
"""
)

ENTRIES = [
    "multilayer.engine.bed_force._sums",
    "multilayer.engine.state.max_wave_speed",
    "multilayer.engine.state.span",
    "multilayer.engine.state.start_moving",
    "multilayer.engine.state.survey",
    "multilayer.engine.state_check._fine",
    "multilayer.engine.state_check._finite",
    "multilayer.engine.state_check._finite_and_still_where_empty",
    "multilayer.engine.transport.kernel._second_stage_start",
    "multilayer.engine.transport.kernel._stages",
    "multilayer.engine.transport.kernel._window",
    "multilayer.engine.vertical.extrapolation._extrapolate",
    "multilayer.engine.vertical.newton_kernel._chunk",
    "multilayer.engine.vertical.results._take",
    "multilayer.engine.vertical.results.clear_dry",
    "multilayer.engine.vertical.results.tally",
    "multilayer.engine.vertical.step._same_columns",
]
"""The kernels a hydrostatic run on one thread calls from Python (``Simulation.advance``,
whose bound on the steps reads the Courant step), the ones it loads from numba's cache
(their callees are compiled into them): no parallel kernel, nothing of the non-hydrostatic
projection."""

COMPILATIONS = 81
"""At most this many compilations of the engine's functions (each kernel and each of its
callees, once per signature) for that run with numba's cache empty (52 when this bound
was set; two more since the column solve's active set and the Newton control's error
bound are compiled once as callees rather than inlined by numba at each call, one more
for the extrapolated Newton seed, one more for the wave speed that ``advance`` reads to
bound its steps, one more for the Newton kernel's iteration of a chunk, compiled without
reference counting apart from the chunk that allocates its work arrays; three more for
the fully sheared columns' error bound formed as vectors, the rise bound tested apart
from the slope, and the interval of a layer's stress that error_bound shares with it;
one more for their keeping of the velocities of the columns they finished (the test of
the signs of the yielded jumps, a function of its own before, is made in the stresses'
pass); one
more for the start of Heun's second stage in one compiled pass, one more for the bed
force's momenta summed apart from the impulses of the vertical steps, one more for the
check, before every step, that no velocity was written into a column without
material; two more for the Newton kernel's clearing of the dry columns of its result and
its counts of the iterations, each one call where numpy took several: on a small mesh
they cost more than the kernel; one more for the bed force's sums of a step in one call,
whose momenta and impulses are now its callees, one more for the state guard's quick
check in one call; four more for the vertical step's parts fixed in a block of columns
and its error-bound and rise-bound terms, each one pass over the block; six more for the
block's tile laid out as the mesh: its coefficients made in one pass, the rows of its
layers' factors, the error bound's sums of all its columns in one pass down it, and the
passes of the stresses, of the bounds' terms, the error and rise bounds of
``newton_control`` and the pressure parts of a law of the thickness compiled again for the
strided view of one column of the tile, less three for the tile's cell index, inlined; two
more for a redone step, which solves again only the columns whose vertical problem changed:
their comparison with the attempt before and the copy of the others' answers)."""


def run(cache: str, **overrides: object) -> dict:
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            CHILD,
            str(ROOT / "scenarios" / "erodible_bed_collapse.yaml"),
            json.dumps(overrides),
        ],
        env={**os.environ, "NUMBA_CACHE_DIR": cache, "MULTILAYER_THREADS": "1"},
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(done.stdout)


@pytest.mark.slow
def test_a_hydrostatic_run_compiles_only_its_own_kernels():
    """The README scenario (40 cells) on one thread, numba's cache empty: it compiles its
    seventeen entry kernels and their callees, at most ``COMPILATIONS`` functions, none
    parallel and none of the non-hydrostatic pressure; run again, it loads those seventeen
    only and compiles nothing."""
    with tempfile.TemporaryDirectory() as cache:
        first = run(cache)
        second = run(cache)
    assert second["entries"] == sorted(ENTRIES) and set(ENTRIES) <= set(first["compiled"])
    assert len(first["compiled"]) <= COMPILATIONS and second["compiled"] == []
    assert not any("parallel" in name or "non_hydrostatic" in name for name in first["compiled"])


AHEAD = (
    LISTENER
    + r"""
import json, sys
from multilayer.app.cli import main

with event.install_listener("numba:compile", Listener()):
    code = main(sys.argv[1:])
print(json.dumps({"code": code, "compiled": compiled}))
"""
)


def test_the_newton_callees_compiled_ahead_take_the_arguments_they_are_given():
    """The run's own share of a first compilation (``compilation._compile_newton_callees``)
    gives each callee of the Newton kernel as many argument types as it takes: a missing
    one was a TypeError that the warm-up swallows (the kernel then compiled them itself)."""
    import inspect

    from multilayer.app.compilation import newton_callees

    for kernel, signature in newton_callees():
        assert len(signature) == len(inspect.signature(kernel.py_func).parameters), kernel.py_func.__name__


@jit(borrowing=True)
def _row_sums(a, passes):
    """The sum of ``a`` (2-D) taken ``passes`` times through a view of each row."""
    total = 0.0
    for _ in range(passes):
        for i in range(a.shape[0]):
            row = a[i]
            for value in row:
                total += value
    return total


@jit(borrowing=True)
def _allocating(n):
    return np.zeros(n).sum()


def test_a_borrowing_kernel_reads_views_of_what_it_borrows_and_cannot_allocate():
    """``compiled.jit(borrowing=True)``, the kernels of the Newton iteration: compiled
    without numba's reference counting, a kernel reads views of the arrays its caller holds
    (a sum of integers, exact) and an allocation in it is an error of compilation, not a
    leak."""
    a = np.arange(12.0).reshape(3, 4)
    assert _row_sums(a, 1000) == 66.0 * 1000
    with pytest.raises(TypingError):
        _allocating(3)


@pytest.mark.slow
def test_the_first_run_compiles_the_newton_kernel_in_a_child_process():
    """``multilayer run`` of the README scenario with numba's cache empty, on two cores:
    the fused Newton kernel is compiled by the child process of
    ``compilation.compile_ahead`` (into the cache, which the run loads it from), the
    transport and two callees of the Newton kernel by the run's own process, by the very
    signature the kernel calls them with (the cache then holds one of each)."""
    if available_cores() < 2:
        pytest.skip("compile_ahead needs two cores")
    scenario = str(ROOT / "scenarios" / "erodible_bed_collapse.yaml")
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
        arguments = ["run", scenario, "-q", "-o", out, "--set", "domain.cells=40", "--set", "time.end=0.01"]
        done = subprocess.run(
            [sys.executable, "-c", AHEAD, *arguments],
            env={**os.environ, "NUMBA_CACHE_DIR": cache, "MULTILAYER_THREADS": "1"},
            capture_output=True,
            text=True,
            check=True,
        )
        first = json.loads(done.stdout.splitlines()[-1])
        assert first["code"] == 0
        names = [name.rsplit(".", 1)[1] for name in first["compiled"]]
        assert "_stages" in names and "_chunk" not in names and "sheared_block" not in names
        assert names.count("_other_structures") == names.count("_dynamic_programme") == 1
        check = (
            "from multilayer.app.compilation import _newton_cached\n"
            "from multilayer.engine.vertical import column_solve, newton_kernel\n"
            "print(_newton_cached(), *(len(d._cache._cache_file._load_index()) for d in "
            "(newton_kernel._other_structures, column_solve._dynamic_programme)))"
        )
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        cached = subprocess.run([sys.executable, "-c", check], env=env, capture_output=True, text=True)
        assert cached.stdout.split() == ["True", "1", "1"], cached.stderr


SHIPPED = sorted(str(path) for path in (ROOT / "scenarios").glob("*.yaml"))

AFTER_COMPILE = (
    LISTENER
    + r"""
import json, sys
import multilayer

found = {}
for path in sys.argv[1:]:
    compiled.clear()
    with event.install_listener("numba:compile", Listener()):
        overrides = {"domain.cells": 40, "numerics.threads": 1}
        sim = multilayer.Simulation(multilayer.load(path, overrides=overrides))
        for _ in range(2):
            sim.step()
    found[path] = list(compiled)
print(json.dumps(found))
"""
)


@pytest.mark.slow
def test_after_multilayer_compile_no_shipped_scenario_compiles_a_kernel(tmp_path):
    """``multilayer compile`` with numba's cache empty, then two steps of every shipped
    scenario (one thread): none compiles anything, so the first run after installing
    starts computing at once."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}

    def child(*arguments: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, *arguments], env=env, capture_output=True, text=True)

    done = child("-m", "multilayer", "compile")
    assert done.returncode == 0 and "compiled the kernels in" in done.stdout, done.stderr
    again = child("-m", "multilayer", "compile")
    assert again.returncode == 0 and "the kernels are compiled and cached" in again.stdout
    runs = child("-c", AFTER_COMPILE, *SHIPPED)
    assert json.loads(runs.stdout) == {path: [] for path in SHIPPED}, runs.stderr


@pytest.mark.slow
def test_two_compiles_and_a_run_at_once_on_an_empty_cache(tmp_path, write_scenario, tiny_scenario):
    """Two ``multilayer compile`` and a run started together on an empty cache
    (``NUMBA_CACHE_DIR`` a fresh directory): all three end well, one compile waits for the
    other (then finds the kernels cached, or compiles again what the run rewrote since
    the mark), the run compiles what it needs beside them (numba writes each entry whole,
    by renaming), and afterwards no shipped scenario compiles a kernel."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "MULTILAYER_THREADS": "1"}
    scenario = write_scenario(tiny_scenario)
    commands = [["compile"], ["compile"], ["run", str(scenario), "-o", str(tmp_path / "out"), "-q"]]
    children = [
        subprocess.Popen([sys.executable, "-m", "multilayer", *command], env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
        for command in commands
    ]  # fmt: skip
    outputs = [child.communicate(timeout=1200) for child in children]
    assert [child.returncode for child in children] == [0, 0, 0], outputs
    assert outputs[0][0].startswith("compiled the kernels in") or outputs[1][0].startswith(
        "compiled the kernels in"
    )
    assert sum("waiting for another multilayer compile" in err for _, err in outputs[:2]) == 1
    runs = subprocess.run(
        [sys.executable, "-c", AFTER_COMPILE, *SHIPPED], env=env, capture_output=True, text=True
    )
    assert json.loads(runs.stdout) == {path: [] for path in SHIPPED}, runs.stderr


def _compiled(names: list[str]) -> object:
    """A listener of numba's ``numba:compile`` events appending each compiled function's
    qualified name to ``names``."""
    from numba.core import event

    class Compiled(event.Listener):
        def on_start(self, e):
            names.append(e.data["dispatcher"].py_func.__qualname__)

        def on_end(self, e):
            pass

    return Compiled()


def test_a_run_after_compile_kernels_compiles_nothing(tiny_scenario):
    """Once :func:`compile_kernels` has cached its tasks' kernels (the test run's warm-up
    did, or this call does), a small run under another law, hydrostatic or not, with side
    walls, with the normal stress or not, on one thread or two, compiles no kernel of the
    engine: the tasks cover the signatures of a run (the first run on two threads compiled
    the parallel Newton kernel and transport, some 25-30 s)."""
    from numba.core import event

    import multilayer
    from multilayer.app.precompile import compile_kernels, work
    from multilayer.engine import kernel_cache

    assert not compile_kernels().failed and kernel_cache.is_compiled(work())
    names: list[str] = []

    tiny_scenario["walls"] = {"name": "wall_friction", "mu_w": 0.2}
    tiny_scenario["domain"]["width"] = 0.1
    for overrides in ({"model.pressure": "hydrostatic"}, {"model.pressure": "non_hydrostatic"},
                      {"model.normal_stress": True}, {"numerics.threads": 2}):  # fmt: skip
        with event.install_listener("numba:compile", _compiled(names)):
            sim = multilayer.Simulation(multilayer.load(tiny_scenario, overrides))
            for _ in range(3):
                sim.step()
        assert sim.t > 0 and names == []


def test_a_run_on_the_numpy_path_after_compile_kernels_compiles_nothing(tiny_scenario, monkeypatch):
    """Once :func:`compile_kernels` has cached its tasks' kernels, a small run on the numpy
    path of the vertical step compiles no kernel of the engine: under a law without a
    compiled viscosity form (a third-party rheology; here a shear-thickening power law,
    whose Newton steps the line search damps) with its yield form compiled, and under side
    walls without compiled forms (the bulk's form read for its concavity).  Their first
    runs compiled the coefficients from the yield forms (about 2 s), the slopes of the line
    search and the concavity of a form given its parameters as an array."""
    from numba.core import event

    import multilayer
    from multilayer.app.precompile import compile_kernels
    from multilayer.engine.vertical import newton
    from multilayer.plugins.builtins import PowerLawMuI, WallFriction

    assert not compile_kernels().failed
    names: list[str] = []
    damped: list[int] = []
    slopes_along = newton.slopes_along
    monkeypatch.setattr(newton, "slopes_along", lambda *a: damped.append(1) or slopes_along(*a))

    tiny_scenario["walls"] = {"name": "wall_friction", "mu_w": 0.2}
    tiny_scenario["domain"]["width"] = 0.1
    thickening = {"name": "power_law_mu_i", "mu_s": 0.38, "m": 0.3, "alpha": 1.5}
    for law, overrides in ((PowerLawMuI, {"rheology": thickening}), (WallFriction, {})):
        with monkeypatch.context() as patched:
            for kernel in ("viscosity_kernel", "yield_stress_kernel")[: 2 if law is WallFriction else 1]:
                patched.setattr(law, kernel, lambda self, material: None)
            with event.install_listener("numba:compile", _compiled(names)):
                sim = multilayer.Simulation(multilayer.load({**tiny_scenario, **overrides}))
                for _ in range(3):
                    sim.step()
            assert sim.t > 0 and sim.vertical.compiled.laws() is None and names == []
    assert damped


@pytest.mark.slow
def test_the_numpy_paths_parallel_column_solve_is_compiled_ahead():
    """A third-party law without compiled forms solves its columns on the numpy path; on
    more than one thread that is the parallel column solve, which no run under a built-in
    law uses (so none caches it): :func:`compile_kernels` compiles it, and a threaded run
    under a plugin then compiles nothing (it compiled it on its first use, about 2 s)."""
    import numpy as np
    from numba.core import event

    from multilayer.app.precompile import compile_kernels
    from multilayer.engine.vertical import column_solve
    from multilayer.engine.vertical.problem import ColumnProblem

    assert not compile_kernels().failed
    names: list[str] = []

    shape = (3, 8)
    p = ColumnProblem(m=np.ones(shape), ustar=np.ones(shape), dt=0.1, kappa=np.full(shape, 0.5),
                      c=np.ones(shape), w=np.zeros(shape), cw=np.zeros(shape))  # fmt: skip
    with event.install_listener("numba:compile", _compiled(names)):
        column_solve.solve(p, threads=2)
    assert column_solve._solve_parallel.signatures and names == []


def test_a_failing_task_is_named_by_the_worker(monkeypatch, capsys):
    """A task that raises is answered ``failed NAME ERROR`` (``multilayer compile`` exits 1
    naming it); the next task still runs."""
    import io

    from multilayer.app import precompile

    def broken() -> None:
        raise RuntimeError("no\nluck")

    tasks = (precompile.Task("broken", broken), precompile.Task("fine", lambda: None))
    monkeypatch.setattr(precompile, "TASKS", tasks)
    monkeypatch.setattr(sys, "stdin", io.StringIO("broken\nfine\n"))
    precompile._worker()
    assert capsys.readouterr().out.splitlines() == ["failed broken RuntimeError: no luck", "done fine"]


def test_a_task_whose_kernels_were_not_cached_fails(monkeypatch, capsys):
    """A child that found a kernel module not to be the code it ran (the bytecode of an
    earlier version, a file edited during the compilation) compiles without caching, with a
    warning on its discarded stderr: it answered ``done`` and the cache was marked compiled,
    so the next run compiled again.  Now the task fails, naming why (no mark is written)."""
    import io

    from multilayer.app import precompile
    from multilayer.engine import kernel_cache

    kernel_cache.ensure_fresh()
    monkeypatch.setattr(precompile, "TASKS", (precompile.Task("fine", lambda: None),))
    monkeypatch.setattr(sys, "stdin", io.StringIO("fine\nfine\n"))
    monkeypatch.setattr(kernel_cache, "_digest", None)  # what _changed_since_import leaves
    precompile._worker()
    assert capsys.readouterr().out.splitlines() == [f"failed fine {precompile.NOT_CACHED}"] * 2


def test_compile_refuses_a_process_count_below_one(cli):
    result = cli("compile", "--processes", "0")
    assert result.code == 2 and "--processes" in result.err and "integer >= 1" in result.err


def test_compile_says_when_numba_cannot_cache(cli, monkeypatch):
    from multilayer.engine import kernel_cache

    monkeypatch.setattr(kernel_cache, "cache_directories", lambda: [])
    result = cli("compile")
    assert result.code == 1 and "NUMBA_CACHE_DIR" in result.err and result.out == ""


def test_compile_closes_the_pipes_of_its_child_processes(monkeypatch):
    """A pipe of a compiling child left open was a ResourceWarning when it was collected:
    under ``PYTHONWARNINGS=error`` a traceback of ``multilayer compile``."""
    import gc
    import warnings

    from multilayer.app import precompile

    monkeypatch.setattr(precompile, "TASKS", (precompile.Task("unknown", lambda: None),))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        report = precompile._compile(1)  # the child answers at once: no task of that name
        gc.collect()
    assert report.failed == {"unknown": "KeyError: 'unknown'"}
    assert [str(w.message) for w in caught if issubclass(w.category, ResourceWarning)] == []
