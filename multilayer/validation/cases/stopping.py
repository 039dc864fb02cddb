"""Stopping thickness and flow rule of the ``pouliquen_forterre`` law on a rough incline
(Pouliquen 1999; Forterre & Pouliquen 2003; Jop, Forterre & Pouliquen 2005, appendix A).

Runs: ``bagnold_chute.yaml`` (a periodic uniform layer on a no-slip base) with the
glass-bead law of ``glass_bead_stopping.yaml`` (d = 0.5 mm, rho / rho_p = 0.6, I_0 from
beta).  Measures: the largest speed of layers 0.1 % thinner and thicker than
h_stop(theta) started from rest; the Froude number of the steady flow at h / h_stop = 1.2,
2 and 5 with 8, 16 and 32 layers.  Criteria: every thinner layer exactly at rest (u == 0.0
at every output), every thicker one flowing; the Froude number's error against
``beta h / h_stop`` converging at an observed order of at least :data:`MIN_ORDER` and below
:data:`MAX_ERROR` at 32 layers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from multilayer.reference.exact import pouliquen_beta, pouliquen_h_stop
from multilayer.validation import published
from multilayer.validation.markdown import met, order_column, table
from multilayer.validation.mesh_study import MeshStudy
from multilayer.validation.runs import Context, Results, Run

NAME = "stopping"
SCENARIO = "bagnold_chute"
DATA = "glass_bead_stopping.yaml"
GRAIN, GRAIN_DENSITY, PACKING = 0.5e-3, 2500.0, 0.6
"""Glass beads of 0.5 mm at a packing of 0.6 (the diameter is an assumption: the source
does not state the one that goes with L)."""
REST_SLOPES = (22.0, 25.0, 28.0)
FLOW_SLOPES = (25.0, 28.0)
RATIOS = (1.2, 2.0, 5.0)
LAYERS = (8, 16, 32)
MIN_ORDER = 1.8
"""Smallest observed order of the Froude error (the midpoint layers of a smooth profile)."""
MAX_ERROR = 1e-3
"""Largest relative Froude error at 32 layers."""
END = 6.0
"""Simulated time of a flow run (s): several relaxation times of the steady flow."""


@dataclass(frozen=True)
class Law:
    """A ``pouliquen_forterre`` law: friction coefficients, L (m), beta, the grains' diameter
    (m) and packing, the start friction's constant (None: no hysteresis), and I_0 from beta."""

    mu_1: float
    mu_2: float
    L: float
    beta: float
    grain: float = GRAIN
    packing: float = PACKING
    mu_3: float | None = None

    @property
    def I_0(self) -> float:
        """``I_0 = 5 beta d / (2 L sqrt(phi))`` (Jop et al. 2005, appendix A)."""
        return 5.0 * self.beta * self.grain / (2.0 * self.L * math.sqrt(self.packing))

    def h_stop(self, theta: float) -> float:
        return pouliquen_h_stop(theta, self.mu_1, self.mu_2, self.L)

    def rheology(self) -> str:
        """The law as the value of a ``--set rheology=`` override."""
        start = "" if self.mu_3 is None else f", mu_3: {self.mu_3!r}"
        return (
            f"{{name: pouliquen_forterre, mu_1: {self.mu_1!r}, mu_2: {self.mu_2!r}, L: {self.L!r}, "
            f"I_0: {self.I_0!r}{start}}}"
        )


def law() -> Law:
    v = published.values(DATA)
    return Law(math.tan(math.radians(v["delta_1"])), math.tan(math.radians(v["delta_2"])), v["L"], v["beta"])


def source_text() -> str:
    """The citation of the glass-bead constants."""
    return published.source(DATA).cite()


def run(name: str, theta: float, h: float, layers: int, end: float) -> Run:
    rheology = law().rheology()
    material = (
        f"{{density: {PACKING * GRAIN_DENSITY!r}, grain_diameter: {GRAIN!r}, "
        f"particle_density: {GRAIN_DENSITY!r}}}"
    )
    return Run(
        name,
        SCENARIO,
        (
            f"slope_deg={theta!r}",
            f"material={material}",
            f"rheology={rheology}",
            f"initial=[{{shape: layer, thickness: {h!r}}}]",
            f"domain.layers={layers}",
            f"time.end={end!r}",
            f"time.output_interval={end / 10!r}",
        ),
    )


def rest_runs() -> list[Run]:
    g = law()
    return [
        run(f"stopping_rest_{theta:g}_{side}", theta, factor * g.h_stop(theta), 8, 1.0)
        for theta in REST_SLOPES
        for side, factor in (("below", 0.999), ("above", 1.001))
    ]


def flow_run(theta: float, ratio: float, layers: int) -> Run:
    return run(f"stopping_flow_{theta:g}_{ratio:g}_{layers}", theta, ratio * law().h_stop(theta), layers, END)


def flow_runs() -> list[Run]:
    return [flow_run(t, r, n) for t in FLOW_SLOPES for r in RATIOS for n in LAYERS]


def largest_speed(results: Results, r: Run) -> float:
    """max |u| over every output of the run (nan if it failed)."""
    ds = results[r.name]
    return math.nan if isinstance(ds, str) else float(np.abs(ds["u"].values).max())


@dataclass(frozen=True)
class Flow:
    """The last output of a flow run: Froude number and the last change over the surface speed."""

    froude: float
    change: float


