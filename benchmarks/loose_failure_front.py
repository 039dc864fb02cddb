"""Benchmark: the failure front that sets the loose submarine deposit moving again.

Reads the ``result.nc`` of a run of ``scenarios/submarine_collapse_loose.yaml`` (e.g.
``multilayer run scenarios/submarine_collapse_loose.yaml --set domain.cells=480 --set
time.end=10 --set output.directory=results/loose-480``) and prints, at every ``--every``-th
output time, the moving part of the deposit (``u != 0``): its extent, its fastest speed and
the median of its basal excess pore pressure over the buoyant weight of its grains, ``P``.

Then the failure fronts (``multilayer.validation.cases.submarine_collapse.failure_fronts``:
the upstream edge of the moving zone running upstream, the deposit set moving column after
column) with their speed against that of the long waves ``sqrt(g' h)``; and, for the mean
packing and thickness of the deposit at the end, the basal stress of the closure
(docs/mixture.md) at rest and its least value over the speeds, in units of ``P``: the
friction the deposit keeps at rest and the one left once it moves.

Deterministic (model quantities only):

    python benchmarks/loose_failure_front.py results/loose-480 [--every 2] [--from 1.0]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import xarray as xr
import yaml

from multilayer.engine.mixture.closure import MixtureMaterial, basal_closure
from multilayer.validation.cases.submarine_collapse import closure_material, failure_fronts


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("run", type=Path, help="output directory of the run (holds result.nc)")
    parser.add_argument("--every", type=int, default=2, help="print every n-th output time")
    parser.add_argument("--from", dest="start", type=float, default=1.0, help="s: first time shown")
    args = parser.parse_args()
    ds = xr.open_dataset(args.run / "result.nc")
    data = yaml.safe_load(ds.attrs["scenario"])
    rho_s, rho_f = data["material"]["particle_density"], data["fluid"]["density"]
    g = data["gravity"] * math.cos(math.radians(data["slope_deg"]))
    t, x = ds["time"].values, ds["x"].values
    h, phi = ds["h"].values, ds["phi"].values
    u = ds["u"].values[:, 0, :]
    weight = (rho_s - rho_f) * g * phi * h
    ratio = np.divide(ds["pore_pressure_excess"].values, weight, out=np.zeros_like(h), where=weight > 0.0)
    for i in range(t.size):
        if t[i] < args.start or i % args.every:
            continue
        moving = np.flatnonzero(u[i] != 0.0)
        if moving.size == 0:
            print(f"t {t[i]:5.2f} s: at rest")
            continue
        print(
            f"t {t[i]:5.2f} s: moving {x[moving[0]] * 100:5.1f} to {x[moving[-1]] * 100:5.1f} cm "
            f"({moving.size} columns), fastest {np.abs(u[i, moving]).max() * 1e3:6.2f} mm/s, "
            f"p_e / P {np.median(ratio[i, moving]):.2f}"
        )
    print("failure fronts (the upstream edge of the moving zone running upstream):")
    for begin, end, speed, wave, edge in failure_fronts(ds):
        print(
            f"  {begin:.2f} to {end:.2f} s, to {edge * 100:.1f} cm: {speed:.3f} m/s, "
            f"sqrt(g' h) {wave:.3f} m/s"
        )
    wet = h[-1] > 5e-3
    packing = float(np.average(phi[-1, wet], weights=h[-1, wet]))
    friction(closure_material(ds), packing, float(h[-1, wet].mean()), g)


def friction(mat: MixtureMaterial, phi: float, h: float, g: float) -> None:
    """Print the closure's basal stress at rest and its least value over the speeds."""
    P = (mat.rho_s - mat.rho_f) * g * phi * h
    speeds = np.logspace(-7, 0, 1401)
    stress = np.array([basal_closure(mat, phi * h, P, h, float(v)).tau_b for v in speeds])
    k = int(np.argmin(stress))
    weak = speeds[np.argmax(stress < 0.5 * stress[0])]
    B = 0.5 * mat.drag(phi) * h * h / (1.0 - phi) ** 2
    print(
        f"closure (uniform layer, gamma = 3 |v| / h) at phi {phi:.4f}, h {h * 1e3:.1f} mm: basal stress / P "
        f"{stress[0] / P:.3f} at rest, half of it from {weak * 1e3:.2f} mm/s, least {stress[k] / P:.4f} "
        f"at {speeds[k] * 1e3:.2f} mm/s; consolidation time (phi_c - phi) B / (phi P) "
        f"{(mat.phi_c - phi) * B / (phi * P):.1f} s"
    )


if __name__ == "__main__":
    main()
