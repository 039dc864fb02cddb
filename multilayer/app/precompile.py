"""Compiling the engine's numba kernels ahead of the first run: ``multilayer compile``.

numba compiles a kernel on its first use and caches it on disk (engine/kernel_cache.py).
Without this step the first run after installing waits for the compilation, about a
minute of one core, most of it numba's own typing and lowering of the fused Newton
kernel, the transport and the non-hydrostatic projection (docs/performance.md, "The
first run").  :func:`compile_kernels` does that work once, as a step of the
installation, in parallel child processes: each :data:`TASKS` entry runs the engine's
real code path on a small built-in scenario (16 columns, one thread), so it compiles the
signatures every run uses.  A task starts once the tasks whose kernels it calls are
compiled (two processes compiling one kernel at once would both do the work).  When all
of them succeed the cache is marked compiled for the current kernel sources and numba
version and this module's task list (:func:`multilayer.engine.kernel_cache.mark_compiled`,
:func:`work`), and a later call returns
at once.  The parallel (threaded) variants are compiled too: a step on two threads or more
(``numerics.threads``; ``auto`` above 200 000 cells holding material) uses them, and the
Newton kernel's alone took 25-30 s of the first such run.  So is the numpy path of the
vertical step, which no run under a built-in law caches: the column solve, serial and
parallel, the Newton control's bounds and the slopes of its line search, and the
coefficients compiled from the yield forms, for laws without a compiled viscosity form
(third-party rheologies, a built-in law's subclass that redefines its viscosity); and the
concavity of a compiled form read there (the FiPy solver of ``numerics.vertical_solver``,
side walls whose law has no compiled form).  Their first use took 2-3 s of CPU.
"""

from __future__ import annotations

import hashlib
import select
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from multilayer.app.compilation import interpreter
from multilayer.engine import kernel_cache
from multilayer.engine.threads import available_cores

