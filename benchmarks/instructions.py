"""Benchmark: instructions per cell-step of the parts of a step, counted by callgrind.

Machine-independent evidence of the per-cell cost (a count, not a time: it does not
move with the load of the machine).  The chute of ``chute.py`` (or, ``--case
dam_break``, the dam break of ``dam_break.py`` with ``--pressure``) on one thread runs
``--warm`` steps (and to ``--warm-time``), then ``--steps`` steps (or, ``--until T``, the
steps to the time ``T``, the last one cut to land on it) during which valgrind's
callgrind counts the instructions executed inside one region of the step:

- ``step``: the whole step (``Simulation.step``);
- ``transport``: the transport with its checks (``Simulation._transport``);
- ``transport_kernel``: the compiled transport sweep alone;
- ``vertical``: the implicit vertical step (``Simulation._vertical_step``);
- ``projection``: the pressure model's projection (``Simulation._project``);
- ``forces``: the impulses on the bed and walls (``BedForce.record``);
- with ``--pressure non_hydrostatic``, the parts of the projection: ``assembly`` (the
  constraint and its normal equations, ``normal_equations``), ``solve`` (the banded
  Cholesky factorisation with active sets, ``multipliers``), ``correction`` (``correct``)
  and ``finish`` (the new velocities and pressures, ``_finish``).

Each region is one run under valgrind (``--instr-atstart=no``: the import and the kernels'
loading, :data:`PROBE_STEPS`, run outside the instrumentation), divided by the cell-steps
on cells holding material. numba compiles for one instruction set (``CPU``; valgrind runs
no AVX-512) into its own cache, filled by a first run outside valgrind. ``--peer SOURCE``
also counts a plain C kernel of the same step (its source, built with ``gcc -O3
-march=CPU``, run as ``KERNEL N L STEPS``) on the same sizes: the difference of two runs
of ``--steps`` and twice as many steps, per cell-step (its transport and vertical step
together). ``--cache-sim`` also simulates the data caches (callgrind's ``--cache-sim``, no
prefetching: a count of the lines moved, not of their cost) as ``CACHES``, an L1 of 48 KiB
and an L2 of 2 MiB per core as the last level, and gives their misses per cell-step beside
the instructions.
``--functions N`` also lists the N compiled functions in which each region executes the
most instructions per cell-step (callgrind's ``--dump-instr``; numba's code has no symbols
valgrind can see, so each region's run records the object code numba loads or compiles and
locates its functions, ``nm``, at their addresses in the process; code a function inlined
counts as its caller's).

    python benchmarks/instructions.py [--case chute|dam_break] [--cells 2000] [--layers 64]
        [--steps 4 | --until T] [--warm 3] [--warm-time 0] [--start bagnold|rest]
        [--pressure hydrostatic|non_hydrostatic] [--regions step,transport,...]
        [--peer kernel.c] [--cache-sim] [--functions N] [--json FILE]

Needs valgrind, its headers (valgrind/callgrind.h) and a C compiler (and ``nm`` for
``--functions``).
"""

from __future__ import annotations

import argparse
import bisect
import collections
import ctypes
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

HELPER = r"""
#include <valgrind/callgrind.h>
void start(void) { CALLGRIND_START_INSTRUMENTATION; }
void toggle(void) { CALLGRIND_TOGGLE_COLLECT; }
"""
CPU = "haswell"
"""The instruction set counted, the same for numba and the C kernel (valgrind runs neither
AVX-512 nor the host's own CPU model: numba's cache is keyed by the CPU it compiled for)."""
FEATURES = "+avx,+avx2,+fma,+bmi,+bmi2,+f16c,+lzcnt,+movbe,+popcnt,+sse4.2"
REGIONS = ("step", "transport", "transport_kernel", "vertical", "projection", "forces")
PROJECTION_PARTS = {"assembly": "normal_equations", "solve": "multipliers", "correction": "correct",
                    "finish": "_finish"}  # fmt: skip
"""The regions inside the non-hydrostatic projection: the functions of its module counted."""
PROBE_STEPS = 3
"""Steps of a copy of the problem run before it, uncounted: numba loads each kernel from its
cache at the kernel's first call (hundreds of instructions per cell-step of a small mesh
in the first step, the redone steps' kernels in the first redone step), so that a count
from the start (``--warm 0``, a run from rest) counts the steps, not the loading."""
CACHES = ["--cache-sim=yes", "--D1=49152,12,64", "--LL=2097152,16,64"]
"""The simulated data caches of ``--cache-sim`` (size, ways, line): the L1 and the L2 of a
core of the machine the project is measured on, the L2 as the last level."""


