"""Regenerate the figures of README.md and docs/results.md from the shipped scenarios.

    python docs/make_figures.py [-o DIR]

Runs ``scenarios/erodible_bed_collapse.yaml`` as shipped into ``DIR`` (default
``results/make-figures``), prints the CPU and wall time it took, and draws from it, with
the functions of ``multilayer plot``:

- ``docs/figures/readme_section.png``: the X-Z section at four times (README.md);
- ``docs/figures/results_profiles.png``: u(z) at three columns (docs/results.md);
- ``docs/figures/results_front.png``: the front x_f(t) and u_f(t) (docs/results.md);
- ``docs/figures/results_force.png``: the force on the bed and the walls (docs/results.md).

The figures of docs/validation.md are drawn by ``python docs/make_validation.py``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from multilayer.app import runner
from multilayer.io import plotting
from multilayer.io.results import open_result
from multilayer.scenario import load

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures"
FLAGSHIP = ROOT / "scenarios" / "erodible_bed_collapse.yaml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, default=Path("results/make-figures"), metavar="DIR")
    args = parser.parse_args()

    scenario = load(FLAGSHIP)
    cpu = time.process_time()
    summary = runner.run(scenario, args.output, quiet=True)
    cpu = time.process_time() - cpu
    print(
        f"{FLAGSHIP.name}: {cpu:.1f} s CPU, {summary['wall_time_s']:.1f} s wall, {summary['steps']} steps "
        "(numba compilation included on a first run)"
    )
    ds = open_result(args.output)
    figures = {
        "readme_section.png": plotting.section_figure(ds, scenario.name, times=4),
        "results_profiles.png": plotting.profiles_figure(
            ds, scenario.name, plotting.representative_columns(ds), times=6
        ),
        "results_front.png": plotting.front_figure(ds, scenario.name),
        "results_force.png": plotting.force_figure(ds, scenario.name),
    }
    for name, fig in figures.items():
        fig.savefig(FIGURES / name, dpi=100)
        print(FIGURES / name)


if __name__ == "__main__":
    main()