def flow(results: Results, theta: float, ratio: float, layers: int) -> Flow | None:
    ds = results[flow_run(theta, ratio, layers).name]
    if isinstance(ds, str):
        return None
    fractions = ds["sigma_bnds"].values[:, 1] - ds["sigma_bnds"].values[:, 0]
    u = ds["u"].values[-1].mean(axis=1)
    h = float(ds["h"].values[-1].mean())
    change = float(np.abs(ds["u"].values[-1] - ds["u"].values[-2]).max() / abs(u[-1]))
    return Flow(float(fractions @ u) / math.sqrt(9.81 * h * math.cos(math.radians(theta))), change)


def rest_met(results: Results) -> bool:
    """Criterion: every thinner layer exactly at rest, every thicker one flowing."""
    speeds = {r.name: largest_speed(results, r) for r in rest_runs()}
    return all((speeds[n] == 0.0) if n.endswith("below") else (speeds[n] > 0.0) for n in speeds)


def flow_rule_met(results: Results) -> bool:
    """Criterion: every Froude error converges at an order of at least :data:`MIN_ORDER`
    and is below :data:`MAX_ERROR` at the finest resolution."""
    beta = law().beta
    for theta in FLOW_SLOPES:
        for ratio in RATIOS:
            found = [flow(results, theta, ratio, n) for n in LAYERS]
            if any(f is None for f in found):
                return False
            errors = tuple(abs(f.froude / (beta * ratio) - 1) for f in found if f is not None)
            if errors[-1] >= MAX_ERROR or min(MeshStudy(LAYERS, errors).orders()) < MIN_ORDER:
                return False
    return True


FLOW_HEADER = [
    "theta (deg)",
    "h / h_stop",
    "layers",
    "Fr",
    "Fr / (beta h/h_stop) - 1",
    "order",
    "last change",
]


def section(ctx: Context) -> str:
    g = law()
    results = ctx.execute([*rest_runs(), *flow_runs()])
    rest_rows = []
    speeds = [largest_speed(results, r) for r in rest_runs()]
    for k, theta in enumerate(REST_SLOPES):
        below, above = speeds[2 * k], speeds[2 * k + 1]
        rest_rows.append([f"{theta:g}", f"{g.h_stop(theta) * 1e3:.3f}", repr(below), f"{above:.2e}"])
    flow_rows: list[list[object]] = []
    for theta in FLOW_SLOPES:
        for ratio in RATIOS:
            found = [flow(results, theta, ratio, n) for n in LAYERS]
            if any(f is None for f in found):
                flow_rows.append([f"{theta:g}", f"{ratio:g}", "failed", "", "", "", ""])
                continue
            errors = [f.froude / (g.beta * ratio) - 1 for f in found if f is not None]
            orders = order_column(MeshStudy(LAYERS, tuple(abs(e) for e in errors)).orders())
            for n, f, e, o in zip(LAYERS, found, errors, orders):
                assert f is not None
                flow_rows.append(
                    [f"{theta:g}", f"{ratio:g}", n, f"{f.froude:.5f}", f"{e:+.2e}", o, f"{f.change:.1e}"]
                )
    source = source_text()
    beta_law = pouliquen_beta(g.I_0, g.L, GRAIN, PACKING)
    return f"""## Stopping thickness and flow rule (`pouliquen_forterre`)

The law `mu = max(mu_stop(h), mu_J(I))` ([model.md](model.md)) with the glass-bead fit
mu_1 = tan {math.degrees(math.atan(g.mu_1)):.2f} deg, mu_2 = tan {math.degrees(math.atan(g.mu_2)):.2f} deg,
L = {g.L * 1e3:g} mm, beta = {g.beta:g} ({source}); d = {GRAIN * 1e3:g} mm and rho / rho_p =
{PACKING:g} are assumptions, and
I_0 = 5 beta d / (2 L sqrt(phi)) = {g.I_0:.4f} makes the law's own flow rule `Fr = beta h / h_stop`
with beta = {beta_law:.4f} (Jop, Forterre & Pouliquen 2005, appendix A).  The fit and the rule are
thus inputs: this section checks that the engine realises them (an exact threshold, the steady
flow of the law), not the fit against the bead data, whose points are in the papers' figures.
Runs: `{SCENARIO}.yaml` (a uniform layer in four periodic columns on a no-slip base) with this
law, `--set slope_deg`, `initial`, `domain.layers`.

**h_stop(theta).**  Layers 0.1 % thinner and thicker than h_stop(theta), from rest, 1 s, 8 layers:
the largest speed over every output.

{table(["theta (deg)", "h_stop (mm)", "max abs(u), 0.999 h_stop", "max abs(u), 1.001 h_stop"], rest_rows)}

Verdict: every thinner layer exactly at rest (u == 0.0) and every thicker one flowing:
{met(rest_met(results))}.

**Flow rule.**  Steady flow after {END:g} s from rest; Fr = depth-mean u / sqrt(g h cos theta) at the
last output, its error against beta h / h_stop, the observed order of that error, and the
largest change over the last output interval relative to the surface speed (steadiness).

{table(FLOW_HEADER, flow_rows)}

Verdict: the Froude error converges at an observed order of at least {MIN_ORDER:g} and is below
{MAX_ERROR:.1%} at {LAYERS[-1]} layers for every slope and thickness: {met(flow_rule_met(results))}.
Together the two tables show the stop at a finite Froude number: Fr = beta h / h_stop down to
h_stop, zero below it, as for the glass beads (Pouliquen 1999).
"""
