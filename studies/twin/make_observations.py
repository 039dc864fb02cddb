"""Write the twin experiment's observations: collapse.yaml run with known mu_s and mu_2,
its front x_f(t) and final deposit h(x) measured (multilayer.io.observables), perturbed by
Gaussian noise of standard deviation NOISE mm, into front.csv and deposit.csv (mm).

Usage: python make_observations.py [NOISE_MM] [SEED] [OUTDIR]   (defaults 1.0, 1, this directory)
"""

from __future__ import annotations

import csv
import sys
import tempfile
from pathlib import Path

import numpy as np

from multilayer import scenario
from multilayer.app import runner
from multilayer.io.observables import Measure

HERE = Path(__file__).resolve().parent
TRUE = {"rheology.mu_s": 0.4770, "rheology.mu_2": 0.7265}
TIMES = (0.05, 0.1, 0.15, 0.2, 0.25, 0.3)
XS = tuple(np.round(np.arange(0.01, 0.16, 0.015), 4))


def write(noise_mm: float, seed: int, outdir: Path) -> None:
    """Run the truth, measure, add noise, write the two CSV files."""
    truth = scenario.load(HERE / "collapse.yaml", [f"{k}={v}" for k, v in TRUE.items()])
    with tempfile.TemporaryDirectory() as run_dir:
        runner.run(truth, run_dir, quiet=True)
        exact = Measure((("front", TIMES, None), ("h", XS, None)))(Path(run_dir) / "result.nc")
    rng = np.random.default_rng(seed)
    noisy = exact * 1e3 + noise_mm * rng.standard_normal(exact.size)  # mm
    outdir.mkdir(parents=True, exist_ok=True)
    for name, header, coords, values in (
        ("front.csv", ("t", "x_f", "sigma"), TIMES, noisy[: len(TIMES)]),
        ("deposit.csv", ("x", "h", "sigma"), XS, noisy[len(TIMES) :]),
    ):
        with (outdir / name).open("w", newline="") as stream:
            out = csv.writer(stream)
            out.writerow(header)
            out.writerows((c, f"{v:.4f}", noise_mm) for c, v in zip(coords, values))


if __name__ == "__main__":
    args = sys.argv[1:]
    write(
        float(args[0]) if args else 1.0,
        int(args[1]) if len(args) > 1 else 1,
        Path(args[2]) if len(args) > 2 else HERE,
    )
