"""Benchmark: how far the loose submarine deposit compacts, and what limits it.

Reads the ``result.nc`` of runs of ``scenarios/submarine_collapse_loose.yaml`` (e.g.
``multilayer run scenarios/submarine_collapse_loose.yaml --set domain.cells=480 --set
time.end=10 --set output.directory=results/loose-480``) and prints, for each:

1. the change of the mixture volume against the Darcy outflow, ``-int sum h p_e / B dx dt``
   (trapezoids between output times, ``B = beta h^2 / (2 (1 - phi)^2)``): the fluid that
   leaves a column must flow out through its pores.  The closure ``p_e = -B Phi`` makes the
   two equal, and so does ``fluid.compressibility`` in one layer, whose step changes the
   thickness by that outflow (George & Iverson 2014); in several layers the thickness
   follows the dilatancy ``Phi`` while the pore pressures relax, and the difference is the
   skeleton's elastic volume change, ``alpha d_t p_e`` (docs/mixture.md).
2. the body of the deposit (the columns thicker than 5 mm at every output time from
   ``--from`` on): its packing, the shear strain it has undergone since then,
   ``int 2 |u| / h dt`` (the local step's shear rate; median and largest over the columns),
   the packing a drained packing would reach with that strain (the dilatancy law at
   ``phi_eq = phi_c``, ``d phi / d strain = phi K (phi_c - phi)``, Roux & Radjai 1998), the
   compaction the Darcy outflow allows, ``int phi p_e / B dt``, the share of its
   column-times that move and their median ``p_e / P``.
3. the closure's basal stress near rest at the body's final mean packing and thickness
   (the uniform layer's, ``gamma = 3 |v| / h``): its slope at ``gamma -> 0+``, analytic,

       d tau / d gamma = (K1 + K K2) eta_f - (tan(delta) + K (phi - phi_c)) B K (phi_c - phi),

   and by a finite difference of the closure.

``--uniform`` instead runs a uniform loose layer (16 mm, ``phi0 = 0.552``, on 17 degrees,
the grains and fluid of the file) with a relaxing pore pressure and prints its packing
against the compaction its Darcy outflow allows.  Deterministic (model quantities only):

    python benchmarks/loose_compaction.py results/loose-240 results/loose-480 [--from 1.5]
    python benchmarks/loose_compaction.py --uniform
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import xarray as xr
import yaml

from multilayer.engine.mixture.closure import MixtureMaterial, basal_closure, drag
from multilayer.engine.mixture.uniform_layer import UniformLayer
from multilayer.validation.cases.submarine_collapse import BODY, closure_material

TIMES = (0.5, 1.0, 1.5, 3.0, 5.0, 10.0)
"""Output times (s) at which the volumes are printed (those the run reached)."""


def darcy_time(mat: MixtureMaterial, h: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """``B = beta h^2 / (2 (1 - phi)^2)`` (Pa s) where ``h > 0``, 1 elsewhere."""
    wet = h > 0.0
    packing = np.where(wet, phi, 0.5)
    coefficient = 0.5 * drag(mat.kozeny, mat.eta_f, mat.d, packing) / (1.0 - packing) ** 2
    return np.where(wet, coefficient * h * h, 1.0)


def cumulative(t: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """The trapezoidal integral of ``rate`` (time first) from ``t[0]`` to each output time."""
    steps = 0.5 * (rate[1:] + rate[:-1]) * np.diff(t).reshape((-1,) + (1,) * (rate.ndim - 1))
    return np.concatenate([np.zeros_like(rate[:1]), np.cumsum(steps, axis=0)])


def report(run: Path, start: float) -> None:
    """Print the three parts of the module's description for one run."""
    ds = xr.open_dataset(run / "result.nc")
    mat = closure_material(ds)
    data = yaml.safe_load(ds.attrs["scenario"])
    g = data["gravity"] * math.cos(math.radians(data["slope_deg"]))
    t, x = ds["time"].values, ds["x"].values
    dx = float(x[1] - x[0])
    h, phi, p_e = ds["h"].values, ds["phi"].values, ds["pore_pressure_excess"].values
    u = np.abs(ds["u"].values).max(axis=1)
    B = darcy_time(mat, h, phi)
    volume = h.sum(axis=1) * dx
    outflow = cumulative(t, (np.where(h > 0.0, -h * p_e / B, 0.0)).sum(axis=1) * dx)
    print(f"{run}:")
    for when in TIMES:
        if when <= t[-1] + 1e-9:
            i = int(np.searchsorted(t, when - 1e-9))
            packing = (phi[i] * h[i]).sum() / h[i].sum()
            print(
                f"  t {t[i]:5.2f} s: mean packing {packing:.4f}, volume change "
                f"{(volume[i] - volume[0]) * 1e6:8.2f} mm2, Darcy outflow {outflow[i] * 1e6:8.2f} mm2"
            )
    first = int(np.searchsorted(t, start - 1e-9))
    body = (h[first:] > BODY).all(axis=0)
    if not body.any():
        print(f"  no column thicker than {BODY * 1e3:.0f} mm from {t[first]:.2f} s on")
        return
    shear = np.divide(2.0 * u, h, out=np.zeros_like(h), where=h > 0.0)
    strain = cumulative(t[first:], shear[first:, body])[-1]
    allowed = cumulative(t[first:], (phi * p_e / B)[first:, body])[-1]
    drained = phi[first, body].copy()
    for _ in range(1000):  # d phi / d strain = phi K (phi_c - phi), explicit in 1000 steps
        drained += strain / 1000 * drained * mat.K * (mat.phi_c - drained)
    weight = (mat.rho_s - mat.rho_f) * g * phi * h
    moving = u[first:, body] > 0.0
    ratio = (p_e / np.where(weight > 0.0, weight, 1.0))[first:, body][moving]
    median = float(np.median(ratio)) if ratio.size else float("nan")
    print(
        f"  body ({body.sum()} columns thicker than {BODY * 1e3:.0f} mm from {t[first]:.2f} s): "
        f"packing {phi[first, body].mean():.4f} -> {phi[-1, body].mean():.4f} at {t[-1]:.2f} s; "
        f"strain since {t[first]:.2f} s median {np.median(strain):.2f}, largest {strain.max():.2f}; "
        f"drained packing at that strain {drained.mean():.4f}; compaction the Darcy outflow allows "
        f"{allowed.mean():+.4f} (the run's {phi[-1, body].mean() - phi[first, body].mean():+.4f}); "
        f"moving {moving.mean():.1%} of its column-times, p_e / P {median:.2f} (median)"
    )
    slope(mat, float(phi[-1, body].mean()), float(h[-1, body].mean()), g)