def helper(directory: Path) -> Path:
    """The shared library of the two callgrind client requests, built once."""
    library = directory / "callgrind_toggle.so"
    if not library.exists():
        source = directory / "callgrind_toggle.c"
        source.write_text(HELPER)
        subprocess.run(["cc", "-O1", "-shared", "-fPIC", "-o", str(library), str(source)], check=True)
    return library


def wrap(owner, name: str, toggle) -> None:
    """Count the instructions inside ``owner.name`` (an attribute: a method of the
    simulation or a function of a module)."""
    inner = getattr(owner, name)

    def counted(*args, **kwargs):
        toggle()
        try:
            return inner(*args, **kwargs)
        finally:
            toggle()

    setattr(owner, name, counted)


def simulation(args: argparse.Namespace):
    """The benchmark's problem on one thread: the chute (``chute.py``) or the dam break
    (``dam_break.py``) with the pressure model ``args.pressure``."""
    sys.path.insert(0, str(Path(__file__).parent))
    from multilayer.app.simulation import Simulation

    if args.case == "chute":
        from chute import scenario

        return Simulation(scenario(args.cells, args.layers, 2, 1.0, 1, args.start))
    from dam_break import scenario as dam_break

    return Simulation(dam_break(args.cells, args.layers, 2, 5.0, 1, args.pressure, args.pressure_layers))


def objects() -> list:
    """numba's object code, as its JIT loads it from the cache or compiles it: (code library,
    object) pairs, recorded from here on (before numba's first compilation)."""
    from numba.core import codegen

    recorded: list = []
    owner: Any = codegen.CPUCodeLibrary
    compiled, cached = owner._object_compiled_hook.__func__, owner._object_getbuffer_hook.__func__

    def on_compiled(cls, module, buffer):
        recorded.append((getattr(module, "_CPUCodeLibrary__library", None), bytes(buffer)))
        return compiled(cls, module, buffer)

    def on_cached(cls, module):
        buffer = cached(cls, module)
        if buffer is not None:
            recorded.append((getattr(module, "_CPUCodeLibrary__library", None), bytes(buffer)))
        return buffer

    owner._object_compiled_hook = classmethod(on_compiled)
    owner._object_getbuffer_hook = classmethod(on_cached)
    return recorded


def symbols(recorded: list, workdir: Path) -> list[tuple[int, int, str]]:
    """The functions of the objects of :func:`objects` (``nm``) at their addresses in this
    process: (address, size, name).  Each object is placed by a function it alone defines
    (weak copies of a function stand in several objects)."""
    found = []
    for library, code in recorded:
        path = workdir / "object.o"
        path.write_bytes(code)
        listed = subprocess.run(
            ["nm", "-S", "--defined-only", str(path)], capture_output=True, text=True
        ).stdout
        rows = [row.split() for row in listed.splitlines()]
        functions = [
            (int(r[0], 16), int(r[1], 16), r[3], r[2]) for r in rows if len(r) == 4 and r[2] in "tTwW"
        ]
        names = collections.Counter(name for _, _, name, _ in functions)
        base = None
        for value, _, name, kind in functions:
            if library is not None and kind in "tT" and names[name] == 1 and not name.startswith("NRT"):
                address = library._codegen._engine.get_function_address(name)
                if address:
                    base = address - value
                    break
        if base is not None:
            found += [(base + value, size, name) for value, size, name, _ in functions]
    return sorted(found)


def by_function(
    out: Path, found: list[tuple[int, int, str]], cell_steps: int, most: int
) -> list[tuple[str, float]]:
    """The ``most`` functions of ``found`` in which the callgrind output ``out`` (with
    ``--dump-instr``) counts the most instructions, per cell-step (a call's line, the cost
    of its callee, not counted)."""
    starts = [address for address, _, _ in found]
    costs: collections.Counter = collections.Counter()
    columns, last, call = 1, 0, False
    for line in out.read_text().splitlines():
        if line.startswith("positions:"):
            columns = len(line.split()) - 1
        elif line.startswith("calls="):
            call = True
        elif line and line[0] in "0123456789+-*":
            fields = line.split()
            position = fields[0]
            if position.startswith("0x"):
                last = int(position, 16)
            elif position[0] in "+-":
                last += int(position)
            elif position != "*":
                last = int(position)
            if call or len(fields) <= columns:
                call = False
                continue
            i = bisect.bisect_right(starts, last) - 1
            inside = i >= 0 and last < found[i][0] + max(found[i][1], 1)
            costs[short(found[i][2]) if inside else "(elsewhere)"] += int(fields[columns])
    return [(name, count / cell_steps) for name, count in costs.most_common(most)]


