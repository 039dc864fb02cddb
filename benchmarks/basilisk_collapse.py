"""Benchmark: the tall-column collapse against Basilisk's layered solver (docs/nonhydrostatic.md,
"An independent code: Basilisk's layered solver").

The granular column collapse at a = 7 (L0 = 5 cm, H0 = 35 cm), the channel collapse of
docs/validation.md without its side walls, Jop's mu(I) of the same beads, 8 layers, a
no-slip bed, run to t = 1.5 s with outputs every 0.01 s, either as the released rectangle
or as the mound H0 cos^2(pi x/(4 L0)) on [0, 2 L0] of the same height and volume, by
multilayer and by benchmarks/basilisk_collapse/collapse.c, a program for Basilisk's layered
solver (src/layered/hydro.h, and src/layered/nh.h with the non-hydrostatic pressure;
Popinet 2020) that adds the same vertical mu(I) stress and remaps the layers to equal
fractions every step.  Both outputs are measured alike (multilayer.io.observables):

- tip: (x - L0)/L0 where h falls through 1.5 mm (3 grain diameters);
- front95: (x - L0)/L0 of the point holding 95 % of the volume behind it;
- mass: the volume per unit width at the end (m^2, initially 0.0175);
- t_stop: when the tip's speed falls below 1 cm/s for good (nan: still faster at the end),
  and t_stop_scaled = t_stop / sqrt(H0/g); t95: when the tip has covered 95 % of its run.

    python benchmarks/basilisk_collapse.py --basilisk DIR [--shape mound | rectangle]
        [--pressure non_hydrostatic | hydrostatic] [--dx-mm 2] [--layers 8]
        [--code both | basilisk | multilayer] [--cfl 0.5] [--dt-max S] [--tolerance 1e-5]
        [--time-cfl 0.45] [--pressure-layers N] [--work DIR] [--json]

``--basilisk`` is the ``src`` directory of a Basilisk source tree with ``qcc`` built in it
(default: the ``BASILISK`` environment variable; in ``src``: ``ln -s config.gcc config``,
then ``BASILISK=$PWD make -C ast`` and ``BASILISK=$PWD make qcc``); the numbers of
docs/nonhydrostatic.md are of the comphy-lab/basilisk-C snapshot c7be0ade.  The program is
built in the work directory as ``qcc -O2 [-DNH=1] collapse.c -lm``.  Without a ``qcc``
only ``--code multilayer`` runs: otherwise the script stops with exit status 2 and says
why.  Basilisk's domain is [0, 2.08] m hydrostatic (65 x 2^k cells) and [0, 1.024] m
non-hydrostatic (2^k cells, its multigrid), walls at both ends; multilayer's is [0, 2.08]
and [0, 1.04] m, wall on the left, outflow on the right (never reached).  ``--cfl``,
``--dt-max`` and ``--tolerance`` are Basilisk's CFL (and CFL_H, hydrostatic), DT (default
1e-3 s non-hydrostatic: the first step starts from rest) and TOLERANCE; ``--time-cfl`` and
``--pressure-layers`` are multilayer's ``time.cfl`` and ``model.pressure_layers`` (default:
all the layers).  The outputs go to ``--work`` (default: a temporary directory, removed);
``--json`` prints each run as a line of benchmarks/history/collapse_basilisk_nh.json.
Nothing is timed.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

import multilayer
from multilayer.io import observables

HERE = Path(__file__).resolve().parent
PROGRAM = HERE / "basilisk_collapse" / "collapse.c"
SCENARIO = HERE.parent / "scenarios" / "column_collapse_channel.yaml"

L_COLUMN = 0.05
"""m: the released column's length L0."""
H_COLUMN = 0.35
"""m: its height H0 (a = 7)."""
GRAIN = 0.5e-3
"""m: the grain diameter (the tip is 3 of them above the bed)."""
GRAVITY = 9.81
JOP = {"name": "jop_mu_i", "mu_s": 0.38186, "mu_2": 0.64347, "I_0": 0.26602}
"""Jop's mu(I) of the beads of the channel collapse (collapse.c has the same numbers)."""
MOUND_POINTS = 401
"""Points of multilayer's mound profile on [0, 2 L0]."""
OUTPUT_INTERVAL = 0.01
END = 1.5


@dataclass
class Series:
    """Outputs of one run: times (s), cell centres (m), depth h[time, x] (m) and the largest
    |u| of each column's layers (m/s)."""

    t: np.ndarray
    x: np.ndarray
    h: np.ndarray
    umax: np.ndarray