def slope(mat: MixtureMaterial, phi: float, h: float, g: float) -> None:
    """Print the closure's ``d tau / d gamma`` at ``gamma -> 0+``, analytic and by a difference."""
    P = (mat.rho_s - mat.rho_f) * g * phi * h
    B = float(darcy_time(mat, np.array(h), np.array(phi)))
    viscous = (mat.K1 + mat.K * mat.K2) * mat.eta_f
    weakening = mat.static_friction(phi) * B * mat.K * (mat.phi_c - phi)
    speed = 1e-9  # m/s, gamma = 3 speed / h
    tau = [basal_closure(mat, phi * h, P, h, v).tau_b for v in (0.0, speed)]
    print(
        f"  closure at phi {phi:.4f}, h {h * 1e3:.1f} mm (P {P:.1f} Pa, B {B:.0f} Pa s): d tau / d gamma "
        f"at 0+ {viscous - weakening:.1f} Pa s analytic ({viscous:.2f} viscous, -{weakening:.1f} from the "
        f"pore pressure, B K (phi_c - phi) = {B * mat.K * (mat.phi_c - phi):.0f} Pa s of p_e per 1/s), "
        f"{(tau[1] - tau[0]) / (3.0 * speed / h):.1f} Pa s by the closure"
    )


def uniform() -> None:
    """Print the uniform loose layer's packing against its Darcy outflow, closure and relaxing."""
    grains = {"rho_s": 2500.0, "d": 225e-6, "rho_f": 1010.0, "eta_f": 0.0121}  # the collapse's files
    mat = MixtureMaterial(**grains, delta_deg=22.5, phi_c=0.582, K=4.09, K1=90.5, K2=25.0)
    for alpha in (None, 5e-6, 5e-5):
        run = UniformLayer(mat, 17.0, 0.016, 0.552, compressibility=alpha).run(t_end=4.0, dt=0.002)
        allowed = cumulative(run.t, run.phi * run.p_e / darcy_time(mat, run.h, run.phi))
        for when in (0.1, 0.5, 1.0, 4.0):
            i = int(np.searchsorted(run.t, when - 1e-9))
            print(
                f"alpha {alpha or 'closure'}: t {run.t[i]:.2f} s, {run.v[i] * 1e3:.1f} mm/s, "
                f"phi {run.phi[i]:.4f} (change {run.phi[i] - run.phi[0]:+.4f}; "
                f"the Darcy outflow allows {allowed[i]:+.4f})"
            )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("runs", type=Path, nargs="*", help="output directories of runs (hold result.nc)")
    parser.add_argument("--from", dest="start", type=float, default=1.5, help="s: start of the body's record")
    parser.add_argument("--uniform", action="store_true", help="the uniform loose layer instead")
    args = parser.parse_args()
    if args.uniform:
        uniform()
    for run in args.runs:
        report(run, args.start)


if __name__ == "__main__":
    main()
