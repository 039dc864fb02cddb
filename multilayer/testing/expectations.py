"""Regression expectations: a scenario's ``expect:`` list checked against its run summary.

Each entry ``{quantity, value, rtol, atol}`` (docs/scenarios.md) passes when

    |obtained - value| <= atol + rtol * |value|          (a missing tolerance counts as 0)

where ``obtained`` is ``multilayer.results.summary(result.nc)[quantity]``; a NaN never
passes.  The values hold for the scenario *exactly as written in the file* (resolution
included): a check runs the file as it is.  The shipped scenarios are therefore kept cheap
enough for CI, and their full-resolution counterparts are run by ``docs/make_validation.py``
through ``--set`` overrides (docs/validation.md, "Regression checks").
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from multilayer.io.scenario import Expect, Scenario


@dataclass(frozen=True)
class Outcome:
    """The result of one expectation."""

    quantity: str
    expected: float
    obtained: float
    tolerance: float
    """Allowed absolute deviation, ``atol + rtol * |expected|``."""

    @property
    def passed(self) -> bool:
        """True when the obtained value lies within the tolerance (never for NaN)."""
        return math.isfinite(self.obtained) and abs(self.obtained - self.expected) <= self.tolerance


def evaluate(expectations: Sequence[Expect], summary: Mapping[str, float]) -> list[Outcome]:
    """Compare every expectation with the run summary."""
    outcomes = []
    for entry in expectations:
        tolerance = (entry.atol or 0.0) + (entry.rtol or 0.0) * abs(entry.value)
        outcomes.append(Outcome(entry.quantity, entry.value, float(summary[entry.quantity]), tolerance))
    return outcomes


def check(scenario: Scenario, outdir: str | Path | None = None) -> list[Outcome]:
    """Run ``scenario`` quietly (into ``outdir``, else a temporary directory) and evaluate.

    Raises :class:`multilayer.errors.RunError` if the run fails.
    """
    from multilayer.app import runner  # the engine is imported only to run

    if outdir is not None:
        return evaluate(scenario.expect, runner.run(scenario, outdir, quiet=True))
    with tempfile.TemporaryDirectory(prefix=f"multilayer-check-{scenario.name}-") as tmp:
        return evaluate(scenario.expect, runner.run(scenario, tmp, quiet=True))


def report(name: str, outcomes: Sequence[Outcome]) -> str:
    """Expected vs obtained table, one line per expectation, with a verdict per line."""
    lines = [
        f"{name}: {sum(o.passed for o in outcomes)}/{len(outcomes)} expectations met",
        f"  {'quantity':<28} {'expected':>12} {'obtained':>12} {'tolerance':>10}  verdict",
    ]
    for o in outcomes:
        lines.append(
            f"  {o.quantity:<28} {o.expected:>12.6g} {o.obtained:>12.6g} "
            f"{o.tolerance:>10.3g}  {'ok' if o.passed else 'FAILED'}"
        )
    return "\n".join(lines)
