"""Bagnold profile: steady uniform mu(I) flow down a rough chute (GDR MiDi 2004; Tsang,
Dalziel & Vriend 2019, eq. 4.1).

Runs: ``bagnold_chute.yaml`` with 5 to 80 uniform layers.  Measures: the file's own
comparison with the exact solution (the largest layer-velocity error against Bagnold's
profile averaged over each layer, relative to the largest exact layer mean), the error of
the depth-mean velocity, and the steadiness.  Criteria: the layer error converges at an
order of at least :data:`MIN_ORDER` and is below :data:`MAX_ERROR` at the finest
resolution; the file's tolerance separates its resolution from a twice coarser one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from multilayer.app import exact_solutions, factory
from multilayer.reference import exact
from multilayer.validation.markdown import met, order_column, table
from multilayer.validation.mesh_study import MeshStudy, file_comparison, file_error
from multilayer.validation.runs import Context, Results, Run

NAME = "bagnold"
SCENARIO = "bagnold_chute"
LAYERS = (5, 10, 20, 40, 80)
MIN_ORDER = 1.3
"""Smallest observed order of the layer error: the (h - z)^(3/2) term of the profile has
an unbounded curvature at the surface, which caps the order of the layer discretisation
near 3/2 (second order elsewhere)."""
MAX_ERROR = 0.02
"""Largest layer error at the finest resolution, relative to the largest exact layer mean."""


def run(layers: int) -> Run:
    return Run(f"bagnold_{layers}", SCENARIO, (f"domain.layers={layers}",))


def flow(ctx: Context) -> exact.BagnoldFlow:
    """Bagnold's flow of the file (layers do not change it)."""
    return exact_solutions.Bagnold(ctx.load(SCENARIO)).flow


@dataclass(frozen=True)
class Level:
    """One resolution."""

    layers: int
    error: float
    """The file's comparison: the largest layer error over the largest exact layer mean."""
    mean: float
    """The depth-mean velocity (m/s)."""
    change: float
    """The largest change over the last output interval, over the surface speed."""
    u: np.ndarray
    z: np.ndarray
    """Layer centres (m)."""


def measure(ds: xr.Dataset, ctx: Context, r: Run) -> Level:
    scenario = r.load(ctx.scenarios)
    h = float(ds["h"].values[-1].mean())
    fractions = ds["sigma_bnds"].values[:, 1] - ds["sigma_bnds"].values[:, 0]
    u = ds["u"].values[-1].mean(axis=1)
    surface = flow(ctx).surface_velocity
    return Level(
        layers=ds.sizes["layer"],
        error=file_error(ds, scenario),
        mean=float(np.sum(fractions * u)),
        change=float(np.abs(ds["u"].values[-1] - ds["u"].values[-2]).max() / surface),
        u=u,
        z=ds["sigma"].values * h,
    )


def levels(ctx: Context, results: Results) -> list[Level]:
    """The measured resolutions (failed runs left out)."""
    return [measure(ds, ctx, run(n)) for n in LAYERS if not isinstance(ds := results[run(n).name], str)]


def converges(levels: list[Level]) -> bool:
    """Criterion: every observed order of the layer error at least :data:`MIN_ORDER`, and
    the error at the finest resolution below :data:`MAX_ERROR`."""
    study = MeshStudy(tuple(lv.layers for lv in levels), tuple(lv.error for lv in levels))
    return len(levels) == len(LAYERS) and levels[-1].error < MAX_ERROR and min(study.orders()) >= MIN_ORDER


