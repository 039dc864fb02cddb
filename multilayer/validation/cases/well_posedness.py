"""Jop's mu(I) at high resolution, and the partially regularised law of Barker & Gray (2017).

The incompressible mu(I) equations are ill posed at low (and high) inertial numbers
(Barker, Schaeffer, Bohorquez & Gray 2015): short waves grow ever faster as they get
shorter, so computed flows do not converge under refinement.  This case asks what the
unregularised law does in this model, and compares the regularised one
(:mod:`multilayer.validation.barker_gray`, run in-process: it is not a plugin).

Runs (in-process, ``bagnold_chute.yaml`` with the beads of ``inclined_channel_beads.yaml``):

* **Steady uniform flow of the regularised law**: from rest on :data:`STEADY_SLOPES`
  with 8-32 layers, against Bagnold's profile at the law's own ``I_theta`` (the low branch
  inverted at 26 deg, Jop's law with the high-I term at 30 deg).
* **A perturbed uniform flow**: the steady flow :data:`DEPTH` deep, its thickness perturbed
  by ``1e-3 cos(2 pi x / lambda)`` on a periodic domain one wavelength long, at
  :data:`WAVELENGTHS`, on :data:`SLOPES` (Jop's ``I_theta`` below and inside the
  well-posed window), hydrostatic and non-hydrostatic, refined in x and in the layers
  together (:data:`LEVELS`).  Measure: the growth rate of the thickness perturbation and
  of the velocity perturbation over the second half of :data:`SPAN`.
"""

from __future__ import annotations

import math
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

from multilayer.app import factory
from multilayer.engine.simulation import Simulation
from multilayer.plugins.contract import Rheology
from multilayer.reference import exact
from multilayer.validation import published
from multilayer.validation.barker_gray import PartialRegularisation, well_posed_window
from multilayer.validation.markdown import met, order_column, table
from multilayer.validation.mesh_study import MeshStudy
from multilayer.validation.runs import Context

NAME = "well_posedness"
SCENARIO = "bagnold_chute"
BEADS = "inclined_channel_beads.yaml"
STEADY_SLOPES = (26.0, 30.0)
STEADY_LAYERS = (8, 16, 32)
STEADY_END = 6.0
"""Simulated time from rest (s)."""
DEPTH = 0.005
"""Depth of the perturbed flow (m)."""
SLOPES = (26.0, 29.5)
WAVELENGTHS = (1.0,)
"""Wavelengths of the perturbation, in flow depths."""
LEVELS = ((16, 8), (32, 16), (64, 32))
"""(cells per wavelength, layers)."""
PRESSURES = ("hydrostatic", "non_hydrostatic")
AMPLITUDE = 1e-3
SPAN = 0.5
"""Simulated time of a perturbed run (s)."""
OUTPUTS = 20
MAX_STEADY_ERROR = 0.02
"""Largest layer error of the regularised law's steady flow at 32 layers (as the Bagnold case)."""


def beads() -> tuple[float, float, float]:
    v = published.values(BEADS)
    return v["mu_s"], v["mu_2"], v["I_0"]


def law(name: str, ctx: Context) -> Rheology:
    """``jop`` (the file's law, Jop's mu(I) with the beads' values) or ``regularised``."""
    if name == "regularised":
        return PartialRegularisation(*beads())
    return factory.laws(ctx.load(SCENARIO, overrides(26.0, 0.01, 0.04, 4, 8)))[0]


def overrides(theta: float, depth: float, length: float, cells: int, layers: int) -> list[str]:
    mu_s, mu_2, I_0 = beads()
    return [
        f"slope_deg={theta!r}",
        f"rheology={{name: jop_mu_i, mu_s: {mu_s!r}, mu_2: {mu_2!r}, I_0: {I_0!r}}}",
        f"domain.x_max={length!r}",
        f"domain.cells={cells}",
        f"domain.layers={layers}",
        f"initial=[{{shape: layer, thickness: {depth!r}}}]",
    ]


