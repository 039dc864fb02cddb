"""Mesh studies: an error measured at successive resolutions, its observed orders, and the
rule that justifies the tolerance of a scenario file's comparison with an exact solution."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import xarray as xr

from multilayer.app import exact_solutions
from multilayer.scenario import Scenario
from multilayer.scenario.schema import ExactComparison


@dataclass(frozen=True)
class MeshStudy:
    """Errors at resolutions ``sizes`` (cells or layers, increasing)."""

    sizes: tuple[int, ...]
    errors: tuple[float, ...]

    def orders(self) -> list[float]:
        """Observed orders log(e_{k-1}/e_k) / log(n_k/n_{k-1}) between successive resolutions."""
        e, n = self.errors, self.sizes
        return [math.log(e[k - 1] / e[k]) / math.log(n[k] / n[k - 1]) for k in range(1, len(e))]

    def error(self, size: int) -> float:
        """The error at resolution ``size`` (nan if not in the study)."""
        return self.errors[self.sizes.index(size)] if size in self.sizes else math.nan

    def separates(self, size: int, tolerance: float) -> bool:
        """The tolerance rule of a file run at resolution ``size``: the error there passes
        (``e(size) < tolerance``) and the twice coarser run fails (``tolerance <= e(size / 2)``).

        A correct code at the file's resolution meets the tolerance; any loss of accuracy
        worth a halving of the resolution (a lost order, a broken boundary) does not.  The
        study must contain both resolutions."""
        return self.error(size) < tolerance <= self.error(size // 2)


def difference_orders(values: Sequence[float]) -> list[float]:
    """Observed orders from a quantity at three or more levels, each halving the step or
    the cell of the one before, without an exact answer: ``log2(|q_{k-1} - q_k| / |q_k -
    q_{k+1}|)`` (nan where a difference vanishes)."""
    d = [abs(values[k] - values[k - 1]) for k in range(1, len(values))]
    return [
        math.log2(d[k - 1] / d[k]) if d[k] > 0.0 and d[k - 1] > 0.0 else math.nan for k in range(1, len(d))
    ]


@dataclass(frozen=True)
class FileComparison:
    """A scenario file's own comparison with an exact solution (its ``expect:`` entry with
    ``exact:``) and the tolerance the file gives it (``atol``)."""

    exact: ExactComparison
    tolerance: float


def file_comparison(scenario: Scenario) -> FileComparison:
    """The scenario's (first) comparison with an exact solution."""
    for entry in scenario.expect:
        if entry.exact is not None and entry.atol is not None:
            return FileComparison(entry.exact, entry.atol)
    raise ValueError(f"{scenario.name}: no expect entry with exact")


def file_error(ds: xr.Dataset, scenario: Scenario) -> float:
    """The error of the scenario's own comparison in its result ``ds``."""
    return exact_solutions.error(ds, scenario, file_comparison(scenario).exact)