def short(name: str) -> str:
    """A mangled numba name (``_ZN``, then each word after its length) as its last two
    words: module.function."""
    if not name.startswith("_ZN"):
        return name
    words, text = [], name[3:]
    while (digits := re.match(r"\d+", text)) is not None:
        size, text = int(digits.group()), text[digits.end() :]
        words.append(text[:size])
        text = text[size:]
    return ".".join(words[-2:]) if words else name


def run_region(args: argparse.Namespace) -> None:
    """Inside valgrind: the problem, counting the instructions of ``args.region``."""
    recorded = objects() if args.functions else []
    import numpy as np

    from multilayer.engine.transport import kernel

    lib = ctypes.CDLL(str(helper(Path(args.workdir))))
    probe = simulation(args)  # numba loads a kernel at its first call: not in the count
    for _ in range(PROBE_STEPS):
        probe.step()
    sim = simulation(args)
    while sim.steps < args.warm or sim.t < args.warm_time:
        sim.step()
    if args.region == "transport_kernel":
        wrap(kernel, "_stages_serial", lib.toggle)
    elif args.region == "forces":
        wrap(sim.forces, "record", lib.toggle)
    elif args.region in PROJECTION_PARTS:
        from multilayer.engine.pressure.non_hydrostatic import projection

        wrap(projection, PROJECTION_PARTS[args.region], lib.toggle)
    elif args.region != "step":
        method = {"transport": "_transport", "vertical": "_vertical_step", "projection": "_project"}
        wrap(sim, method[args.region], lib.toggle)
    lib.start()
    newton, cells, steps = sim.newton_iterations, 0, sim.steps
    while sim.t < args.until if args.until is not None else sim.steps - steps < args.steps:
        # a read-only view: sim.h would be checked at the next step
        cells += sim.fractions.size * int((sim.read_only("h") > 0.0).sum())
        if args.region == "step":
            lib.toggle()
        sim.step(np.inf if args.until is None else args.until)
        if args.region == "step":
            lib.toggle()
    result = {"cell_steps": cells, "newton": sim.newton_iterations - newton, "steps": sim.steps - steps}
    if args.functions:
        path = Path(args.workdir) / f"{args.region}.symbols.json"
        path.write_text(json.dumps(symbols(recorded, Path(args.workdir))))
    print("RESULT " + json.dumps(result))


def environment(cache: Path) -> dict[str, str]:
    """One thread; numba compiling for ``CPU`` into its own cache ``cache``."""
    return {**os.environ, "NUMBA_NUM_THREADS": "1", "NUMBA_CPU_NAME": CPU, "NUMBA_CPU_FEATURES": FEATURES,
            "NUMBA_CACHE_DIR": str(cache)}  # fmt: skip


def callgrind(
    command: list[str],
    out: Path,
    env: dict[str, str] | None = None,
    caches: bool = False,
    instr: bool = False,
) -> tuple[dict[str, int], str]:
    """Run ``command`` under callgrind: the events it counted (``Ir`` the instructions; with
    ``caches`` also the misses of the simulated caches, ``CACHES``), its output; with
    ``instr`` the counts per instruction in ``out``."""
    options = ["--instr-atstart=no", "--collect-atstart=no"] if command[0] == sys.executable else []
    options += ["--dump-instr=yes"] if instr else []
    run = subprocess.run(
        ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", *options, *(CACHES if caches else []),
         *command],
        check=True,
        capture_output=True,
        text=True,
        env=env,
    )  # fmt: skip
    text = out.read_text()
    events, totals = re.search(r"^events: (.*)$", text, re.M), re.search(r"^totals: (.*)$", text, re.M)
    if events is None or totals is None:
        raise SystemExit(f"callgrind wrote no totals to {out}")
    return dict(zip(events.group(1).split(), map(int, totals.group(1).split()), strict=True)), run.stdout


def misses(events: dict[str, int], cell_steps: int) -> dict[str, float]:
    """Misses of the simulated data caches per cell-step (reads and writes): L1, last level."""
    if "D1mr" not in events:
        return {}
    return {
        "D1_misses": (events["D1mr"] + events["D1mw"]) / cell_steps,
        "LL_misses": (events["DLmr"] + events["DLmw"]) / cell_steps,
    }


def described(counts: dict) -> str:
    """The simulated cache misses per cell-step in ``counts``, if any, as text."""
    if "D1_misses" not in counts:
        return ""
    return f", {counts['D1_misses']:.2f} L1 and {counts['LL_misses']:.2f} last-level misses"