COLLAPSE: dict[str, Any] = {
    "name": "compile",
    "slope_deg": 20.0,
    "domain": {"x_min": 0.0, "x_max": 1.0, "cells": 16, "layers": 4, "width": 0.1},
    "material": {"density": 1550.0, "grain_diameter": 0.7e-3, "particle_density": 2500.0},
    "rheology": {"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.279},
    "walls": {"name": "wall_friction", "mu_w": 0.2},
    "base": [{"condition": "no_slip"}],
    "initial": [{"shape": "rectangle", "x_min": 0.0, "x_max": 0.5, "height": 0.1}],
    "numerics": {"threads": 1},
    "time": {"end": 1.0, "output_interval": 1.0},
}
"""The small granular collapse the tasks step: Jop's mu(I), a no-slip base and side walls
(the kernels' types do not depend on the law, the mesh size or the parameters)."""


def _simulation(pressure: str = "hydrostatic") -> Any:
    """A :class:`multilayer.Simulation` of :data:`COLLAPSE` with the given pressure model."""
    from multilayer.app.api import load
    from multilayer.app.simulation import Simulation

    return Simulation(load(COLLAPSE, {"model.pressure": pressure}))


def _newton() -> None:
    """The fused Newton kernel of the vertical step, with everything it calls."""
    sim = _simulation()
    sim._vertical_step(sim.h, sim.u, sim.time_step(), 1)


def _projection() -> None:
    """The non-hydrostatic projection (its kernels call none of the other tasks')."""
    import numpy as np

    sim = _simulation("non_hydrostatic")
    u = np.where(sim.h > 0, np.linspace(0.1, 1.0, sim.u.shape[0])[:, None], 0.0)
    for _ in range(2):  # the second from the first's constraint (its start is on the same thickness)
        sim.pressure.project(sim.state, sim.h, u, 1e-3)
    sim.pressure.yield_gravity(sim.state, sim.h)


def _transport() -> None:
    """The transport of the layers."""
    sim = _simulation()
    sim._transport(sim.time_step(), 1)


def _parallel() -> None:
    """The parallel variants of the Newton kernel and of the transport (a step on two
    threads; numba caps the threads at ``NUMBA_NUM_THREADS``, the variant is the same)."""
    sim = _simulation()
    dt = sim.time_step()
    sim._vertical_step(sim.h, sim.u, dt, 2)
    sim._transport(dt, 2)


def _normal_stress() -> None:
    """The normal-stress step after each vertical step (``model.normal_stress``)."""
    from multilayer.app.api import load
    from multilayer.app.simulation import Simulation

    sim = Simulation(load(COLLAPSE, {"model.normal_stress": True}))
    dt = sim.time_step()
    h, ustar = sim._transport(dt, 1)
    sim._normal_stress(h, ustar, dt, sim.u)  # on the transport's velocities: no vertical step compiled here


def _numpy_path() -> None:
    """The numpy path of the vertical step (laws without compiled viscosity forms, the FiPy
    solver): the exact column solve, serial and parallel, the Newton control (its bounds and
    the slopes of the line search of a damped step), the coefficients compiled from the laws'
    yield forms, and the concavity of their compiled viscosity forms."""
    import numpy as np

    from multilayer.engine.vertical import column_solve
    from multilayer.engine.vertical.forms import concave_laws
    from multilayer.engine.vertical.newton_control import examine_columns, slopes_along
    from multilayer.engine.vertical.problem import ColumnProblem

    rng = np.random.default_rng(0)
    shape = (3, 4)
    p = ColumnProblem(
        m=rng.uniform(0.5, 2, shape), ustar=rng.normal(0, 1, shape), dt=0.1, kappa=rng.uniform(0, 1, shape),
        c=rng.uniform(0, 1, shape), w=np.zeros(shape), cw=np.zeros(shape),
    )  # fmt: skip
    u = column_solve.solve(p)
    column_solve.solve(p, threads=2)  # the parallel variant: no built-in law's run caches it
    examine_columns(p.m, p.ustar, p.kappa, p.c, p.w, p.cw, p.ustar, u, np.zeros((4, *shape)), True)
    slopes_along(p.m, p.ustar, p.kappa, p.c, p.w, p.cw, p.ustar, u, 0.5 * (p.ustar + u), 1.0)
    sim = _simulation()
    stresses = sim.vertical.stresses
    concave_laws((stresses.bulk, stresses.walls), stresses.material)
    assert sim.vertical.compiled is not None  # (the compiled solver: the default)
    sim.vertical.compiled.coefficients(sim.h, np.flatnonzero(sim.h > 0))


MIXTURE: dict[str, Any] = {
    "name": "compile-mixture",
    "domain": {"x_min": 0.0, "x_max": 0.3, "cells": 16, "layers": 1},
    "material": {"density": 1830.0, "grain_diameter": 225.0e-6, "particle_density": 2500.0},
    "rheology": {"name": "dilatant_coulomb", "delta_deg": 22.5, "K1": 90.5},
    "fluid": {"density": 1010.0, "viscosity": 0.0121},
    "mixture": {"phi_critical": 0.582, "dilatancy": 4.09, "critical_shift": 25.0},
    "initial": [{"shape": "rectangle", "x_min": 0.0, "x_max": 0.06, "height": 0.048, "phi": 0.55}],
    "boundaries": {"left": "wall", "right": "outflow"},
    "numerics": {"threads": 1},
    "time": {"end": 1.0, "output_interval": 1.0},
}
"""A small loose column collapsing in a fluid (scenarios/submarine_collapse_loose.yaml on 16
cells): the mixture's steps, of one layer under the dilatant law."""


def _mixture() -> None:
    """Three steps of a grain–fluid mixture: the compiled map of its local step
    (engine/mixture/local_kernel.py) and the kernels its steps call."""
    from multilayer.app.api import load
    from multilayer.app.simulation import Simulation

    sim = Simulation(load(MIXTURE))
    for _ in range(3):
        sim.step()


def _steps(pressure: str) -> Callable[[], None]:
    def steps() -> None:
        """Three whole steps (the state checks, the bed force, the seed extrapolation)."""
        sim = _simulation(pressure)
        for _ in range(3):
            sim.step()

    return steps


@dataclass(frozen=True)
class Task:
    """One child process's work: ``run`` compiles (or loads) its kernels once the tasks
    named in ``needs`` are done."""

    name: str
    run: Callable[[], None]
    needs: tuple[str, ...] = ()


TASKS: tuple[Task, ...] = (
    Task("newton", _newton),
    Task("projection", _projection),
    Task("transport", _transport),
    Task("parallel", _parallel, ("newton", "transport")),
    Task("numpy_path", _numpy_path, ("newton",)),
    Task("normal_stress", _normal_stress, ("transport",)),
    Task("hydrostatic_steps", _steps("hydrostatic"), ("newton", "transport")),
    Task("non_hydrostatic_steps", _steps("non_hydrostatic"), ("newton", "transport", "projection")),
    Task("mixture", _mixture, ("numpy_path", "transport")),
)
"""The longest first: on two cores the Newton kernel compiles beside the projection and
then the transport, and the parallel variants once both are done."""


NOT_CACHED = (
    "its kernels were compiled but not cached: a kernel module changed during the compilation, "
    "or Python ran the bytecode of an earlier version of it; run multilayer compile again"
)
"""What a task whose kernels were not cached answers (:func:`_worker`)."""


def work() -> str:
    """What the mark of the compilation says was compiled: the SHA-256 of this module,
    whose :data:`TASKS` say which kernels (a task list changed since compiles again), and
    Python's optimisation level (``-O``, ``-OO``: numba keys a kernel's cache entry on
    its bytecode and its callees', which ``-O`` strips of asserts and ``-OO`` of
    docstrings, so the kernels of one level are not those of another)."""
    try:
        module = hashlib.sha256(Path(__file__).read_bytes()).hexdigest()
    except OSError:  # the module's file is gone: no mark is found current
        return "none"
    return f"{module} optimize {sys.flags.optimize}"


@dataclass
class Report:
    """What :func:`compile_kernels` did: ``seconds`` of wall time, the ``processes`` used,
    and the tasks that ``failed`` with the last line each wrote to stderr (empty: every
    kernel is compiled and cached); ``cached`` is True when nothing had to be done (the
    ``checked`` cached files found as the mark of the compilation recorded them)."""

    seconds: float = 0.0
    processes: int = 0
    cached: bool = False
    checked: int = 0
    failed: dict[str, str] = field(default_factory=dict)


def _worker() -> None:
    """A child process of :func:`compile_kernels` (or of a run's
    ``compilation.compile_ahead``): runs the tasks named on its stdin, one
    per line, and answers each with ``done NAME`` or ``failed NAME MESSAGE`` on stdout.  A
    task whose kernels were compiled but not cached (a kernel module that is not the code
    the process ran: :func:`multilayer.engine.kernel_cache.caching`, whose warning goes to
    the discarded stderr) failed: the cache is then not marked compiled."""
    tasks = {task.name: task for task in TASKS}
    for line in sys.stdin:
        name = line.strip()
        try:
            tasks[name].run()
        except Exception as error:  # reported by the parent
            answer = f"failed {name} {type(error).__name__}: {error}".replace("\n", " ")
        else:
            answer = f"done {name}" if kernel_cache.caching() else f"failed {name} {NOT_CACHED}"
        print(answer, flush=True)


def compile_kernels(processes: int | None = None, on_wait: Callable[[], None] = lambda: None) -> Report:
    """Compile every kernel of :data:`TASKS` into numba's cache in ``processes`` child
    processes (None: the cores this process may use), each task once the tasks it
    ``needs`` are done; nothing when the cache is already marked compiled for the current
    sources and every file the mark records is unchanged (``checked`` of them).  One call
    at a time per cache (``on_wait`` is called when another holds it, then this one
    waits).  Interrupted, the children are stopped with it."""
    with kernel_cache.compiling(on_wait):
        kernel_cache.ensure_fresh()
        checked = kernel_cache.compiled_files(work())
        if checked is not None:
            return Report(cached=True, checked=checked)
        return _compile(processes)


def _compile(processes: int | None) -> Report:
    """:func:`compile_kernels` once the cache is found not compiled."""
    sources = kernel_cache.compiled_text(work())  # an edit during the compilation leaves no mark
    processes = max(1, min(len(TASKS), available_cores() if processes is None else processes))
    start = time.perf_counter()
    report = Report(processes=processes)
    children = [
        subprocess.Popen(
            [*interpreter(), "-m", __name__],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
            bufsize=1,
        )  # fmt: skip
        for _ in range(processes)
    ]
    pending, done = list(TASKS), set[str]()
    busy: dict[int, str] = {}  # a child's stdout descriptor: its task
    try:
        while pending or busy:
            for child in children:
                ready = [t for t in pending if all(n in done for n in t.needs)]
                if child.stdout is None or child.stdout.fileno() in busy or not ready:
                    continue
                assert child.stdin is not None
                child.stdin.write(ready[0].name + "\n")
                child.stdin.flush()
                busy[child.stdout.fileno()] = ready[0].name
                pending.remove(ready[0])
            if not busy:  # a task's needs were never done: cannot happen with TASKS
                break
            readable, _, _ = select.select(list(busy), [], [])
            for fd in readable:
                child = next(c for c in children if c.stdout is not None and c.stdout.fileno() == fd)
                assert child.stdout is not None
                answer = child.stdout.readline()
                name = busy.pop(fd)
                if not answer.startswith("done "):
                    report.failed[name] = answer.split(" ", 2)[2].strip() if answer else "the process ended"
                done.add(name)
    finally:
        for child in children:
            if child.stdin is not None:
                child.stdin.close()
            if pending or busy:  # interrupted: stop at once
                child.kill()
            child.wait()
            if child.stdout is not None:  # left open, a ResourceWarning (a traceback under -W error)
                child.stdout.close()
    report.seconds = time.perf_counter() - start
    if not report.failed:
        kernel_cache.mark_compiled(sources)
    return report


if __name__ == "__main__":
    _worker()
