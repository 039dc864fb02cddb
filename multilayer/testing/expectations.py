"""Expectations: a scenario's ``expect:`` list checked against its run summary.

Each entry ``{kind, quantity, value, rtol, atol, source}`` (docs/scenarios.md) passes when

    |obtained - value| <= atol + rtol * |value|          (a missing tolerance counts as 0)

where ``obtained`` is ``multilayer.io.results.summary(result.nc)[quantity]``; a NaN never
passes.  ``kind`` says what passing means: ``regression``, the value is pinned from the
code's own output (a change detector); ``reference``, the value is an exact solution or a
published result named in ``source`` (a validation).  The values hold for the scenario
*exactly as written in the file* (resolution included): a check runs the file as it is.
The shipped scenarios are therefore kept cheap enough for CI, and their full-resolution
counterparts are run by ``docs/make_validation.py`` through ``--set`` overrides
(docs/validation.md, "Expectations of the scenario files").
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from multilayer.scenario import Scenario
from multilayer.scenario.schema import EXPECT_KINDS, Expect


@dataclass(frozen=True)
class Outcome:
    """The result of one expectation."""

    quantity: str
    expected: float
    obtained: float
    tolerance: float
    """Allowed absolute deviation, ``atol + rtol * |expected|``."""
    kind: str = "regression"
    """``regression`` (pinned from the code's output) or ``reference`` (exact or published)."""
    source: str | None = None
    """Where a reference value comes from."""

    @property
    def passed(self) -> bool:
        """True when the obtained value lies within the tolerance (never for NaN)."""
        return math.isfinite(self.obtained) and abs(self.obtained - self.expected) <= self.tolerance


def evaluate(expectations: Sequence[Expect], summary: Mapping[str, float]) -> list[Outcome]:
    """Compare every expectation with the run summary."""
    outcomes = []
    for entry in expectations:
        tolerance = (entry.atol or 0.0) + (entry.rtol or 0.0) * abs(entry.value)
        outcomes.append(
            Outcome(
                entry.quantity,
                entry.value,
                float(summary[entry.quantity]),
                tolerance,
                entry.kind,
                entry.source,
            )
        )
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
    """Expected vs obtained table, one line per expectation with its kind and verdict.

    The sources of reference values follow the table.
    """
    met = {kind: sum(o.passed for o in outcomes if o.kind == kind) for kind in EXPECT_KINDS}
    counts = ", ".join(
        f"{met[kind]}/{sum(o.kind == kind for o in outcomes)} {kind}"
        for kind in EXPECT_KINDS
        if any(o.kind == kind for o in outcomes)
    )
    lines = [
        f"{name}: {sum(o.passed for o in outcomes)}/{len(outcomes)} expectations met ({counts})",
        f"  {'kind':<10} {'quantity':<28} {'expected':>12} {'obtained':>12} {'tolerance':>10}  verdict",
    ]
    for o in outcomes:
        lines.append(
            f"  {o.kind:<10} {o.quantity:<28} {o.expected:>12.6g} {o.obtained:>12.6g} "
            f"{o.tolerance:>10.3g}  {'ok' if o.passed else 'FAILED'}"
        )
    lines += [f"  reference {o.quantity}: {o.source}" for o in outcomes if o.kind == "reference"]
    return "\n".join(lines)