def peer(source: Path, cells: int, layers: int, steps: int, workdir: Path, caches: bool) -> dict:
    """Instructions per cell-step of the C kernel (transport and vertical step together),
    from two runs of ``steps`` and ``2 steps`` steps (the set-up cancels); with ``caches``
    the simulated cache misses too."""
    binary = workdir / "kernel"
    subprocess.run(["gcc", "-O3", f"-march={CPU}", "-o", str(binary), str(source), "-lm"], check=True)
    runs = {n: [str(binary), str(cells), str(layers), str(n)] for n in (steps, 2 * steps)}
    counts = [callgrind(run, workdir / f"peer.{n}.out", None, caches)[0] for n, run in runs.items()]
    difference, cell_steps = {k: counts[1][k] - counts[0][k] for k in counts[0]}, steps * cells * layers
    return {"instructions": difference["Ir"], "cell_steps": cell_steps,
            "per_cell_step": difference["Ir"] / cell_steps, **misses(difference, cell_steps)}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", default="chute", choices=("chute", "dam_break"))
    parser.add_argument("--cells", type=int, default=2000)
    parser.add_argument("--layers", type=int, default=64)
    parser.add_argument("--steps", type=int, default=4, help="steps counted")
    parser.add_argument("--until", type=float, help="count the steps to this time instead")
    parser.add_argument("--warm", type=int, default=3, help="steps run before counting")
    parser.add_argument("--warm-time", type=float, default=0.0, help="time run before counting")
    parser.add_argument("--start", default="bagnold", choices=("bagnold", "rest"))
    parser.add_argument("--pressure", default="hydrostatic", choices=("hydrostatic", "non_hydrostatic"))
    parser.add_argument("--pressure-layers", type=int, default=None)
    parser.add_argument("--regions", default=",".join(REGIONS))
    parser.add_argument("--peer", type=Path, help="the C kernel's source, counted on the same sizes")
    parser.add_argument("--cache-sim", action="store_true", help="also count simulated cache misses")
    parser.add_argument("--functions", type=int, default=0, help="list the N costliest compiled functions")
    parser.add_argument("--json", type=Path, help="write the counts to this file")
    cache = Path(tempfile.gettempdir()) / "instructions-numba-cache"
    parser.add_argument(
        "--cache", type=Path, default=cache, help=f"numba's cache of the counted runs ({CPU})"
    )
    parser.add_argument("--region", help=argparse.SUPPRESS)
    parser.add_argument("--workdir", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.region:
        run_region(args)
        return
    workdir = Path(tempfile.mkdtemp(prefix="instructions-"))
    helper(workdir)
    forwarded = [
        f"--case={args.case}", f"--cells={args.cells}", f"--layers={args.layers}", f"--steps={args.steps}",
        *([f"--until={args.until}"] if args.until is not None else []),
        f"--warm={args.warm}", f"--warm-time={args.warm_time}", f"--start={args.start}",
        f"--pressure={args.pressure}",
        *([f"--pressure-layers={args.pressure_layers}"] if args.pressure_layers else []),
        f"--functions={args.functions}",
    ]  # fmt: skip
    env = environment(args.cache)
    command = [sys.executable, __file__, *forwarded, "--workdir", str(workdir), "--region"]
    subprocess.run([*command, "step"], check=True, stdout=subprocess.DEVNULL, env=env)  # numba's cache
    counts: dict = {}
    for region in args.regions.split(","):
        out = workdir / f"{region}.out"
        events, output = callgrind([*command, region], out, env, args.cache_sim, args.functions > 0)
        result = json.loads(output.split("RESULT ", 1)[1])
        total, simulated = events["Ir"], misses(events, result["cell_steps"])
        per_cell_step = total / result["cell_steps"]
        counts[region] = {"instructions": total, **result, "per_cell_step": per_cell_step, **simulated}
        print(f"{region}: {per_cell_step:.1f} instructions per cell-step{described(simulated)} ({result})")
        if args.functions:
            found = json.loads((workdir / f"{region}.symbols.json").read_text())
            costliest = by_function(out, found, result["cell_steps"], args.functions)
            counts[region]["functions"] = dict(costliest)
            print("\n".join(f"  {count:7.2f}  {name}" for name, count in costliest))
    if args.peer:
        counts["C kernel"] = peer(args.peer, args.cells, args.layers, args.steps, workdir, args.cache_sim)
        print(f"C kernel: {counts['C kernel']['per_cell_step']:.1f} instructions per cell-step"
              f"{described(counts['C kernel'])}")  # fmt: skip
    if args.json:
        args.json.write_text(
            json.dumps({"arguments": forwarded, "cpu": CPU, "counts": counts}, indent=1) + "\n"
        )


if __name__ == "__main__":
    main()
