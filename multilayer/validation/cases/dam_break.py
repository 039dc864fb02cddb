"""Dam breaks: Coulomb friction on a slope (Mangeney, Heinrich & Roche 2000) and Ritter's
solution on a horizontal frictionless bed (Ritter 1892).

Runs: ``coulomb_dam_break.yaml`` at five resolutions, as written and with
``slope_deg=0`` and a free-slip base.  Measure: the relative L1 error of h at the end time,
the comparison of the file's own ``expect:`` entry (:mod:`multilayer.app.exact_solutions`).
Criteria: first-order convergence, mass conserved to round-off, and the file's tolerance
separating its resolution from a twice coarser one (:meth:`MeshStudy.separates`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from multilayer.app import exact_solutions
from multilayer.scenario import Scenario
from multilayer.validation.markdown import met, order_column, table
from multilayer.validation.mesh_study import MeshStudy, file_comparison, file_error
from multilayer.validation.runs import Context, Results, Run

NAME = "dambreak"
SCENARIO = "coulomb_dam_break"
CELLS = (100, 200, 400, 800, 1600)
CASES = {
    "coulomb": ((), "Coulomb, theta = 30 deg, delta = 20 deg, t = 0.5 s"),
    "ritter": (
        ("slope_deg=0", "base=[{condition: free_slip}]", "time.end=0.4"),
        "Ritter (no friction, flat), t = 0.4 s",
    ),
}
"""Case -> (overrides of the file, title)."""
MIN_ORDER = 0.9
"""Smallest observed order accepted between successive resolutions: the scheme is first
order where h has kinks (the rarefaction edges, the wet/dry front), so about 1 is expected."""
MASS_ROUNDOFF = 1e-12
"""Largest relative change of the mass: nothing leaves the domain before the end time."""


def run(case: str, cells: int) -> Run:
    return Run(f"dam_{case}_{cells}", SCENARIO, (f"domain.cells={cells}", *CASES[case][0]))


@dataclass(frozen=True)
class Level:
    """One resolution of one case."""

    cells: int
    error: float
    """The relative L1 error of the file's comparison."""
    front: float
    exact_front: float
    """Where the exact h equals the front threshold: what the numerical front measures."""
    mass_error: float
    x: np.ndarray
    h: np.ndarray


def measure(ds: xr.Dataset, scenario: Scenario) -> Level:
    """The error, the fronts and the mass change of one run."""
    final = ds.isel(time=-1)
    t = float(final["time"])
    solution = exact_solutions.solution(scenario, file_comparison(scenario).exact)
    fine = np.linspace(-1.0, 2.0, 300001)
    wet = fine[np.flatnonzero(solution.field("h", fine, None, t) > ds["front"].attrs["threshold"])]
    return Level(
        cells=ds.sizes["x"],
        error=file_error(ds, scenario),
        front=float(final["front"]),
        exact_front=float(wet.max()),
        mass_error=float(final["mass"]) / float(ds["mass"][0]) - 1,
        x=ds["x"].values,
        h=final["h"].values,
    )


def levels(ctx: Context, results: Results, case: str) -> list[Level]:
    """The measured resolutions of ``case`` (failed runs left out)."""
    out = []
    for cells in CELLS:
        r = run(case, cells)
        ds = results[r.name]
        if not isinstance(ds, str):
            out.append(measure(ds, r.load(ctx.scenarios)))
    return out


def study(case_levels: list[Level]) -> MeshStudy:
    return MeshStudy(tuple(lv.cells for lv in case_levels), tuple(lv.error for lv in case_levels))


def converges(s: MeshStudy) -> bool:
    """Criterion: every observed order at least :data:`MIN_ORDER`, over all of :data:`CELLS`."""
    return len(s.sizes) == len(CELLS) and all(p >= MIN_ORDER for p in s.orders())


def conserves_mass(case_levels: list[Level]) -> bool:
    """Criterion: the mass changes by at most :data:`MASS_ROUNDOFF` (relative)."""
    return all(abs(lv.mass_error) <= MASS_ROUNDOFF for lv in case_levels)