def section(ctx: Context) -> str:
    results = ctx.execute([run(n) for n in LAYERS])
    bagnold = flow(ctx)
    scenario = ctx.load(SCENARIO)
    params = scenario.rheology.params
    material = factory.material(scenario)
    found = levels(ctx, results)
    study = MeshStudy(tuple(lv.layers for lv in found), tuple(lv.error for lv in found))
    means = [abs(lv.mean / bagnold.mean_velocity - 1) for lv in found]
    mean_study = MeshStudy(study.sizes, tuple(means))
    rows: list[list[object]] = []
    for lv, o1, o2 in zip(found, order_column(study.orders()), order_column(mean_study.orders())):
        rows.append(
            [
                lv.layers,
                f"{lv.error:.4f}",
                o1,
                f"{lv.mean:.5f}",
                f"{lv.mean / bagnold.mean_velocity - 1:+.4f}",
                o2,
                f"{lv.change:.1e}",
            ]
        )
    fig = Figure(figsize=(10, 4))
    ax, ax2 = fig.subplots(1, 2)
    z = np.linspace(0, bagnold.depth, 400)
    ax.plot(bagnold.velocity(z), z * 1000, "k-", lw=2.5, alpha=0.4, label="Bagnold (exact)")
    for lv in found:
        if lv.layers in (5, 20, 80):
            ax.plot(lv.u, lv.z * 1000, "o" if lv.layers == 5 else ".-", label=f"{lv.layers} layers")
    ax.set_xlabel("u (m/s)")
    ax.set_ylabel("z (mm)")
    ax.legend()
    layers = [lv.layers for lv in found]
    ax2.loglog(layers, study.errors, "o-", label="max layer error (the file's comparison)")
    ax2.loglog(layers, means, "s-", label="depth-mean error")
    ref = np.array([layers[0], layers[-1]], dtype=float)
    ax2.loglog(ref, study.errors[0] * (ref / ref[0]) ** -1, "k:", label="order 1")
    ax2.loglog(ref, study.errors[0] * (ref / ref[0]) ** -2, "k--", label="order 2")
    ax2.set_xticks(layers, [str(n) for n in layers])
    ax2.minorticks_off()
    ax2.set_xlabel("layers")
    ax2.legend()
    figure = ctx.figure(fig, "bagnold")
    tolerance = file_comparison(scenario).tolerance
    n_file = scenario.domain.layers
    ratio = material.density / material.particle_density
    header = [
        "layers",
        "max layer error / max exact layer mean",
        "order",
        "depth-mean u (m/s)",
        "mean error",
        "order",
        "last change / u_s",
    ]
    return f"""## Bagnold profile (steady uniform mu(I) chute flow)

Scenario `{SCENARIO}.yaml`: a 1 cm layer of the erodible-bed experiments' glass beads (Jop
mu(I), mu_s = tan 25.5 deg, mu_2 = tan 36 deg, I_0 = {params["I_0"]:g}, rho/rho_p = {ratio:.2f})
released from rest on a 28 deg no-slip chute, periodic in x, run to t = {scenario.time.end:g} s;
{", ".join(map(str, LAYERS))} uniform layers (`--set domain.layers=N`).  Reference: Bagnold profile
(Tsang et al. 2019, eq. 4.1), I_theta = {bagnold.inertial_number:.5f}, surface speed
{bagnold.surface_velocity:.4f} m/s, depth-mean {bagnold.mean_velocity:.5f} m/s.  Each layer velocity
is compared with the exact average over that layer; the largest difference, relative to the
largest exact layer mean, is the comparison of the file's `expect:` entry with `exact:`.
"Last change" is the largest change over the last output interval (steadiness).

{figure}

{table(header, rows)}

Verdict: the computed profile converges to Bagnold's at an order of at least {MIN_ORDER:g}
(the (h - z)^(3/2) term of the profile has an unbounded curvature at the surface, which
caps the order near 3/2) with a layer error below {MAX_ERROR:.0%} at {LAYERS[-1]} layers:
{met(converges(found))}.

**The file's reference check.**  `{SCENARIO}.yaml` ({n_file} layers) requires this error to be at
most {tolerance:g}: the error of its resolution passes ({study.error(n_file):.5f}) and the error
of a twice coarser column fails ({study.error(n_file // 2):.5f}): {met(study.separates(n_file, tolerance))}.
"""
