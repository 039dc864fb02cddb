"""Memory and output-size estimates of a scenario, checked against a budget before a run.

The engine holds the state and its work arrays: some per column, some per cell of the
``cells x layers`` mesh, more of them with each pressure model, the normal stress and a
grain-fluid mixture.  Measured (peak resident memory on top of about 150 MB for the
interpreter and libraries) over three steps of a layer flowing on every column, on two
threads, from 10^5 to 10^6 columns of 1 to 400 layers: 130-160 bytes per cell and about 160
per column with the hydrostatic pressure, 250-280 per cell with ``bim2016``, 490-880 per cell
and about 200 per column with ``non_hydrostatic`` (more with more ``pressure_layers``), 590-700
per cell more with the normal stress, 1.4-1.45 kB per cell in all with a mixture (one and ten
layers), and ``run`` about 45 bytes per cell more (its records).  The estimate takes the
largest of each, raised by a quarter or more (:data:`BYTES_PER_CELL`,
:data:`BYTES_PER_COLUMN`, :data:`NORMAL_STRESS_BYTES`, :data:`MIXTURE_BYTES`, 200 MB): a
bound of the peak, not a multiple of it, so that a run that fits is not refused
(``benchmarks/memory_estimate.py`` measures it).  ``result.nc`` receives one record per
output time (``ceil(end / output_interval)`` of them plus the initial state), each of
``(layers + 2) cells + 3`` doubles (``u``, ``h``, the static interface; time, front, mass).

The exact vertical step keeps, per thread, the piecewise-linear messages of every layer
of a column (``engine.vertical.problem.workspace_bytes``): quadratic in the layers, 51 GB at 20 000
layers, counted once per thread that can run (at most one per column).

The steps are estimated with the Courant step of the fastest initial wave: the front of
a dam break of the deepest initial material, ``max|u| + 2 sqrt(g cos(theta) h_max)``
(Ritter 1892; ``h_max`` the initial entries stacked at their highest, ``|u|`` their
speed at the surface), or the inflow's ``|u| + sqrt(g cos(theta) h)``, with ``dt = min(cfl,
1/2) dx / s``: an order of magnitude (friction slows a collapse, a slope accelerates a
flow), which tells a run of 10^4 steps from one of 10^150.  A run is refused
beyond :data:`MAX_STEPS` steps (``--max-steps`` sets another bound), and stops there
(exit 1, resumable with a larger ``--max-steps``) if it gets that far: the time loop
never runs without a bound that ``validate`` prints.

By default a run must fit the memory available now and the free space of the file
system it writes to (and the file size limit of the process, ``ulimit -f``);
``--max-memory``, ``--max-output`` and ``--max-steps`` set other bounds and ``--force``
skips the check (and the bound on the steps).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from multilayer.engine.config import MAX_STEPS
from multilayer.errors import InputError, shown
from multilayer.io import disk
from multilayer.io.netcdf_layout import HEADER_SPACE

BYTES_PER_CELL = {"hydrostatic": 260, "bim2016": 410, "non_hydrostatic": 1160}
"""Bytes per cell (a column's layer) of each pressure model (module docstring)."""
BYTES_PER_COLUMN = {"hydrostatic": 400, "bim2016": 400, "non_hydrostatic": 700}
"""Bytes per column of each pressure model (module docstring)."""
NORMAL_STRESS_BYTES = (400, 900)
"""Bytes per column and per cell added by ``model.normal_stress``."""
MIXTURE_BYTES = (400, 1600)
"""Bytes per column and per cell added by a grain-fluid mixture."""
BASE_BYTES = 200 * 2**20
_UNITS = {"": 1, "k": 2**10, "m": 2**20, "g": 2**30, "t": 2**40}


@dataclass(frozen=True)
class Estimate:
    """What a scenario needs: peak memory and size of ``result.nc`` (bytes), output times."""

    memory: float
    output: float
    records: float


@dataclass(frozen=True)
class Steps:
    """About how many time steps a run takes, and the wave speed (m/s), cell (m) and step
    (s) that set them (module docstring)."""

    count: float
    speed: float
    dx: float
    dt: float


@dataclass(frozen=True)
class Budget:
    """Limits of a run: bytes (``None``: the available memory, the free disk space) and
    time steps (``None``: :data:`MAX_STEPS`); ``force`` lifts them all."""

    memory: float | None = None
    output: float | None = None
    force: bool = False
    steps: int | None = None

    @property
    def step_limit(self) -> float:
        """The bound on the steps of the run (inf when forced)."""
        return math.inf if self.force else float(self.steps or MAX_STEPS)


def estimate(scenario: Any, text: str | None = None) -> Estimate:
    """Peak memory and output size of ``scenario`` (module docstring); ``text``: its
    :meth:`resolved_yaml`, where written already (else its size is estimated without it)."""
    from multilayer.engine.vertical.problem import workspace_bytes

    cells, layers = float(scenario.domain.cells), float(scenario.domain.layers)
    records = output_records(scenario)
    per_record = 8.0 * ((layers + 2.0) * cells + 3.0)
    fixed = (
        8.0 * (5.0 * cells + 4.0 * layers)
        + (scenario.text_size() if text is None else len(text))
        + 16384
        + HEADER_SPACE
    )
    threads = scenario.numerics.threads
    workspaces = min(cells, threads if isinstance(threads, int) else float(os.cpu_count() or 1))
    memory = BASE_BYTES + state_bytes(scenario) + workspaces * workspace_bytes(int(layers))
    return Estimate(memory, fixed + records * per_record, records)


def state_bytes(scenario: Any) -> float:
    """The bytes of the state and work arrays of ``scenario``'s mesh (module docstring)."""
    cells, layers = float(scenario.domain.cells), float(scenario.domain.layers)
    pressure = scenario.model.pressure
    column, cell = BYTES_PER_COLUMN[pressure], BYTES_PER_CELL[pressure]
    parts = ((NORMAL_STRESS_BYTES, scenario.model.normal_stress), (MIXTURE_BYTES, scenario.fluid))
    for added, present in parts:
        if present:
            column, cell = column + added[0], cell + added[1]
    return cells * (column + cell * layers)


def output_records(scenario: Any) -> float:
    """The output times of ``scenario``, its start included."""
    end, interval = scenario.time.end, scenario.time.output_interval
    return 1.0 + (1.0 if interval >= end else math.ceil(end / interval - 1e-9))


def steps(scenario: Any) -> Steps:
    """About how many steps ``scenario`` takes (module docstring), from the deepest and the
    fastest of its initial entries (their stack and their surface speeds: nothing the size
    of the mesh is built)."""
    from multilayer.engine import initial_state
    from multilayer.engine.transport.reference import POSITIVITY_LIMIT

    depth, fastest = 0.0, 0.0
    for entry in scenario.initial:
        points = initial_state.entry_points(entry)
        top = float(entry.thickness) if points is None else float(points[1].max())
        surface = initial_state.velocity_profile(entry.velocity, np.array([top]), np.array([top]))
        depth, fastest = depth + top, max(fastest, float(abs(surface[0])))
    g_n = scenario.gravity * math.cos(math.radians(scenario.slope_deg))
    speed = fastest + 2.0 * math.sqrt(g_n * depth)
    inflow = scenario.boundaries.inflow
    if inflow is not None:
        level = np.array([inflow.thickness])
        entering = float(abs(initial_state.velocity_profile(inflow.velocity, level, level)[0]))
        speed = max(speed, entering + math.sqrt(g_n * inflow.thickness))
    dom = scenario.domain
    dx = (dom.x_max - dom.x_min) / dom.cells
    dt = min(scenario.time.cfl, POSITIVITY_LIMIT) * dx / speed if speed > 0 else math.inf
    count = scenario.time.end / dt if dt > 0 else math.inf  # waves past 1e308 m/s: a step of 0 s
    return Steps(count + output_records(scenario), speed, dx, dt)


def size_text(n: float) -> str:
    """``1.5 GB``: a byte count for messages."""
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if n < 1024 or unit == "PB":
            return f"{n:.3g} {unit}"
        n /= 1024
    raise AssertionError  # pragma: no cover


def parse_size(text: str) -> float:
    """``"4G"``, ``"500MB"``, ``"2e9"`` -> bytes (binary units); ValueError otherwise (a
    number Python's ``float`` refuses, ``1.2.3``, was its own message, naming nothing)."""
    accepted = (
        "accepted: a finite number of bytes > 0 in ASCII decimal notation, with an optional unit k, M, G, T"
    )
    number = r"(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
    match = re.fullmatch(rf"\s*({number})\s*([kKmMgGtT]?)[iI]?[bB]?\s*", text)
    if not match:
        raise ValueError(f"not a size: {shown(text)}; {accepted}")
    value = float(match.group(1)) * _UNITS[match.group(2).lower()]
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"not a size > 0: {shown(text)} is {value:g} bytes; {accepted}")
    return value


