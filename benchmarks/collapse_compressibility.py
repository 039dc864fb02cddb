"""Benchmark: the submarine collapses with a relaxing basal excess pore pressure.

Reads the ``result.nc`` of runs of ``scenarios/submarine_collapse_{loose,dense}.yaml`` with
``--set fluid.compressibility=...`` (docs/mixture.md, "A pore pressure with its own
evolution"), e.g.

    multilayer run scenarios/submarine_collapse_loose.yaml --set domain.cells=120 \\
        --set time.end=10 --set fluid.compressibility=5e-5 --set output.directory=results/l120

and prints, for each, the measures of the validation case ``submarine_collapse``
(:func:`multilayer.validation.cases.submarine_collapse.measure`): run-out, stop time, the
times to 95 % of the run-out and of the centre of mass's displacement, the extreme basal
excess pore pressure under the initial column, and the failure fronts (their number, and
for each its start and its speed over the long-wave speed ``sqrt(g' h)``).
Deterministic (model quantities only):

    python benchmarks/collapse_compressibility.py results/l120 [more result directories]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import xarray as xr
import yaml

from multilayer.validation.cases.submarine_collapse import durations, measure


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("directories", nargs="+", type=Path, help="output directories holding result.nc")
    args = parser.parse_args()
    print(
        "| run | cells | alpha (1/Pa) | run-out / stop / t95 / t95 mass | extreme p_e (Pa) | failure fronts |"
    )
    print("| --- | --- | --- | --- | --- | --- |")
    for directory in args.directories:
        with xr.open_dataset(directory / "result.nc") as ds:
            data = yaml.safe_load(ds.attrs["scenario"])
            q = measure(ds)
            alpha = data["fluid"].get("compressibility", "closure")
            print(
                f"| {data['name']} | {data['domain']['cells']} | {alpha} | "
                f"{durations(q)} | {q['pressure']:+.0f} | {len(q['fronts'])}"
                + "".join(f", {f[0]:.2f} s ({f[2] / f[3]:.2f})" for f in q["fronts"])
                + " |"
            )


if __name__ == "__main__":
    main()