def simulation(
    ctx: Context,
    name: str,
    theta: float,
    depth: float,
    length: float,
    cells: int,
    layers: int,
    pressure: str = "hydrostatic",
) -> tuple[Simulation, exact.BagnoldFlow]:
    """The chute with law ``name`` and the Bagnold flow of that law on the slope."""
    scenario = ctx.load(
        SCENARIO, [*overrides(theta, depth, length, cells, layers), f"model.pressure={pressure}"]
    )
    bulk = law(name, ctx)
    material = factory.material(scenario)
    inertial = exact.inertial_number_for_slope(exact.friction_coefficient(bulk, material), theta)
    flow = exact.BagnoldFlow(
        depth,
        inertial,
        material.grain_diameter,
        theta,
        density_ratio=material.density / material.particle_density,
    )
    return Simulation(factory.engine_config(scenario), bulk, None), flow


@dataclass(frozen=True)
class Steady:
    """The regularised law's flow from rest: layer error against Bagnold, last change."""

    inertial: float
    error: float
    change: float


def steady(ctx: Context, theta: float, layers: int) -> Steady:
    sim, flow = simulation(ctx, "regularised", theta, 0.01, 0.04, 4, layers)
    sim.advance(STEADY_END - 0.2)
    before = sim.u.copy()
    sim.advance(STEADY_END)
    edges = np.concatenate([[0.0], np.cumsum(sim.fractions)]) * float(sim.h.mean())
    exact_means = flow.layer_means(edges)
    u = sim.u.mean(axis=1)
    return Steady(
        flow.inertial_number,
        float(np.abs(u - exact_means).max() / np.abs(exact_means).max()),
        float(np.abs(sim.u - before).max() / np.abs(sim.u).max()),
    )


@dataclass(frozen=True)
class Growth:
    """Growth rates (1/s) of the perturbation of h and of u over the second half of the run."""

    thickness: float
    velocity: float
    steps: int


def growth(
    ctx: Context, name: str, theta: float, wavelength: float, cells: int, layers: int, pressure: str
) -> Growth:
    sim, flow = simulation(ctx, name, theta, DEPTH, wavelength * DEPTH, cells, layers, pressure)
    state = sim.state_dict()
    edges = np.concatenate([[0.0], np.cumsum(sim.fractions)]) * DEPTH
    state["h"] = DEPTH * (
        1.0 + AMPLITUDE * np.cos(2.0 * math.pi * np.arange(cells) / cells + math.pi / cells)
    )
    state["u"] = np.repeat(flow.layer_means(edges)[:, None], cells, axis=1)
    sim.load_state(state)
    t, dh, du = [], [], []
    for k in range(1, OUTPUTS + 1):
        sim.advance(SPAN * k / OUTPUTS)
        t.append(sim.t)
        dh.append(0.5 * (sim.h.max() - sim.h.min()))
        du.append(np.abs(sim.u - sim.u.mean(axis=1, keepdims=True)).max())
    half = OUTPUTS // 2
    tt = np.array(t[half:])
    return Growth(
        float(np.polyfit(tt, np.log(dh[half:]), 1)[0]),
        float(np.polyfit(tt, np.log(np.maximum(du[half:], 1e-300)), 1)[0]),
        sim.steps,
    )


def _growth(task: tuple[Context, str, float, float, int, int, str]) -> Growth:
    return growth(*task)


def convergence(grown: list[Growth]) -> tuple[float, float]:
    """``(r, limit)``: the ratio of the last change of the thickness growth rate under
    refinement to the one before, and the rate extrapolated to infinite resolution,
    ``s_3 + (s_3 - s_2) r / (1 - r)`` (Richardson; nan unless ``0 <= r < 1``).  A rate that
    converges has ``r < 1``; the rates of an ill-posed problem grow without bound."""
    s = [g.thickness for g in grown[-3:]]
    r = (s[2] - s[1]) / (s[1] - s[0])
    return r, (s[2] + (s[2] - s[1]) * r / (1.0 - r)) if 0.0 <= r < 1.0 else math.nan


