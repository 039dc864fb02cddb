"""Read the numbers of ``multilayer/validation/data/pailha2008_onsets.csv`` and
``pailha2008_speeds.csv`` off a local copy of the digitisation of Pailha, Nicolas & Pouliquen
(2008)'s curves they come from (SedFoam's tutorials/Py/DATA/ExperimentalDataPailha2008/,
GPL-3.0, not shipped; ``data/sources.yaml`` gives its units: s, mm/s, Pa).

For each initial fraction of the validation case, from ``v_t_exp_<fraction>.txt`` and
``p_t_exp_<fraction>.txt`` (tab-separated, a header row ``time velocity`` or ``time
pressure``): the first and last times of each record, the onset (the first time the velocity
reaches the case's onset speed, interpolated linearly between the points, the record's first
time if it starts above: ``onset_time``, as for the model), the velocity interpolated at the
fixed times the record reaches, and the point of largest pore-pressure magnitude.  Prints the
two tables in the data files' format, to compare with them:

    python benchmarks/pailha2008_readings.py PATH/TO/ExperimentalDataPailha2008
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from multilayer.engine.mixture.uniform_layer import onset_time
from multilayer.validation.cases.immersed_layer import ONSET_SPEED, PHI0S

SPEED_TIMES = (10.0, 100.0, 300.0)
"""s: the fixed times of the velocity readings."""


def record(path: Path, column: str) -> tuple[np.ndarray, np.ndarray]:
    """Time and ``column`` of one digitised curve, in time order."""
    data = np.genfromtxt(path, delimiter="\t", names=True)
    t, y = np.asarray(data["time"], dtype=float), np.asarray(data[column], dtype=float)
    if t.size < 2 or not np.all(np.diff(t) > 0.0) or not np.all(np.isfinite(y)):
        raise ValueError(f"{path}: expected at least two points in increasing time")
    return t, y


def readings(directory: Path) -> tuple[list[str], list[str]]:
    """The rows of the onsets table and of the speeds table (CSV, header first)."""
    onsets = [
        "phi0 (-),v first (s),v last (s),onset (s),p first (s),p last (s),p extreme (Pa),p extreme at (s)"
    ]
    speeds = ["phi0 (-),t (s),v (mm/s)"]
    for phi0 in PHI0S:
        name = f"{round(phi0 * 1000)}.txt"
        t, v = record(directory / f"v_t_exp_{name}", "velocity")
        tp, p = record(directory / f"p_t_exp_{name}", "pressure")
        onset = onset_time(t, v, ONSET_SPEED * 1e3)
        k = int(np.argmax(np.abs(p)))
        onsets.append(
            f"{phi0:g},{t[0]:.2f},{t[-1]:.2f},{onset:.2f},{tp[0]:.2f},{tp[-1]:.2f},{p[k]:.2f},{tp[k]:.2f}"
        )
        speeds += [f"{phi0:g},{s:g},{np.interp(s, t, v):.4f}" for s in SPEED_TIMES if t[0] <= s <= t[-1]]
    return onsets, speeds


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("directory", type=Path, help="the directory of v_t_exp_*.txt and p_t_exp_*.txt")
    args = parser.parse_args(argv)
    try:
        onsets, speeds = readings(args.directory)
    except (OSError, ValueError) as exc:
        print(f"pailha2008_readings: {exc}", file=sys.stderr)
        return 2
    print("\n".join(onsets))
    print()
    print("\n".join(speeds))
    return 0


if __name__ == "__main__":
    sys.exit(main())