def available_memory() -> float:
    """Memory available to a new process now, bytes."""
    import psutil

    return float(psutil.virtual_memory().available)


def check_workers(workers: int) -> None:
    """:class:`InputError` naming ``--workers`` when that many worker processes of a local
    cluster, each an interpreter with the engine (:data:`BASE_BYTES`), do not fit in the
    memory available now: ``--workers 100000`` grew its process to 5.6 GB in ten minutes of
    starting them, deaf to SIGTERM."""
    have = available_memory()
    if workers * BASE_BYTES > have:
        raise InputError(
            f"--workers {workers}: {workers} worker processes of about {size_text(BASE_BYTES)} each need "
            f"{size_text(workers * BASE_BYTES)}, more than the memory available on this machine "
            f"({size_text(have)}); accepted: at most {int(have // BASE_BYTES)} workers here (the default "
            "is one per core)"
        )


def check(scenario: Any, outdir: Path | None, budget: Budget, text: str | None = None) -> Estimate:
    """The estimate of ``scenario`` (``text``: as :func:`estimate`); :class:`InputError`
    (estimate and limit) if it exceeds ``budget``, unless ``budget.force``."""
    need = estimate(scenario, text)
    if budget.force:
        return need
    where = str(scenario.source or "<scenario>")
    shape = f"{scenario.domain.cells} cells x {scenario.domain.layers} layers"
    memory = budget.memory if budget.memory is not None else available_memory()
    source = "--max-memory" if budget.memory is not None else "the memory available on this machine"
    # a limit of the address space (ulimit -v) below the memory: the run's MemoryError was numpy's message
    if budget.memory is None and disk.address_space_limit() < memory:
        memory, source = disk.address_space_limit(), "the address space of this process (ulimit -v)"
    if need.memory > memory:
        raise InputError(
            f"{where}: domain.cells, domain.layers: {shape} need about {size_text(need.memory)} of memory, "
            f"more than {source} ({size_text(memory)}); accepted: fewer cells or layers, a larger "
            "--max-memory, or --force to run anyway"
        )
    output, source = budget.output, "--max-output"
    if output is None and outdir is not None:
        output, source = disk.free_space(outdir), f"the free disk space at {outdir}"
        if disk.file_size_limit() < output:
            output, source = disk.file_size_limit(), "the file size limit of this process (ulimit -f)"
    if output is not None and need.output > output:
        raise InputError(
            f"{where}: time.output_interval: {need.records:.0f} output times of {shape} make a "
            f"result file of about {size_text(need.output)}, more than {source} ({size_text(output)}); "
            "accepted: a larger time.output_interval, fewer cells or layers, a larger --max-output, "
            "or --force to run anyway"
        )
    return need


def check_steps(scenario: Any, budget: Budget) -> Steps:
    """The steps of ``scenario``; :class:`InputError` (estimate and bound) if they exceed
    ``budget.step_limit``."""
    need = steps(scenario)
    if need.count > budget.step_limit:
        source = "--max-steps" if budget.steps is not None else "the default bound (--max-steps)"
        where = scenario.source or "<scenario>"
        raise InputError(
            f"{where}: time.end, time.cfl, domain.x_min, domain.x_max, domain.cells, gravity: about "
            f"{need.count:.3g} time steps ({scenario.time.end:g} s in steps of about {need.dt:.3g} s: "
            f"cells of {need.dx:.3g} m, the initial waves at {need.speed:.3g} m/s), more than {source} "
            f"({budget.step_limit:.3g}); accepted: a shorter time.end, larger cells, a smaller gravity or "
            "initial depth, a larger --max-steps, or --force to run anyway"
        )
    return need
