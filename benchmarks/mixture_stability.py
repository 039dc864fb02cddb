"""Benchmark: the dispersion relation of the one-layer mixture about the loose deposit of
the submarine collapse, and the growth rates the time loop measures against it.

Prints (model quantities only, deterministic; docs/mixture.md, "Well-posedness of the
closure"):

1. the deposit's uniform state (:func:`multilayer.reference.mixture_stability.deposit_state`,
   and the 480-cell body, 14.9 mm at 0.560): its slope, pore pressure, stress slope;
2. ``max Re lambda`` against ``k`` from 0.1 to 1e9 1/m for the closure, a relaxing pore
   pressure (``alpha`` = 5e-8, 5e-6, 5e-5 1/Pa), the lateral drainage and an in-plane
   viscosity the model does not have;
3. the cut-off wavenumber and wavelength against ``alpha`` (5e-9 to 5e-4 1/Pa), the
   drainage and ``nu``;
4. with ``--runs``: the growth rates of periodic time-loop runs, 8, 16 and 32 cells per
   wavelength (closure: 20, 2 and 0.5 mm, steps of 2.5 us; ``alpha = 5e-6``: 50 and
   20 mm, steps of 25 us), against the dispersion relation (a few minutes on one core).

    python benchmarks/mixture_stability.py [--runs]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from multilayer.engine.mixture.closure import darcy_coefficient
from multilayer.reference.mixture_stability import (
    RONDON_2011_BEADS,
    UniformMixture,
    cutoff,
    deposit_state,
    measured_growth,
    stress_slope,
)

WAVENUMBERS = np.geomspace(0.1, 1e9, 11)
RUNS = [
    (0.0, 0.02, 2.5e-6),
    (0.0, 0.002, 2.5e-6),
    (0.0, 0.0005, 2.5e-6),
    (5e-6, 0.05, 2.5e-5),
    (5e-6, 0.02, 2.5e-5),
]
"""``(alpha, wavelength, dt)`` of the time-loop runs (tests/test_mixture_stability.py, slow)."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", action="store_true", help="also measure growth rates on the time loop")
    args = parser.parse_args()
    states = {
        "16 mm, 0.552": deposit_state(),
        "14.9 mm, 0.560": UniformMixture(RONDON_2011_BEADS, 0.0149, 0.560, 2e-4),
    }
    for name, state in states.items():
        theta = state.slope
        P = state.weight(state.h, state.phi, theta)
        B = darcy_coefficient(RONDON_2011_BEADS.drag(state.phi), state.h, state.phi)
        slope, viscous = stress_slope(state)
        print(
            f"{name}, u = {state.u * 1e3:.2f} mm/s: tan(theta) = {math.tan(theta):.4f}, "
            f"p_e / P = {state.base[3] / P:.3f}, d tau / d gamma = {slope:.1f} Pa s "
            f"(viscous {viscous:.2f}), c = {state.wave_speed():.4f} m/s, B = {B:.4g} Pa s, "
            f"short-wave limit {state.short_wave_limit():.1f} 1/s"
        )
        print("  k (1/m):      " + " ".join(f"{k:9.2g}" for k in WAVENUMBERS))
        curves: list[tuple[str, dict[str, float]]] = [
            ("closure", {}),
            ("alpha 5e-8", {"alpha": 5e-8}),
            ("alpha 5e-6", {"alpha": 5e-6}),
            ("alpha 5e-5", {"alpha": 5e-5}),
            ("drainage", {"drainage": True}),
            ("nu 1e-4", {"nu": 1e-4}),
        ]
        for label, changes in curves:
            rates = state.with_(**changes).growth(WAVENUMBERS)
            print(f"  {label:13s} " + " ".join(f"{g:9.3g}" for g in rates))
        print("  cut-off:")
        varied_by: list[tuple[str, dict[str, float]]] = [
            *((f"alpha {a:g}", {"alpha": a}) for a in (5e-9, 5e-8, 5e-7, 5e-6, 5e-5, 5e-4)),
            ("drainage", {"drainage": True}),
            *((f"nu {n:g}", {"nu": n}) for n in (1e-6, 1e-5, 1e-4, 1e-3)),
        ]
        for label, changes in varied_by:
            varied = state.with_(**changes)
            k_c = cutoff(varied)
            t_ig = varied.alpha * B
            print(
                f"    {label:12s} long-wave rate {varied.growth(1e-2)[0]:8.4g} 1/s, k_c = {k_c:9.4g} 1/m, "
                f"lambda_c = {2e3 * math.pi / k_c:7.3g} mm" + (f", t_IG = {t_ig:.3g} s" if t_ig else "")
            )
    if args.runs:
        print("time loop, periodic, one wavelength (measured / predicted 1/s, cells per wavelength):")
        for alpha, wavelength, dt in RUNS:
            for cells in (8, 16, 32):
                m = measured_growth(deposit_state(alpha), wavelength, cells, dt)
                print(
                    f"  alpha {alpha:g}, {wavelength * 1e3:g} mm, {cells} cells, dt {dt:g} s: "
                    f"{m.rate:.1f} / {m.predicted:.1f} ({(m.rate / m.predicted - 1) * 100:+.2f} %), "
                    f"{m.steps} steps, uniform run drifted {m.drift:.1e}"
                )


if __name__ == "__main__":
    main()
