"""Compile each numba kernel once for all pytest-xdist workers (not a test module).

The kernels are compiled into numba's on-disk cache on first use (``cache=True``).  From
a fresh clone every xdist worker would compile every kernel it meets, both workers the
same kernels at the same time (the first tests of both run whole simulations).  Instead,
before its first test, each worker takes the tasks below that no other worker has taken
(in order, once their prerequisites are compiled), so that each kernel is compiled by
one worker and loaded from the cache by the others, then waits until every task is done.
With a warm cache a task only loads its kernels (well under a second each).

Each task runs the real code path on a small input, so it compiles the same
signatures as the tests.  A task that fails is left to the tests to report.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

WAIT = 600.0
"""Seconds a worker waits for the tasks of the others before going on without them."""


NON_HYDROSTATIC = {"pressure": "non_hydrostatic"}
WALLS = {"name": "wall_friction", "mu_w": 0.2}
WALLED = {"x_min": 0.0, "x_max": 1.0, "cells": 50, "layers": 4, "width": 0.1}


def _collapse(**changes):
    """A small granular collapse on the compiled path (mu(I), no-slip base, side walls)."""
    from engine import simulation

    settings = dict(
        slope_deg=20.0,
        domain={"x_min": 0.0, "x_max": 1.0, "cells": 50, "layers": 4},
        material={"density": 1550.0, "grain_diameter": 0.7e-3, "particle_density": 2500.0},
        rheology={"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.279},
        base=[{"condition": "no_slip"}],
        initial=[{"shape": "rectangle", "x_min": 0.0, "x_max": 0.5, "height": 0.1}],
    )
    settings.update(changes)
    return simulation(**settings)


def _transport() -> None:
    from test_transport_kernel import random_state

    from multilayer.engine.transport import kernel as transport_kernel

    h, u, b, fractions = random_state(seed=1)
    kw = dict(dx=0.1, dt=0.004, g_n=9.0, g_t=1.5, left="wall", right="outflow", dry=1e-6, order=2)
    transport_kernel.transport(h, u, b, fractions, threads=1, **kw)


def _newton() -> None:
    sim = _collapse()
    assert sim.vertical.compiled is not None
    ustar = sim.u + 0.01 * (sim.h > 0)
    sim.vertical.compiled(sim.h, ustar, sim.u, 1e-3, threshold=1e-12, max_iterations=200, threads=1)


def _numpy_path() -> None:
    """The exact column solver and the Newton control of the numpy vertical step."""
    from multilayer.engine.vertical import column_solve as column_kernel
    from multilayer.engine.vertical.newton_control import examine_columns
    from multilayer.engine.vertical.problem import ColumnProblem

    rng = np.random.default_rng(0)
    L, N = 3, 4
    p = ColumnProblem(
        m=rng.uniform(0.5, 2, (L, N)), ustar=rng.normal(0, 1, (L, N)), dt=0.1,
        kappa=rng.uniform(0, 1, (L, N)), c=rng.uniform(0, 1, (L, N)), w=np.zeros((L, N)), cw=np.zeros((L, N)),
    )  # fmt: skip
    u = column_kernel.solve(p)
    start, at_start = p.ustar, np.zeros((4, L, N))
    examine_columns(p.m, p.ustar, p.kappa, p.c, p.w, p.cw, start, u, at_start, True)


def _projection() -> None:
    """The non-hydrostatic projection alone (its kernels need no other task's)."""
    sim = _collapse(model=NON_HYDROSTATIC)
    u = np.where(sim.h > 0, np.linspace(0.1, 1.0, sim.u.shape[0])[:, None], 0.0)
    sim.pressure.project(sim.state, sim.h, u, 1e-3)
    sim.pressure.yield_gravity(sim.state, sim.h)


def _steps(**changes) -> None:
    sim = _collapse(**changes)
    for _ in range(3):
        sim.step()


TASKS: list[tuple[str, Callable[[], None], tuple[str, ...]]] = [
    ("newton", _newton, ()),
    ("projection", _projection, ()),
    ("transport", _transport, ()),
    ("numpy_path", _numpy_path, ("newton",)),
    ("step", lambda: _steps(walls=WALLS, domain=WALLED), ("newton", "transport")),
    ("nonhydrostatic", lambda: _steps(model=NON_HYDROSTATIC), ("newton", "transport", "projection")),
]
"""(name, task, the tasks whose kernels it calls): the longest first.  The parallel
variants are not here: only tests under the ``slow`` marker compile them."""


def directory(testrunuid: str) -> Path:
    return Path(tempfile.gettempdir()) / f"multilayer-kernel-warmup-{testrunuid}"


def warm_up(shared: Path) -> None:
    """Run the tasks no other worker has taken (``shared`` holds the claims), then wait
    for all of them."""
    shared.mkdir(exist_ok=True)
    done = lambda name: (shared / f"{name}.done").exists()  # noqa: E731
    deadline = time.monotonic() + WAIT
    while time.monotonic() < deadline:
        waiting = False
        for name, task, needs in TASKS:
            if (shared / f"{name}.claimed").exists():
                waiting = waiting or not done(name)
                continue
            if not all(done(n) for n in needs):
                waiting = True
                continue
            try:
                os.close(os.open(shared / f"{name}.claimed", os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            except FileExistsError:
                waiting = True
                continue
            try:
                task()
            except Exception as error:  # the tests that use the kernel report it
                print(f"kernel warm-up {name}: {error!r}", file=sys.stderr)
            finally:
                (shared / f"{name}.done").touch()
            break  # back to the first task: one may have become ready
        else:
            if not waiting:
                return
            time.sleep(0.1)


def remove(shared: Path) -> None:
    shutil.rmtree(shared, ignore_errors=True)
