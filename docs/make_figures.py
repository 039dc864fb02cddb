"""Regenerate the figures of README.md and docs/results.md from the shipped scenarios.

    python docs/make_figures.py [-o DIR]

Runs ``scenarios/erodible_bed_collapse.yaml`` as shipped into ``DIR`` (default
``results/make-figures``), prints the CPU and wall time it took, and draws from it, with
the functions of ``multilayer plot``:

- ``docs/figures/readme_section.png``: the X-Z section at four times (README.md);
- ``docs/figures/results_profiles.png``: u(z) at three columns (docs/results.md);
- ``docs/figures/results_front.png``: the front x_f(t) and u_f(t) (docs/results.md);
- ``docs/figures/results_force.png``: the force on the bed and the walls (docs/results.md).

``python docs/make_figures.py --stability`` instead draws only
``docs/figures/mixture_stability.png``, the dispersion relation of the loose deposit
(docs/mixture.md, "Well-posedness of the closure"; no run, a second).

The figures of docs/validation.md are drawn by ``python docs/make_validation.py``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from matplotlib.figure import Figure

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
    parser.add_argument("--stability", action="store_true", help="only the mixture's dispersion relation")
    args = parser.parse_args()
    if args.stability:
        stability_figure().savefig(FIGURES / "mixture_stability.png", dpi=100)
        print(FIGURES / "mixture_stability.png")
        return

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


def stability_figure() -> Figure:
    """The growth rate ``max Re lambda`` of the loose deposit's uniform state against the
    wavenumber: the closure, a relaxing pore pressure, the lateral drainage
    (:mod:`multilayer.reference.mixture_stability`)."""
    import numpy as np

    from multilayer.reference.mixture_stability import deposit_state

    k = np.geomspace(1.0, 1e7, 200)
    fig = Figure(figsize=(7.0, 4.2))
    ax = fig.add_subplot()
    curves = [
        ("closure (the model)", {}),
        ("alpha = 5e-8 1/Pa", {"alpha": 5e-8}),
        ("alpha = 5e-6 1/Pa", {"alpha": 5e-6}),
        ("alpha = 5e-5 1/Pa", {"alpha": 5e-5}),
        ("closure + lateral drainage", {"drainage": True}),
    ]
    for label, changes in curves:
        rate = deposit_state(**changes).growth(k)
        ax.loglog(k, np.where(rate > 0.0, rate, np.nan), label=label)
    for cells in (240, 960):
        ax.axvline(np.pi * cells / 0.3, color="0.6", lw=0.8, ls=":")
        ax.text(np.pi * cells / 0.3, 3.0, f" 2 dx, {cells} cells", color="0.4", fontsize=8, rotation=90)
    ax.set_xlabel("wavenumber k (1/m)")
    ax.set_ylabel("growth rate max Re lambda (1/s)")
    ax.set_ylim(1.0, 5e3)
    ax.set_title("loose deposit, 16 mm at 0.552, sliding at 0.2 mm/s (decaying: not drawn)", fontsize=9)
    ax.legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    return fig


if __name__ == "__main__":
    main()
