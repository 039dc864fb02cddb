"""Expectations: a scenario's ``expect:`` list checked against its run summary.

Each entry ``{kind, quantity, value, rtol, atol, source}`` (docs/scenarios.md) passes when

    |obtained - value| <= atol + rtol * |value|          (a missing tolerance counts as 0)

where ``obtained`` is ``multilayer.io.results.summary(result.nc)[quantity]``, or, for an
entry with ``exact:``, the relative error norm of a field against an exact solution
(:mod:`multilayer.app.exact_solutions`), expected 0 within ``atol``; a NaN never passes.
``kind`` says what passing means: ``regression``, the value is pinned from the
code's own output (a change detector); ``reference``, the value is an exact solution or a
published result named in ``source`` (a validation).  The values hold for the scenario
*exactly as written in the file* (resolution included): a check runs the file as it is.
The shipped scenarios are therefore kept cheap enough for CI, and their full-resolution
counterparts are run by :mod:`multilayer.validation` through ``--set`` overrides
(docs/validation.md, "Expectations of the scenario files").
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from multilayer.app import exact_solutions
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


def exact_label(solution: object, field: object, norm: object) -> str:
    """The name of a comparison with an exact solution: ``<field>_<norm>_error_<solution>``."""
    return f"{field}_{norm}_error_{solution}"


def label(entry: Expect) -> str:
    """What an entry checks: its quantity, or the :func:`exact_label` of its comparison."""
    if entry.exact is not None:
        return exact_label(entry.exact.solution, entry.exact.field, entry.exact.norm)
    assert entry.quantity is not None  # required without exact
    return entry.quantity


def evaluate(expectations: Sequence[Expect], measured: Mapping[str, float]) -> list[Outcome]:
    """Compare every expectation with the measured values, keyed by :func:`label` (the run
    summary and the errors against exact solutions)."""
    outcomes = []
    for entry in expectations:
        value = 0.0 if entry.value is None else entry.value
        outcomes.append(
            Outcome(
                label(entry), value, float(measured[label(entry)]), entry.tolerance, entry.kind, entry.source
            )
        )
    return outcomes


def _where(scenario: Scenario, index: int) -> str:
    return f"{scenario.source or scenario.name}: expect.{index}.exact"


def validate(scenario: Scenario) -> None:
    """Raise :class:`~multilayer.errors.InputError` if an ``exact:`` entry names a solution
    whose assumptions the scenario does not meet (checked before anything runs)."""
    for index, entry in enumerate(scenario.expect):
        if entry.exact is not None:
            exact_solutions.solution(scenario, entry.exact, _where(scenario, index))


def measure(scenario: Scenario, result: Path) -> dict[str, float]:
    """The run summary of ``result`` (a result directory or file) and the error of each
    ``exact:`` entry of ``scenario``, keyed by :func:`label`."""
    from multilayer.io.results import open_result, summary  # reading results imports FiPy

    measured = summary(result)
    comparisons = [(i, e.exact) for i, e in enumerate(scenario.expect) if e.exact is not None]
    if comparisons:
        ds = open_result(result)
        for index, comparison in comparisons:
            where = _where(scenario, index)
            measured[label(scenario.expect[index])] = exact_solutions.error(ds, scenario, comparison, where)
    return measured


def check(scenario: Scenario, outdir: str | Path | None = None) -> list[Outcome]:
    """Run ``scenario`` quietly (into ``outdir``, else a temporary directory) and evaluate.

    Raises :class:`multilayer.errors.InputError` (before running) if an ``exact:`` entry
    does not apply, :class:`multilayer.errors.RunError` if the run fails.
    """
    from multilayer.app import runner  # the engine is imported only to run

    validate(scenario)
    if outdir is not None:
        runner.run(scenario, outdir, quiet=True)
        return evaluate(scenario.expect, measure(scenario, Path(outdir)))
    with tempfile.TemporaryDirectory(prefix=f"multilayer-check-{scenario.name}-") as tmp:
        runner.run(scenario, tmp, quiet=True)
        return evaluate(scenario.expect, measure(scenario, Path(tmp)))


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
        f"  {'kind':<10} {'quantity':<48} {'expected':>12} {'obtained':>12} {'tolerance':>10}  verdict",
    ]
    for o in outcomes:
        expected, obtained = f"{o.expected:.6g}", f"{o.obtained:.6g}"
        if not o.passed and expected == obtained:  # to the digits that tell them apart
            expected, obtained = repr(float(o.expected)), repr(float(o.obtained))
        lines.append(
            f"  {o.kind:<10} {o.quantity:<48} {expected:>12} {obtained:>12} "
            f"{o.tolerance:>10.3g}  {'ok' if o.passed else 'FAILED'}"
        )
    lines += [f"  reference {o.quantity}: {o.source}" for o in outcomes if o.kind == "reference"]
    return "\n".join(lines)