def file_tolerance(ctx: Context) -> tuple[int, float]:
    """The shipped file's resolution and the tolerance of its comparison with the exact solution."""
    scenario = ctx.load(SCENARIO)
    return scenario.domain.cells, file_comparison(scenario).tolerance


def section(ctx: Context) -> str:
    results = ctx.execute([run(case, n) for case in CASES for n in CELLS])
    fig = Figure(figsize=(14, 3.8))
    axes = fig.subplots(1, 3)
    rows: list[list[object]] = []
    studies: dict[str, MeshStudy] = {}
    mass_ok = True
    for ax, (case, (_, title)) in zip(axes, CASES.items()):
        found = levels(ctx, results, case)
        studies[case] = study(found)
        mass_ok = mass_ok and conserves_mass(found)
        for lv, order in zip(found, order_column(studies[case].orders())):
            row = [case, lv.cells, f"{lv.error:.4f}", order, f"{lv.front:.4f}", f"{lv.exact_front:.4f}"]
            rows.append([*row, f"{lv.mass_error:.1e}"])
            if lv.cells in (400, 1600):
                ax.plot(lv.x, lv.h * 100, label=f"{lv.cells} cells")
        scenario = run(case, CELLS[0]).load(ctx.scenarios)
        xs = np.linspace(-1.0, 2.0, 3001)
        solution = exact_solutions.solution(scenario, file_comparison(scenario).exact)
        ax.plot(xs, solution.field("h", xs, None, scenario.time.end) * 100, "k--", label="exact")
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("h (cm)")
        ax.legend()
        axes[2].loglog(studies[case].sizes, studies[case].errors, "o-", label=case)
    n_ref = np.array([CELLS[0], CELLS[-1]])
    axes[2].loglog(n_ref, 0.05 * (n_ref / 100.0) ** -1, "k:", label="order 1")
    axes[2].set_xlabel("cells")
    axes[2].set_ylabel("relative L1 error of h")
    axes[2].legend()
    figure = ctx.figure(fig, "dam_break")
    orders = {case: s.orders() for case, s in studies.items()}
    ok = all(converges(s) for s in studies.values())
    cells, tolerance = file_tolerance(ctx)
    coulomb = studies["coulomb"]
    header = ["case", "cells", "rel. L1 error", "order", "front (m)", "exact front (m)", "mass error"]
    return f"""## Dam breaks: Coulomb on a slope and Ritter

Scenario `{SCENARIO}.yaml` (one layer, h0 = 0.1 m behind x0 = 0, theta = 30 deg,
Coulomb basal friction tan 20 deg) at {", ".join(map(str, CELLS))} cells over 4 m,
and the same with no friction on a horizontal plane
(`--set slope_deg=0 --set 'base=[{{condition: free_slip}}]'`, t = 0.4 s).
References: Mangeney, Heinrich & Roche (2000) and Ritter's solution (Ritter
1892).  The error is the L1 norm of h - h_exact over x > -1 m (away from the
rarefaction that leaves the back wall at x = -2 m) relative to the L1 norm of h_exact,
at the end time: the comparison of the file's `expect:` entry with `exact:`.
"Exact front" is where the exact h equals the front threshold (1 mm), the quantity the
numerical front measures.

{figure}

{table(header, rows)}

Verdict: both solutions converge; the observed orders are
{"; ".join(f"{case} {', '.join(f'{p:.2f}' for p in o)}" for case, o in orders.items())}
(criterion: at least {MIN_ORDER:g} between every pair of resolutions, since the scheme is first
order where h has kinks, at the rarefaction edges and the wet/dry front): {met(ok)}.
The front lags the exact one by a few cells' worth of numerical diffusion and the lag
shrinks with refinement.  Mass conserved to round-off (relative change at most {MASS_ROUNDOFF:g}):
{met(mass_ok)}.

**The file's reference check.**  `{SCENARIO}.yaml` ({cells} cells) requires this error to be
at most {tolerance:g}.  The tolerance rule: the error of the file's resolution passes
({coulomb.error(cells):.5f}) and the error of a twice coarser mesh fails ({coulomb.error(cells // 2):.5f}),
so any loss of accuracy worth a halving of the resolution is caught:
{met(coulomb.separates(cells, tolerance))}.
"""
