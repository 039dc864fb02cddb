"""Benchmark: the uniform immersed layers of Pailha et al. (2008) with a relaxing excess pore
pressure (the skeleton's compressibility ``alpha``, George & Iverson 2014), against the
closure of Bouchut et al. (2016) (``alpha`` absent).

For the loose (``phi0 = 0.562``) and dense (``0.592``) layers in the viscous fluid and each
``alpha``, prints the relaxation time ``t_IG = alpha B`` at the start, the onset (first time
at 0.1 mm/s), the basal excess pore pressure at the end and its extreme value, from
backward-Euler steps (:meth:`UniformLayer.step`) of 1 % of the time reached (at least
0.1 us, at most 0.5 s).  Deterministic (model quantities only):

    python benchmarks/immersed_compressibility.py
"""

from __future__ import annotations

import argparse

import numpy as np

from multilayer.engine.mixture.uniform_layer import UniformLayer, onset_time
from multilayer.reference.immersed_layer import pailha_2008_layer

ALPHAS = (None, 5e-10, 5e-8, 5e-6, 5e-5)
"""1/Pa: the closure, then Bouchut et al. (2016)'s two values and the range between."""
CASES = {0.562: 5.0, 0.592: 500.0}
"""phi0 -> end of the run (s)."""
ONSET = 1e-4
"""m/s: the speed that marks the onset."""


def main() -> None:
    argparse.ArgumentParser(description=__doc__.split("\n\n")[0]).parse_args()
    print("| phi0 | alpha (1/Pa) | t_IG (s) | onset, 0.1 mm/s (s) | p_e, end (Pa) | extreme p_e (Pa) |")
    print("| --- | --- | --- | --- | --- | --- |")
    for phi0, t_end in CASES.items():
        for alpha in ALPHAS:
            layer = pailha_2008_layer(phi0, compressibility=alpha)
            times, v, p_e = _run(layer, t_end)
            extreme = p_e[int(np.argmax(np.abs(p_e)))]
            print(
                f"| {phi0:g} | {'closure' if alpha is None else f'{alpha:g}'} | "
                f"{layer.relaxation_time(layer.h0):.3g} | {onset_time(times, v, ONSET):.4g} | "
                f"{p_e[-1]:+.3f} | {extreme:+.3f} |"
            )


def _run(layer: UniformLayer, t_end: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times, solid velocities and basal excess pore pressures of a run with steps of 1 %."""
    s = layer.initial_state()
    rows = [(s.t, s.v, layer.state_closure(s).p_e)]
    while s.t < t_end:
        s = layer.step(s, min(max(1e-7, 0.01 * s.t), 0.5, t_end - s.t))
        rows.append((s.t, s.v, layer.state_closure(s).p_e))
    t, v, p_e = (np.array(column) for column in zip(*rows, strict=True))
    return t, v, p_e


if __name__ == "__main__":
    main()