def measures(series: Series) -> dict[str, float | None]:
    """The record's measures of one run (module docstring); None where undefined."""
    dx = float(series.x[1] - series.x[0])
    tips = np.array([observables.tip(series.x, h, GRAIN) for h in series.h])
    mass = series.h.sum(axis=1) * dx
    t_stop = observables.front_stop_time(series.t, tips)
    values = {
        "t_end": float(series.t[-1]),
        "tip": (tips[-1] - L_COLUMN) / L_COLUMN,
        "front95": (observables.mass_front(series.x, series.h[-1]) - L_COLUMN) / L_COLUMN,
        "mass": float(mass[-1]),
        "mass_change": float(mass[-1] - mass[0]),
        "t_stop": t_stop,
        "t_stop_scaled": t_stop / math.sqrt(H_COLUMN / GRAVITY),
        "t95": observables.time_to_fraction(series.t, tips),
        "umax_end": float(series.umax[-1].max()),
    }
    for at in (0.1, 0.2):
        values[f"tip_{at:g}s"] = (float(np.interp(at, series.t, tips)) - L_COLUMN) / L_COLUMN
    return {key: None if not math.isfinite(v) else float(v) for key, v in values.items()}


def rounded(key: str, value: float) -> float:
    """``value`` as the record gives it: 6 significant digits for the small ones, else 4 decimals."""
    return float(f"{value:.6g}") if key in ("umax_end", "mass_change") else round(value, 4)


def parse_output(text: str) -> Series:
    """collapse.c's stdout: blocks of a line ``t TIME`` and lines ``x H umax`` (other lines,
    Basilisk's own ``#`` summary, are skipped)."""
    times: list[float] = []
    blocks: list[list[list[float]]] = []
    for line in text.splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        if line.startswith("t "):
            times.append(float(line.split()[1]))
            blocks.append([])
        else:
            blocks[-1].append([float(v) for v in line.split()])
    data = np.array(blocks)
    return Series(np.array(times), data[0, :, 0], data[:, :, 1], data[:, :, 2])


def qcc_or_exit(basilisk: str | None) -> Path:
    """The ``qcc`` of the Basilisk tree ``basilisk`` (exit status 2 if there is none)."""
    if not basilisk:
        print(
            "basilisk_collapse.py: Basilisk is needed for its runs: give --basilisk DIR (or set "
            "BASILISK), the src directory of a Basilisk source tree with qcc built in it "
            "(--code multilayer runs multilayer alone)",
            file=sys.stderr,
        )
        sys.exit(2)
    qcc = Path(basilisk) / "qcc"
    if not os.access(qcc, os.X_OK):
        print(
            f"basilisk_collapse.py: no executable qcc in {basilisk} (build it: make qcc there)",
            file=sys.stderr,
        )
        sys.exit(2)
    return qcc