def limits_of(
    rates: dict[tuple[str, str, float, float], list[Growth]], key: tuple[str, str, float, float]
) -> float:
    """The extrapolated thickness growth rate of one series (:func:`convergence`)."""
    return convergence(rates[key])[1]


def describe(key: tuple[str, str, float, float]) -> str:
    pressure, name, theta, wavelength = key
    return f"{name}, {pressure}, {theta:g} deg"


def section(ctx: Context) -> str:
    mu_s, mu_2, I_0 = beads()
    lo, hi = well_posed_window(mu_s, mu_2, I_0)
    regularised = PartialRegularisation(mu_s, mu_2, I_0)
    steady_rows, steady_ok = [], True
    for theta in STEADY_SLOPES:
        found = [steady(ctx, theta, n) for n in STEADY_LAYERS]
        orders = order_column(MeshStudy(STEADY_LAYERS, tuple(s.error for s in found)).orders())
        steady_ok &= found[-1].error < MAX_STEADY_ERROR
        for n, s, o in zip(STEADY_LAYERS, found, orders):
            steady_rows.append([f"{theta:g}", f"{s.inertial:.4f}", n, f"{s.error:.2e}", o, f"{s.change:.1e}"])
    growth_rows = []
    series = [
        (p, n, t, w) for p in PRESSURES for t in SLOPES for w in WAVELENGTHS for n in ("jop", "regularised")
    ]
    tasks = [(ctx, n, t, w, c, k, p) for p, n, t, w in series for c, k in LEVELS]
    if ctx.jobs > 1:
        with ProcessPoolExecutor(max_workers=ctx.jobs) as pool:
            done = list(pool.map(_growth, tasks))
    else:
        done = [_growth(task) for task in tasks]
    rates = {key: done[i * len(LEVELS) : (i + 1) * len(LEVELS)] for i, key in enumerate(series)}
    for pressure in PRESSURES:
        for theta in SLOPES:
            jop_inertial = exact.jop_inertial_number(theta, mu_s, mu_2, I_0)
            for wavelength in WAVELENGTHS:
                for name in ("jop", "regularised"):
                    grown = rates[(pressure, name, theta, wavelength)]
                    growth_rows.append(
                        [
                            pressure,
                            f"{theta:g} (I = {jop_inertial:.3f})",
                            f"{wavelength:g}",
                            name,
                            " / ".join(f"{g.thickness:+.2f}" for g in grown),
                            " / ".join(f"{g.velocity:+.2f}" for g in grown),
                            f"{convergence(grown)[0]:.2f}",
                            f"{convergence(grown)[1]:+.1f}",
                        ]
                    )
    low_jop = exact.jop_inertial_number(SLOPES[0], mu_s, mu_2, I_0)
    low_regularised = exact.inertial_number_for_slope(
        exact.friction_coefficient(regularised, factory.material(ctx.load(SCENARIO))), SLOPES[0]
    )
    high = [k for k in rates if k[2] == SLOPES[-1] and k[1] == "jop" and limits_of(rates, k) > 0.0]
    same = all(
        abs(limits_of(rates, k) - limits_of(rates, (k[0], "regularised", k[2], k[3])))
        <= 0.1 * abs(limits_of(rates, k))
        for k in high
    )
    alike = (
        (
            f"At {SLOPES[-1]:g} deg, where both laws are Jop's (but for the small high-I term), the "
            f"extrapolated rates of the two laws agree within 10 %: this growth is not the low-I "
            f"ill-posedness that the regularisation removes; its mechanism is not identified here."
            if same
            else f"At {SLOPES[-1]:g} deg the extrapolated rates of the two laws differ by more than 10 %."
        )
        if high
        else ""
    )
    limits = {k: convergence(grown) for k, grown in rates.items()}
    converges = all(abs(r) < 1.0 for r, _ in limits.values())
    reading = (
        "The ill-posedness of Barker et al. (2015) belongs to the depth-resolved incompressible "
        "equations; this layer-averaged model, with the hydrostatic pressure or the "
        "non-hydrostatic one of its layers, does not show it at these resolutions."
        if converges
        else "Some rate does not converge: see the ratios of changes."
    )
    surviving = "; ".join(f"{describe(k)} ({lim:+.1f} 1/s)" for k, (_, lim) in limits.items() if lim > 0.0)
    header = [
        "pressure",
        "theta (deg)",
        "wavelength / depth",
        "law",
        f"rate of h, {len(LEVELS)} levels",
        f"rate of u, {len(LEVELS)} levels",
        "ratio of changes",
        "extrapolated rate of h",
    ]
    levels = " / ".join(f"{c} x {n}" for c, n in LEVELS)
    return f"""## Jop's mu(I) at high resolution; Barker & Gray's regularisation

The incompressible mu(I) equations are ill posed where the inertial number is too low or
too high (Barker, Schaeffer, Bohorquez & Gray 2015, J. Fluid Mech. 779, 794-818): short
waves grow ever faster as they get shorter, so that computed flows do not converge.  For
the beads of the inclined-channel collapses (mu_s = {mu_s:.4f}, mu_2 = {mu_2:.4f}, I_0 = {I_0:g})
Jop's law is well posed only for {lo:.4f} < I < {hi:.3f} (the criterion of Barker & Gray
2017, eq. 3.9).  Barker & Gray (2017, J. Fluid Mech. 828, 5-32) keep the law (with a high-I
term mu_inf = {regularised.mu_inf:g}) above I_1 = {regularised.I_1:.4f} and replace it below by
mu = sqrt(alpha / ln(A / I)), alpha = {regularised.alpha:g}, A = {regularised.A:.4g}, well posed down
to I = 0 but with mu(0) = 0: no yield stress, so every slope creeps.  The project's laws keep
an exact yield stress; the regularised law lives in the validation package
(`multilayer.validation.barker_gray`) and is run in-process.

**Its steady uniform flow.**  `{SCENARIO}.yaml` (1 cm, four periodic columns, no-slip base)
with the regularised law from rest for {STEADY_END:g} s, against Bagnold's profile at the law's
own I_theta (the largest layer error relative to the largest exact layer mean), and the
largest change over the last 0.2 s relative to the surface speed:

{table(["theta (deg)", "I_theta", "layers", "layer error", "order", "last change"], steady_rows)}

Verdict: the regularised law's steady flow is Bagnold's profile at its own I_theta, within
{MAX_STEADY_ERROR:.0%} at {STEADY_LAYERS[-1]} layers: {met(steady_ok)}.

**A perturbed uniform flow at increasing resolution.**  The steady flow {DEPTH * 1e3:g} mm deep,
its thickness perturbed by {AMPLITUDE:g} of a cosine one wavelength long (periodic),
for {SPAN:g} s; growth rates (1/s, negative: decay) of the thickness perturbation and of the
velocity perturbation (largest deviation of a layer velocity from its mean along x) over
the second half, at {levels} (cells per wavelength x layers):

{table(header, growth_rows)}

"Ratio of changes": the last change of the rate of h under refinement over the one before;
"extrapolated": the rate at infinite resolution (Richardson, from the three levels).

Verdict: every growth rate converges under refinement (ratio of changes between -1 and 1), so nothing grows
without bound in this model, with Jop's law as with the regularised one: {met(converges)}.
{reading}  At
{SLOPES[0]:g} deg the two laws flow at different inertial numbers ({low_regularised:.4f} and
{low_jop:.4f}): their rates there compare different base flows.  Perturbations one depth
long that still grow at infinite resolution: {surviving or "none"}.  {alike}
"""
