"""Published and experimental data the validation cases compare with.

Every file of ``multilayer/validation/data/`` is listed in ``data/sources.yaml`` with its
source (the publication), where in it the numbers are (table, figure, equation), their
status (primary, secondary or digitised) and notes.  A file is a YAML mapping of named
values, or a CSV table whose header names each column with its unit, ``name (unit)``.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

DATA = Path(__file__).resolve().parent / "data"
SOURCES = DATA / "sources.yaml"
STATUSES = ("primary", "secondary", "digitised")


@dataclass(frozen=True)
class Source:
    """Where the numbers of one data file come from."""

    source: str
    where: str
    status: str
    notes: str = ""

    def cite(self) -> str:
        """For a report: the publication and where in it, then the status and the notes
        unless the numbers were read in the publication itself."""
        if self.status == "primary":
            return f"{self.source}, {self.where}"
        return f"{self.source}, {self.where}; {self.status}: {self.notes}"


def sources() -> dict[str, Source]:
    """File name -> its source, as listed in ``data/sources.yaml``."""
    listed = yaml.safe_load(SOURCES.read_text(encoding="utf-8")) or {}
    return {name: Source(**entry) for name, entry in listed.items()}


def source(name: str) -> Source:
    """The source of data file ``name``."""
    return sources()[name]


def values(name: str) -> dict[str, float]:
    """The named values of a YAML data file."""
    data = yaml.safe_load((DATA / name).read_text(encoding="utf-8"))
    return {key: float(value) for key, value in data.items()}


def table(name: str) -> dict[str, np.ndarray]:
    """The columns of a CSV data file, by their header (``name (unit)``), as float arrays."""
    with open(DATA / name, newline="", encoding="utf-8") as f:
        rows = [row for row in csv.reader(f) if row and not row[0].startswith("#")]
    header, body = rows[0], rows[1:]
    return {column.strip(): np.array([float(r[i]) for r in body]) for i, column in enumerate(header)}