def build(qcc: Path, work: Path, nonhydrostatic: bool) -> Path:
    """collapse.c built in ``work`` as ``qcc -O2 [-DNH=1] collapse.c -lm``; the executable."""
    shutil.copy(PROGRAM, work / PROGRAM.name)
    name = "collapse_nh" if nonhydrostatic else "collapse_h"
    command = [str(qcc), "-O2", *(["-DNH=1"] if nonhydrostatic else []), PROGRAM.name, "-o", name, "-lm"]
    env = {**os.environ, "BASILISK": str(qcc.parent), "PATH": f"{os.environ.get('PATH', '')}:{qcc.parent}"}
    done = subprocess.run(command, cwd=work, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        print(f"basilisk_collapse.py: {' '.join(command)} failed:\n{done.stderr}", file=sys.stderr)
        sys.exit(2)
    return work / name


def run_basilisk(executable: Path, args: argparse.Namespace, work: Path) -> Series:
    """One run of collapse.c; its stdout and stderr kept in ``work`` as ``basilisk.out`` and
    ``basilisk.err`` (Basilisk warns there where the CFL limit clips a flux it cannot pass
    on to the layer above, at the front's top layer)."""
    nonhydrostatic = args.pressure == "non_hydrostatic"
    length = 1.024 if nonhydrostatic else 2.08
    cells = round(length / (args.dx_mm * 1e-3))
    command = [
        str(executable),
        f"shape={args.shape}",
        f"cells={cells}",
        f"layers={args.layers}",
        f"cfl={args.cfl}",
    ]
    if args.dt_max is not None:
        command.append(f"dtmax={args.dt_max}")
    if args.tolerance is not None:
        command.append(f"tolerance={args.tolerance}")
    done = subprocess.run(command, cwd=work, capture_output=True, text=True)
    (work / "basilisk.out").write_text(done.stdout)
    (work / "basilisk.err").write_text(done.stderr)
    lines = done.stderr.splitlines()
    summary = [line for line in lines if line.startswith("collapse")]
    print("\n".join(summary), file=sys.stderr)
    if len(lines) > len(summary):
        print(f"({len(lines) - len(summary)} more lines of Basilisk's warnings on stderr)", file=sys.stderr)
    if done.returncode != 0:
        print(
            f"basilisk_collapse.py: {' '.join(command)} failed (exit status {done.returncode})",
            file=sys.stderr,
        )
        sys.exit(1)
    return parse_output(done.stdout)


def mound_points() -> list[list[float]]:
    """H0 cos^2(pi x/(4 L0)) on [0, 2 L0] at :data:`MOUND_POINTS` points."""
    x = np.linspace(0.0, 2.0 * L_COLUMN, MOUND_POINTS)
    h = H_COLUMN * np.cos(np.pi * x / (4.0 * L_COLUMN)) ** 2
    h[-1] = 0.0
    return [[float(a), float(b)] for a, b in zip(x, h, strict=True)]


def scenario(args: argparse.Namespace) -> dict[str, Any]:
    """scenarios/column_collapse_channel.yaml without its side walls, with Jop's mu(I), the
    column of a = 7 (or the mound), the mesh and the pressure of ``args``."""
    data = yaml.safe_load(SCENARIO.read_text())
    for key in ("walls", "expect", "output"):
        data.pop(key, None)
    data["domain"].pop("width", None)
    data["rheology"] = dict(JOP)
    length = 1.04 if args.pressure == "non_hydrostatic" else 2.08
    data["domain"].update(x_max=length, cells=round(length / (args.dx_mm * 1e-3)), layers=args.layers)
    if args.shape == "mound":
        data["initial"] = [{"shape": "profile", "points": mound_points()}]
    else:
        data["initial"][0]["height"] = H_COLUMN
    data["time"] = {"end": END, "output_interval": OUTPUT_INTERVAL, "cfl": args.time_cfl}
    data["model"] = {"pressure": args.pressure}
    if args.pressure == "non_hydrostatic":
        data["model"]["pressure_layers"] = args.pressure_layers or args.layers
    return data


def run_multilayer(args: argparse.Namespace, work: Path) -> Series:
    """One multilayer run, written to ``work/multilayer``."""
    ds = multilayer.run(scenario(args), work / "multilayer")
    return Series(ds["time"].values, ds["x"].values, ds["h"].values, np.abs(ds["u"].values).max(axis=1))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--basilisk", default=os.environ.get("BASILISK"), help="Basilisk's src directory")
    parser.add_argument("--shape", default="mound", choices=("mound", "rectangle"))
    parser.add_argument("--pressure", default="non_hydrostatic", choices=("non_hydrostatic", "hydrostatic"))
    parser.add_argument("--dx-mm", type=float, default=2.0, help="cell size, mm (default 2)")
    parser.add_argument("--layers", type=int, default=8)
    parser.add_argument("--code", default="both", choices=("both", "basilisk", "multilayer"))
    parser.add_argument("--cfl", type=float, default=0.5, help="Basilisk's CFL (default 0.5)")
    parser.add_argument("--dt-max", type=float, default=None, help="Basilisk's DT (s)")
    parser.add_argument("--tolerance", type=float, default=1e-5, help="Basilisk's TOLERANCE (default 1e-5)")
    parser.add_argument("--time-cfl", type=float, default=0.45, help="multilayer's time.cfl (default 0.45)")
    parser.add_argument("--pressure-layers", type=int, default=None, help="multilayer's (default: all)")
    parser.add_argument("--work", type=Path, default=None, help="keep the outputs in this directory")
    parser.add_argument("--json", action="store_true", help="print each run as a line of the record")
    args = parser.parse_args()
    codes = ("basilisk", "multilayer") if args.code == "both" else (args.code,)
    qcc = qcc_or_exit(args.basilisk) if "basilisk" in codes else None
    work = args.work or Path(tempfile.mkdtemp(prefix="basilisk-collapse-"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        for code in codes:
            if code == "basilisk":
                assert qcc is not None
                executable = build(qcc, work, args.pressure == "non_hydrostatic")
                result = measures(run_basilisk(executable, args, work))
                if args.pressure == "non_hydrostatic":
                    dt_max = 1e-3 if args.dt_max is None else args.dt_max
                    step = f"CFL {args.cfl:g} (DT {dt_max:g}), TOLERANCE {args.tolerance:g}"
                else:
                    step = f"CFL {args.cfl:g}, CFL_H {args.cfl:g}"
                    step += f" (DT {args.dt_max:g})" if args.dt_max is not None else ""
            else:
                result = measures(run_multilayer(args, work))
                step = f"time.cfl {args.time_cfl:g}"
                if args.pressure == "non_hydrostatic":
                    step += f", pressure_layers {args.pressure_layers or args.layers}"
            print(
                f"{code}: {args.shape}, {args.pressure}, {args.dx_mm:g} mm, {args.layers} layers, {step}: "
                + ", ".join(f"{k} {'-' if v is None else f'{v:.4g}'}" for k, v in result.items())
            )
            if args.json:
                record = {
                    "code": code,
                    "shape": args.shape,
                    "pressure": args.pressure,
                    "dx_mm": args.dx_mm,
                    "layers": args.layers,
                    "step": step,
                    **{k: None if v is None else rounded(k, v) for k, v in result.items()},
                }
                print(json.dumps(record))
    finally:
        if args.work is None:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
