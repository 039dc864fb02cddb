"""Memory and output-size estimates of a scenario, checked against a budget before a run.

The engine holds the FiPy mesh of ``cells x layers`` cells (faces, vertices, geometry) and
the state with its work arrays.  Measured with ``benchmarks/dam_break.py`` scenarios of
64 000 to 800 000 cells, every column wet (peak resident memory): 2.1-2.4 kB per cell on
top of about 150 MB for the interpreter and libraries; the estimate uses 2.6 kB and
200 MB.  ``result.nc`` receives one record per output time (``ceil(end /
output_interval)`` of them plus the initial state), each of ``(layers + 2) cells + 3``
doubles (``u``, ``h``, the static interface; time, front, mass).

By default a run must fit the memory available now and the free space of the file
system it writes to (and the file size limit of the process, ``ulimit -f``);
``--max-memory`` and ``--max-output`` set a smaller (or larger) budget and ``--force``
skips the check.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from multilayer.errors import InputError
from multilayer.io import disk

BYTES_PER_CELL = 2600
BASE_BYTES = 200 * 2**20
_UNITS = {"": 1, "k": 2**10, "m": 2**20, "g": 2**30, "t": 2**40}


@dataclass(frozen=True)
class Estimate:
    """What a scenario needs: peak memory and size of ``result.nc``, bytes."""

    memory: float
    output: float
    records: float


@dataclass(frozen=True)
class Budget:
    """Limits of a run (bytes); ``None``: the available memory, the free disk space."""

    memory: float | None = None
    output: float | None = None
    force: bool = False


def estimate(scenario: Any) -> Estimate:
    """Peak memory and output size of ``scenario`` (module docstring)."""
    cells, layers = float(scenario.domain.cells), float(scenario.domain.layers)
    end, interval = scenario.time.end, scenario.time.output_interval
    records = 1.0 + (1.0 if interval >= end else math.ceil(end / interval - 1e-9))
    per_record = 8.0 * ((layers + 2.0) * cells + 3.0)
    fixed = 8.0 * (5.0 * cells + 4.0 * layers) + len(scenario.resolved_yaml()) + 16384
    return Estimate(BASE_BYTES + BYTES_PER_CELL * cells * layers, fixed + records * per_record, records)


def size_text(n: float) -> str:
    """``1.5 GB``: a byte count for messages."""
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if n < 1024 or unit == "PB":
            return f"{n:.3g} {unit}"
        n /= 1024
    raise AssertionError  # pragma: no cover


def parse_size(text: str) -> float:
    """``"4G"``, ``"500MB"``, ``"2e9"`` -> bytes (binary units); ValueError otherwise."""
    match = re.fullmatch(r"\s*([0-9.]+(?:[eE][+-]?[0-9]+)?)\s*([kKmMgGtT]?)[iI]?[bB]?\s*", text)
    if not match:
        raise ValueError(
            f"not a size: {text!r}; accepted: a number of bytes with an optional unit k, M, G, T"
        )
    value = float(match.group(1)) * _UNITS[match.group(2).lower()]
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"not a size > 0: {text!r}")
    return value


def available_memory() -> float:
    """Memory available to a new process now, bytes."""
    import psutil

    return float(psutil.virtual_memory().available)


def check(scenario: Any, outdir: Path | None, budget: Budget) -> Estimate:
    """The estimate of ``scenario``; :class:`InputError` (estimate and limit) if it exceeds
    ``budget``, unless ``budget.force``."""
    need = estimate(scenario)
    if budget.force:
        return need
    where = str(scenario.source or "<scenario>")
    shape = f"{scenario.domain.cells} cells x {scenario.domain.layers} layers"
    memory = budget.memory if budget.memory is not None else available_memory()
    if need.memory > memory:
        source = "--max-memory" if budget.memory is not None else "the memory available on this machine"
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
