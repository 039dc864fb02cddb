"""Benchmark: the work of the mixture's local step, counted (deterministic, no times).

Runs the shipped mixture scenarios (or the files given) and prints, per run:

- the time steps, and the attempts redone because a column at rest started (the step is
  redone with it moving: docs/mixture.md, "Columns set moving") or shorter for the
  Courant condition;
- the local-step calls of the time loop (two per attempt at order 2);
- the batched evaluations: calls of the rheology's ``mixture_yield_stress`` and of the
  compiled map that answered (engine/mixture/local_kernel.py), one per evaluation of the
  local step's map for all the columns iterated together (the Newton iteration is the
  numpy reference's here: the compiled one, equal to it bit for bit, evaluates column by
  column);
- the Newton iterations, ``Simulation.newton_iterations`` (of every attempt, redone ones
  included; per local step the iterations of its batch of columns summed over its sub-step
  levels, a local step stopped at a start counting one), per step;
- the batched evaluations and Newton iterations of the kept attempts only.

``--finished`` finishes every local step, the last one of a step too (no stop at a start):
the run is the same, the counts are those of the finished local steps.

    python benchmarks/mixture_counts.py [--end 2] [--layers 4] [--finished] [FILE ...]
"""

from __future__ import annotations

import argparse
from collections import Counter
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any
from unittest import mock

import multilayer
from multilayer.app.runner import output_times
from multilayer.app.simulation import Simulation
from multilayer.engine import simulation as engine
from multilayer.engine.mixture import local_kernel, local_step

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
SHIPPED = [
    SCENARIOS / f"{kind}_{packing}.yaml"
    for kind in ("submarine_collapse", "immersed_layer")
    for packing in ("loose", "dense")
]


@contextmanager
def counted(finished: bool) -> Iterator[Counter[str]]:
    """The counts of the runs within the block, every local step finished if ``finished``."""
    counts: Counter[str] = Counter()
    start: Counter[str] = Counter()  # the present attempt: evaluations before it, its iterations
    call, local, transport = local_step.call, local_step.LocalStep.__call__, engine.Simulation._transport
    kernel = local_kernel.one_layer
    tries, stresses = engine.Simulation._transport_and_stresses, engine.Simulation._stress_steps
    step, vertical = engine.Simulation.step, engine.Simulation._vertical_step

    def evaluations(law: Any, method: str, *args: Any, **kwargs: Any) -> Any:
        counts["batched evaluations"] += method == "mixture_yield_stress"
        return call(law, method, *args, **kwargs)

    def compiled(*args: Any) -> Any:
        answered = kernel(*args)  # if not, the numpy map evaluates the trial: counted there
        counts["batched evaluations"] += bool(answered)
        return answered

    def local_calls(self: Any, *args: Any, substeps: int = 1, **kwargs: Any) -> Any:
        counts["local-step calls"] += substeps == 1  # not the sub-steps' own calls
        return local(self, *args, substeps=substeps, **kwargs)

    def attempts(self: Any, *args: Any, stage: int | None = None, **kwargs: Any) -> Any:
        if stage in (0, None):  # an attempt starts
            counts["attempts"] += 1
            start["evaluations"], start["iterations"] = counts["batched evaluations"], 0
        return transport(self, *args, stage=stage, **kwargs)

    def stress_steps(self: Any, *args: Any, **kwargs: Any) -> Any:
        result = stresses(self, *args, **kwargs)
        start["iterations"] += result[2]
        return result

    def courant_tries(self: Any, *args: Any) -> Any:
        counts["tries"] += 1
        return tries(self, *args)

    def finish(self: Any, *args: Any, last: bool = False) -> Any:
        return vertical(self, *args)  # never the last stress step: no stop at a start

    def kept(self: Any, *args: Any) -> Any:
        dt = step(self, *args)
        counts["steps"] += 1
        counts["kept batched evaluations"] += counts["batched evaluations"] - start["evaluations"]
        counts["kept Newton iterations"] += start["iterations"]
        return dt

    with ExitStack() as stack:
        for owner, name, wrapper in (
            (local_step, "call", evaluations),
            (local_kernel, "one_layer", compiled),
            (local_kernel, "iterate_one_layer", lambda *args: -1),  # hands every iteration back
            (local_step.LocalStep, "__call__", local_calls),
            (engine.Simulation, "_transport", attempts),
            (engine.Simulation, "_stress_steps", stress_steps),
            (engine.Simulation, "_transport_and_stresses", courant_tries),
            (engine.Simulation, "step", kept),
        ):
            stack.enter_context(mock.patch.object(owner, name, wrapper))
        if finished:
            stack.enter_context(mock.patch.object(engine.Simulation, "_vertical_step", finish))
        yield counts


def run(path: Path, overrides: dict[str, Any], finished: bool) -> dict[str, int | float]:
    """The counts of the run of ``path`` (with ``overrides``)."""
    scenario = multilayer.load(path, overrides)
    with counted(finished) as counts:
        sim = Simulation(scenario)
        for t in output_times(scenario.time.end, scenario.time.output_interval):
            sim.advance(t)  # landing on the output times, as a run does
    steps = counts["steps"]
    return {
        "steps": steps,
        "redone for a start": counts["attempts"] - counts["tries"],
        "redone shorter": counts["tries"] - steps,
        "local-step calls": counts["local-step calls"],
        "batched evaluations": counts["batched evaluations"],
        "kept batched evaluations": counts["kept batched evaluations"],
        "Newton iterations": sim.newton_iterations,
        "kept Newton iterations": counts["kept Newton iterations"],
        "Newton iterations per step": sim.newton_iterations / steps,
        "kept Newton iterations per step": counts["kept Newton iterations"] / steps,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("files", nargs="*", type=Path, default=SHIPPED)
    parser.add_argument("--end", type=float, help="time.end (s); default: the file's")
    parser.add_argument("--layers", type=int, help="domain.layers; default: the file's")
    parser.add_argument("--finished", action="store_true", help="finish every local step")
    args = parser.parse_args()
    overrides: dict[str, Any] = {}
    if args.end is not None:
        overrides["time.end"] = args.end
    if args.layers is not None:
        overrides["domain.layers"] = args.layers
    for path in args.files:
        counts = run(path, overrides, args.finished)
        shown = ", ".join(
            f"{name} {value:.2f}" if isinstance(value, float) else f"{name} {value}"
            for name, value in counts.items()
        )
        print(f"{path.stem}: {shown}")


if __name__ == "__main__":
    main()
