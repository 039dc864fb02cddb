"""Benchmark: time per cell-step of the transport and of the vertical step, beside a plain C kernel.

The chute of ``chute.py`` on one thread, its steps timed part by part (CPU time of the
process in ``Simulation._transport`` and ``Simulation._vertical_step``, the rest of the
step apart), alternated ``--rounds`` times in one run with a plain C kernel of the same
step on the same sizes (``--peer``: an executable called as ``PEER N L STEPS`` that prints
``transport X ns/cell-step, vertical Y ns/cell-step``, such as a build of a MUSCL-Rusanov
transport with one implicit Thomas solve per column, regularised, no exact yield).  Each
part's figure is the median over the rounds; the ratios are multilayer's over the peer's.
Both sides run the same number of steps of the same mesh, after untimed warm-up steps.

    python benchmarks/per_cell.py --peer PATH [--cells 20000] [--layers 64] [--steps 16]
        [--rounds 5] [--start bagnold|rest] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

from chute import scenario

from multilayer.app.simulation import Simulation

PARTS = ("transport", "vertical", "rest of the step")


def timed_parts(sim: Simulation, steps: int) -> dict[str, float]:
    """CPU seconds of the transport, the vertical step and the rest over ``steps`` steps."""
    spent = {"transport": 0.0, "vertical": 0.0}

    def clocked(name: str, inner: Callable) -> Callable:
        def call(*args, **kwargs):
            start = time.process_time()
            try:
                return inner(*args, **kwargs)
            finally:
                spent[name] += time.process_time() - start

        return call

    sim._transport = clocked("transport", sim._transport)  # type: ignore[method-assign]
    sim._vertical_step = clocked("vertical", sim._vertical_step)  # type: ignore[method-assign]
    start = time.process_time()
    for _ in range(steps):
        sim.step()
    total = time.process_time() - start
    del sim._transport, sim._vertical_step  # the methods of the class again
    return {**spent, "rest of the step": total - spent["transport"] - spent["vertical"]}


def peer_parts(peer: str, cells: int, layers: int, steps: int) -> dict[str, float]:
    """The peer's ns per cell-step of its transport and vertical step."""
    out = subprocess.run(
        [peer, str(cells), str(layers), str(steps)], check=True, capture_output=True, text=True
    )
    match = re.search(r"transport ([\d.]+) ns/cell-step, vertical ([\d.]+) ns/cell-step", out.stdout)
    if match is None:
        raise SystemExit(
            f"the peer printed no 'transport X ns/cell-step, vertical Y ns/cell-step': {out.stdout!r}"
        )
    return {"transport": float(match.group(1)), "vertical": float(match.group(2))}


def summary(values: list[float]) -> str:
    """The median and the range."""
    return f"{statistics.median(values):.2f} ({min(values):.2f}-{max(values):.2f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--peer", required=True, help="the C kernel's executable (PEER N L STEPS)")
    parser.add_argument("--cells", type=int, default=20000)
    parser.add_argument("--layers", type=int, default=64)
    parser.add_argument("--steps", type=int, default=16)
    parser.add_argument("--warm", type=int, default=4, help="untimed steps before each timing")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--start", default="bagnold", choices=("bagnold", "rest"))
    parser.add_argument("--json", type=Path, help="write every round's figures to this file")
    args = parser.parse_args()
    per_cell_step = 1e9 / (args.cells * args.layers * args.steps)
    ours: dict[str, list[float]] = {part: [] for part in PARTS}
    theirs: dict[str, list[float]] = {"transport": [], "vertical": []}
    newton = []
    for _ in range(args.rounds):
        for part, value in peer_parts(args.peer, args.cells, args.layers, args.steps).items():
            theirs[part].append(value)
        sim = Simulation(scenario(args.cells, args.layers, 2, 1.0, 1, args.start))
        for _ in range(args.warm):
            sim.step()
        iterations = sim.newton_iterations
        for part, seconds in timed_parts(sim, args.steps).items():
            ours[part].append(seconds * per_cell_step)
        newton.append((sim.newton_iterations - iterations) / args.steps)
    print(
        f"chute from {args.start}, {args.cells} x {args.layers}, {args.steps} steps, one thread, "
        f"{args.rounds} rounds (median; range), Newton iterations per step {statistics.median(newton):.2f}"
    )
    for part in PARTS:
        line = f"{part}: multilayer {summary(ours[part])} ns/cell-step"
        if part in theirs:
            ratios = [a / b for a, b in zip(ours[part], theirs[part], strict=True)]
            line += f", peer {summary(theirs[part])}, ratio {summary(ratios)}"
        print(line)
    if args.json:
        record = {
            "arguments": vars(args) | {"json": str(args.json)},
            "multilayer_ns": ours,
            "peer_ns": theirs,
        }
        args.json.write_text(json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    main()
