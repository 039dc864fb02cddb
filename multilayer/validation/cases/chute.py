"""The granular Blasius problem: a fast chute flow passing from a smooth to a rough base
(Tsang, Dalziel & Vriend 2019, J. Fluid Mech. 872).

Runs: ``smooth_to_rough_chute.yaml`` with its power law (alpha = 0.34), the linear law
(alpha = 1), each also on a horizontal chute with the same normal gravity, and the Jop law
with three values of I_0, at up to three resolutions; a long chute for the far field.
Measures: the displacement thickness delta*, the shape factor chi and their power-law
exponents in fixed windows, against the similarity solution of
:mod:`multilayer.reference.similarity`; the Bagnold depth and chi = 5/4 far downstream; the
profile at the end of the window for the Jop law.  Criteria: within
:data:`THEORY_ACCURACY` of the leading-order theory; :data:`FAR_FIELD_ACCURACY` for the far
field; a wall layer or none by :data:`WALL_LAYER_SPEED` and :data:`SPREAD_DEFICIT`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from multilayer.app import exact_solutions, factory
from multilayer.reference import exact, similarity
from multilayer.scenario import Scenario
from multilayer.validation.markdown import met, resolution, table
from multilayer.validation.mesh_study import MeshStudy, file_comparison, file_error
from multilayer.validation.runs import Context, Results, Run

NAME = "chute"
SCENARIO = "smooth_to_rough_chute"
Analysis = dict[str, Any]
"""The measures of one run (:func:`analyse`)."""

TIME = ("time.end=1.2", "time.output_interval=0.1")
CELLS = (220, 440, 880)  # dx = 5, 2.5, 1.25 mm over the 1.1 m chute
FINE_LAYERS = (
    "domain.layers=48",
    "domain.layer_fractions={geometric: 1.0583}",
)  # each layer about halved
LINEAR = ("rheology.alpha=1", "rheology.m=0.2")
# Jop fit of Tsang et al. (2019), Table 1: (mu_1, mu_2, I_0) = (tan 16.83 deg, tan 54.08 deg, 3.25)
JOP = ("rheology={name: jop_mu_i, mu_s: 0.30249, mu_2: 1.38043, I_0: 3.25}",)
# the same with smaller I_0: 0.279 (the glass beads of bagnold_chute.yaml), and 0.01 so that
# I >> I_0 throughout the layer and the law is at its alpha = -1 asymptote there
JOP_SMALL_I0 = ("rheology={name: jop_mu_i, mu_s: 0.30249, mu_2: 1.38043, I_0: 0.279}",)
JOP_TINY_I0 = ("rheology={name: jop_mu_i, mu_s: 0.30249, mu_2: 1.38043, I_0: 0.01}",)
# 8 m = 10 Fr^2 H at 2 cm cells, until steady over the whole chute (transit about 3.5 s)
LONG = ("domain.x_max=8.0", "domain.cells=405", "time.end=7.0", "time.output_interval=0.5")
FIXED_WINDOW = (0.01, 0.061)  # m: where the predicted delta* of the alpha = 0.34 layer is below H/10
# The theory is leading order in the layer thickness: at the end of the fixed window delta*
# reaches H/10, where the neglected outer-flow perturbation (h/H = 1 + O(delta*/H), sec. 4.6
# of Tsang et al. 2019) is of that relative size.
THEORY_ACCURACY = 0.1
FAR_FIELD_ACCURACY = 0.02  # the 24-layer Bagnold profile itself is exact to < 0.1 % (Bagnold section)
ASYMPTOTE = 10.0
"""The Jop law is at its alpha = -1 asymptote where the bottom-layer I exceeds ASYMPTOTE I_0."""
WALL_LAYER_SPEED, SPREAD_DEFICIT = 0.5, 0.25
"""No wall layer: the bottom layer keeps more than WALL_LAYER_SPEED of U_e and the mid-depth
deficit exceeds SPREAD_DEFICIT delta*/h.  The similarity layers of the power laws give at
most 0.1 for both, a deficit spread linearly over the depth gives 1: the thresholds lie
between."""
Runs = dict[tuple[str, str], Run]
Analyses = dict[tuple[str, str], Analysis]


def level(scenario: Scenario) -> tuple[str, ...]:
    """A horizontal chute with the normal gravity g cos(theta) of the inclined one."""
    return ("slope_deg=0", f"gravity={scenario.gravity * math.cos(math.radians(scenario.slope_deg)):.6f}")


def runs(scenario: Scenario) -> Runs:
    """(case, resolution) -> run of the shipped ``scenario``; resolutions '220', '440', '880'
    cells, '440x48' layers, and 'long' (the 8 m chute)."""
    cases = {
        "alpha034": (),
        "alpha1": LINEAR,
        "alpha1_level": (*LINEAR, *level(scenario)),
        "alpha034_level": level(scenario),
        "jop": JOP,
        "jop_small_i0": JOP_SMALL_I0,
        "jop_tiny_i0": JOP_TINY_I0,
    }
    studied = {"alpha034": (220, 440), "alpha1": CELLS, "alpha1_level": CELLS, "jop": (220, 440)}
    out = {}
    for case, sets in cases.items():
        for n in studied.get(case, (440,)):
            out[(case, str(n))] = Run(f"chute_{case}_{n}", SCENARIO, (f"domain.cells={n}", *TIME, *sets))
        if case in ("alpha1", "jop_tiny_i0"):
            out[(case, "440x48")] = Run(
                f"chute_{case}_440x48", SCENARIO, ("domain.cells=440", *FINE_LAYERS, *TIME, *sets)
            )
    out[("alpha034", "long")] = Run("chute_long", SCENARIO, LONG)
    return out


def _fit(x: np.ndarray, y: np.ndarray, sel: np.ndarray) -> float:
    """Slope of log(y) against log(x) over ``sel`` (NaN with fewer than 3 points)."""
    sel = sel & (y > 0)
    return float(np.polyfit(np.log(x[sel]), np.log(y[sel]), 1)[0]) if sel.sum() > 2 else math.nan


def analyse(ds: xr.Dataset, scenario: Scenario) -> Analysis:
    """Displacement thickness, shape factor and power-law fits of a chute run's last state.

    The prediction is delta* = zeta_disp eps H (x/H)^(1/(1+alpha)) (Tsang et al. 2019, eq.
    4.13, 4.15-4.17) with the run's own law, slope and gravity; laws without a power-law
    form (Jop) get no prediction.
    """
    p = scenario.rheology.params
    h_in, speed = inflow(scenario)
    final, previous = ds.isel(time=-1), ds.isel(time=-2)
    x = ds["x"].values
    dx = float(x[1] - x[0])
    frac = ds["sigma_bnds"].values[:, 1] - ds["sigma_bnds"].values[:, 0]
    h, u = final["h"].values, final["u"].values
    disp = similarity.displacement_thickness(u, frac[:, None] * h[None, :])
    disp_prev = similarity.displacement_thickness(
        previous["u"].values, frac[:, None] * previous["h"].values[None, :]
    )
    chi = similarity.shape_factor(u, frac)
    ratio = u / u[-1]
    momentum = np.sum(frac[:, None] * h[None, :] * ratio * (1 - ratio), axis=0)
    mat = factory.material(scenario)
    g_n = scenario.gravity * math.cos(math.radians(scenario.slope_deg))
    # inertial number at the centre of the bottom layer: d (du/dz) / sqrt(p / rho_p)
    wall_rate = u[0] / (0.5 * frac[0] * np.maximum(h, 1e-12))
    wall_inertial = mat.grain_diameter * wall_rate / np.sqrt(mat.density / mat.particle_density * g_n * h)
    froude = similarity.froude_number(speed, h_in, scenario.gravity)
    fixed = (x >= FIXED_WINDOW[0]) & (x <= FIXED_WINDOW[1])
    paper = (x >= 0.1 * froude**2 * h_in) & (x <= froude**2 * h_in)  # Tsang et al. fig. 9
    out: Analysis = dict(
        x=x,
        u=u,
        h=h,
        frac=frac,
        disp=disp,
        chi=chi,
        shape_ratio=np.divide(disp, momentum, out=np.full_like(disp, np.nan), where=momentum > 0),
        bottom_speed=ratio[0],
        # velocity deficit at mid-depth relative to delta*/h: ~0 for a wall layer, ~1 when
        # the deficit is spread over the whole depth
        mid_deficit=np.array(
            [np.interp(0.5, np.cumsum(frac) - frac / 2, 1 - ratio[:, i]) for i in range(x.size)]
        )
        * h
        / np.where(disp > 0, disp, np.nan),
        wall_inertial=wall_inertial,
        dx=dx,
        froude=froude,
        slope_fixed=_fit(x, disp, fixed),
        chi_fixed=_fit(x, chi - 1, fixed),
        chi_paper=_fit(x, chi - 1, paper),
        paper=(0.1 * froude**2 * h_in, froude**2 * h_in),
        steady=float(np.abs(disp_prev[fixed] / disp[fixed] - 1).max()),
        steady_all=float(np.abs(disp_prev[paper] / disp[paper] - 1).max()),
        outer_gain=float(np.interp(FIXED_WINDOW[1], x, u[-1]) / np.interp(FIXED_WINDOW[0], x, u[-1]) - 1),
        alpha=p.get("alpha"),
    )
    if "alpha" in p:
        alpha = p["alpha"]
        sol = similarity.solve_similarity(alpha)
        eps = similarity.boundary_layer_scale(
            alpha, p["m"], scenario.slope_deg, h_in, speed, scenario.material.grain_diameter, scenario.gravity
        )
        predicted = sol.displacement_thickness * eps * h_in * (np.maximum(x, 0.0) / h_in) ** (1 / (1 + alpha))
        thin = (x >= 4 * dx) & (predicted <= 0.1 * h_in)  # where the predicted delta* is below H/10
        out.update(
            sol=sol,
            predicted=predicted,
            thin=(float(x[thin].min()), float(x[thin].max())) if thin.any() else (math.nan, math.nan),
            slope_thin=_fit(x, disp, thin),
            ratio=float(np.median(disp[fixed] / predicted[fixed])),
        )
    return out


def follows_exponent(a: Analysis, key: str) -> bool:
    """Criterion: the fitted exponent ``a[key]`` (of delta* or chi - 1) within
    :data:`THEORY_ACCURACY` of 1/(1+alpha) (relative)."""
    return bool(abs(a[key] * (1 + a["alpha"]) - 1) < THEORY_ACCURACY)


def has_predicted_size(a: Analysis) -> bool:
    """Criterion: delta* within :data:`THEORY_ACCURACY` of the prediction (median ratio, fixed window)."""
    return bool(abs(a["ratio"] - 1) < THEORY_ACCURACY)


def inflow(scenario: Scenario) -> tuple[float, float]:
    """Thickness and speed of the plug inflow."""
    spec = scenario.boundaries.inflow
    assert spec is not None and spec.velocity.speed is not None  # the shipped chute has a plug inflow
    return spec.thickness, spec.velocity.speed


def _bagnold_depth(scenario: Scenario) -> float:
    """h_Bag (Tsang et al. 2019, eq. 4.3) for the scenario's power law, slope and inflow flux."""
    p, mat = scenario.rheology.params, factory.material(scenario)
    h_in, speed = inflow(scenario)
    return exact.bagnold_depth(
        h_in * speed,
        exact.power_law_inertial_number(scenario.slope_deg, p["mu_s"], p["m"], p["alpha"]),
        mat.grain_diameter,
        scenario.slope_deg,
        scenario.gravity,
        mat.density / mat.particle_density,
    )


def jop_metrics(an: Analyses, case: str, scenario: Scenario) -> dict[str, float]:
    """What the Jop runs show about sec. 4.5: where I > I_0, growth, similarity, grid."""
    a = an[(case, "440")]
    x, fixed = a["x"], (a["x"] >= FIXED_WINDOW[0]) & (a["x"] <= FIXED_WINDOW[1])
    p = scenario.rheology.params
    below = np.flatnonzero((x > 0) & (a["wall_inertial"] < p["I_0"]))
    # Jop's small-I form mu ~ mu_1 + (mu_2 - mu_1) I / I_0 is the linear law (alpha = 1)
    m_small = (p["mu_2"] - p["mu_s"]) / p["I_0"]
    h_in, speed = inflow(scenario)
    eps = similarity.boundary_layer_scale(
        1.0, m_small, scenario.slope_deg, h_in, speed, scenario.material.grain_diameter, scenario.gravity
    )
    blasius = similarity.solve_similarity(1.0).displacement_thickness * eps * h_in
    far = (x >= 0.2) & (x <= 0.8)
    fine = an.get((case, "440x48"))
    # inertial number at mid-depth at the end of the fixed window (the column's interior)
    i = int(np.argmin(np.abs(x - FIXED_WINDOW[1])))
    z = (np.cumsum(a["frac"]) - a["frac"] / 2) * a["h"][i]
    k = int(np.searchsorted(z, 0.5 * a["h"][i]))
    rate = (a["u"][k, i] - a["u"][k - 1, i]) / (z[k] - z[k - 1])
    mat = factory.material(scenario)
    g_n = scenario.gravity * math.cos(math.radians(scenario.slope_deg)) * mat.density / mat.particle_density
    i_mid = mat.grain_diameter * abs(rate) / math.sqrt(g_n * (a["h"][i] - 0.5 * (z[k] + z[k - 1])))
    return dict(
        x_cross=float(x[below[0]]) if below.size else math.nan,
        i_start=float(a["wall_inertial"][np.argmin(np.abs(x - FIXED_WINDOW[0]))]),
        i_end=float(a["wall_inertial"][i]),
        i_mid=float(i_mid),
        steady=a["steady"],
        slope_fixed=a["slope_fixed"],
        slope_far=_fit(x, a["disp"], far),
        bottom_speed=float(a["bottom_speed"][i]),
        mid_deficit=float(a["mid_deficit"][i]),
        shape_far=float(np.nanmean(a["shape_ratio"][far])),
        linear_ratio=float(np.median(a["disp"][far] / (blasius * (x[far] / h_in) ** 0.5))),
        m_small=m_small,
        grid=float(np.median(fine["disp"][fixed] / a["disp"][fixed])) if fine else math.nan,
    )


def no_wall_layer(m: dict[str, float], i_0: float) -> bool:
    """Criterion (sec. 4.5): at the end of the fixed window the law is at its asymptote
    (I > :data:`ASYMPTOTE` I_0 in the bottom layer) and no wall layer forms (the bottom layer
    faster than :data:`WALL_LAYER_SPEED` U_e, the mid-depth deficit above :data:`SPREAD_DEFICIT`)."""
    asymptotic = m["i_end"] > ASYMPTOTE * i_0
    return asymptotic and m["bottom_speed"] > WALL_LAYER_SPEED and m["mid_deficit"] > SPREAD_DEFICIT


FILE_CELLS = (110, 220, 440, 880)
"""The resolution study of the file's comparison with the similarity solution (the file: 110)."""


def file_run(cells: int) -> Run:
    return Run(f"chute_file_{cells}", SCENARIO, (f"domain.cells={cells}",))


def file_study(ctx: Context, results: Results) -> MeshStudy:
    """The file's comparison with the similarity solution at each of :data:`FILE_CELLS`."""
    sizes, errors = [], []
    for cells in FILE_CELLS:
        r = file_run(cells)
        ds = results[r.name]
        if isinstance(ds, str):
            continue
        sizes.append(cells)
        errors.append(file_error(ds, r.load(ctx.scenarios)))
    return MeshStudy(tuple(sizes), tuple(errors))


def theory_order(scenario: Scenario) -> float:
    """delta*/H predicted at the end of the file's window: the relative size of the terms the
    leading-order theory neglects (Tsang et al. 2019, sec. 4.6)."""
    window = file_comparison(scenario).exact
    assert window.x_max is not None
    layer = exact_solutions.GranularBlasius(scenario)
    return float(layer.field("displacement_thickness", np.array([window.x_max]), None, 0.0)[0] / layer.depth)


def tolerance_is_theory_order(scenario: Scenario) -> bool:
    """Criterion: the file's tolerance is :func:`theory_order` to one significant figure."""
    return file_comparison(scenario).tolerance == float(f"{theory_order(scenario):.1g}")


def within_theory(study: MeshStudy, tolerance: float) -> bool:
    """Criterion: the file's comparison within its tolerance at every resolution of the study."""
    return len(study.sizes) == len(FILE_CELLS) and max(study.errors) <= tolerance


def _file_text(ctx: Context, results: Results) -> str:
    """The file's reference check: delta* against the similarity solution, resolution study."""
    scenario = ctx.load(SCENARIO)
    compared = file_comparison(scenario)
    study = file_study(ctx, results)
    order = theory_order(scenario)
    dx = [(scenario.domain.x_max - scenario.domain.x_min) / n * 1000 for n in study.sizes]
    changes = ["-"] + [f"{b - a:+.4f}" for a, b in zip(study.errors, study.errors[1:])]
    rows = [[n, f"{d:g}", f"{e:.4f}", c] for n, d, e, c in zip(study.sizes, dx, study.errors, changes)]
    window = f"{compared.exact.x_min:g} m <= x <= {compared.exact.x_max:g} m"
    return f"""
### The file's reference check

`{SCENARIO}.yaml` compares, at its end time t = {scenario.time.end:g} s, the displacement
thickness of each column with the similarity prediction over {window}
(relative L1 error, its `expect:` entry with `exact:`).  Its tolerance is the order of the
terms the leading-order theory neglects, delta*/H at the end of the window
({order:.3f}; the file's tolerance, {compared.tolerance:g}, is that to one figure:
{met(tolerance_is_theory_order(scenario))}).  The file at other resolutions:

{table(["cells", "dx (mm)", "relative L1 error of delta*", "change"], rows)}

The error grows with the resolution, by smaller steps, towards the model's own converged
difference from the leading-order theory (the coarse file is closer by a cancellation of
errors); it is within the tolerance at every resolution: {met(within_theory(study, compared.tolerance))}.
"""


def _far_field_text(far: dict[str, Any], h_bag: float, figure: str) -> str:
    """Far downstream: the Bagnold depth (eq. 4.3) and the shape factor 5/4 (sec. 4.6)."""
    if not far:
        return "\nThe long run failed: the far-field checks were not made.\n"
    depth_ok = abs(far["h"] / h_bag - 1) < FAR_FIELD_ACCURACY
    chi_ok = abs(far["chi"] / 1.25 - 1) < FAR_FIELD_ACCURACY
    return f"""
### Far downstream: the Bagnold depth and the shape factor 5/4

A run on an 8 m chute (`{" ".join("--set " + o for o in LONG)}`; 10 Fr^2 H) follows
the flow until the inertia of the inflow is spent.  Far downstream the theory expects the
Bagnold profile without slip (sec. 4.1) at the depth h_Bag of eq. 4.3,
h_Bag = (5 d q / (2 I(theta) (g cos(theta))^(1/2)))^(2/5) = {h_bag * 100:.2f} cm, with the
inflow flux q = U H and I(theta) = (tan(theta) / m)^(1/alpha) (mu_s = 0), and the shape
factor chi = 5/4 (sec. 4.6).  Both are exact for the uniform state, and the 24-layer
Bagnold profile is itself exact to better than 0.1 % (Bagnold section above), so a
{FAR_FIELD_ACCURACY:.0%} criterion tests whether the far field is reached, not the numerics.

{figure}

Measured over {far["band"][0]:.1f}-{far["band"][1]:.1f} m (away from the outflow): depth
{far["h"] * 100:.2f} cm ({far["h"] / h_bag - 1:+.1%} from h_Bag), falling along x by
{-far["dhdx"] * 1000:.1f} mm per m, and changing by at most {far["h_change"] * 1000:.2f} mm over the
last {far["interval"]:g} s; flux {far["flux"]:.4f} m^2/s (q = {far["q"]:.4f}); shape factor
{far["chi"]:.3f}.  Upstream the depth rises from H to a maximum of {far["peak"] * 100:.2f} cm at
x = {far["x_peak"]:.1f} m as the boundary layer slows the flow, then falls towards h_Bag.

Verdicts:
- **Far-downstream depth h_Bag** (eq. 4.3): {
        "**met** (within " + f"{FAR_FIELD_ACCURACY:.0%})"
        if depth_ok
        else "**not reached** within 8 m: the depth is still "
        + f"{far['h'] / h_bag - 1:+.1%} from h_Bag and falling towards it"
    }.  The relaxation is slower than the Fr^2 H scale of the depth-averaged argument, as
  the paper also finds for its DPM flows (sec. 5.3: not Bagnoldian at 2.5 Fr^2 H).
- **Shape factor 5/4** (sec. 4.6): chi = {far["chi"]:.3f}: {
        "**met** (within " + f"{FAR_FIELD_ACCURACY:.0%})" if chi_ok else "**not reached** within 8 m"
    }.
"""


def _jop_text(an: Analyses, chute_runs: Runs, ctx: Context) -> str:
    """The Jop law: no self-similar layer where it is at its alpha = -1 asymptote (sec. 4.5)."""
    rows: list[list[str]] = []
    metrics: dict[str, dict[str, float]] = {}
    for case in ("jop", "jop_small_i0", "jop_tiny_i0"):
        if (case, "440") not in an:
            rows.append([LABELS[case], "run failed"] + [""] * 8)
            continue
        m = metrics[case] = jop_metrics(an, case, chute_runs[(case, "440")].load(ctx.scenarios))
        rows.append(
            [
                LABELS[case],
                f"{m['x_cross']:.3f}" if math.isfinite(m["x_cross"]) else "beyond 1 m",
                f"{m['i_start']:.2f} / {m['i_end']:.2f}",
                f"{m['slope_fixed']:.2f}",
                f"{m['bottom_speed']:.2f} / {m['mid_deficit']:.2f}",
                "n/a" if not math.isfinite(m["grid"]) else f"{m['grid']:.2f}",
                f"{m['slope_far']:.2f}",
                f"{m['shape_far']:.2f}",
                f"{m['linear_ratio']:.2f}",
            ]
        )
    power = []
    for c in ("alpha034", "alpha1"):
        if (c, "440") in an:
            a = an[(c, "440")]
            i = int(np.argmin(np.abs(a["x"] - FIXED_WINDOW[1])))
            power.append(f"alpha = {a['alpha']:g}: {a['bottom_speed'][i]:.2f} / {a['mid_deficit'][i]:.2f}")
    power_profiles = "; ".join(power)
    return f"""
### The Jop law: the alpha = -1 asymptote (sec. 4.5)

For I >> I_0 the Jop law tends to mu_2 - (mu_2 - mu_1) I_0 / I, the form (4.10) with
alpha = -1, for which the paper shows that no self-similar boundary layer exists (the
exponent 1/(1+alpha) of eq. 4.18 is undefined); it notes that a growing layer that is not
self-similar is not excluded.  A self-similar layer has a fixed profile in z / delta*, so
its shape ratio delta* / theta (theta the momentum thickness) is constant along x, and
delta* grows as a single power of x.  Runs (2.5 mm cells, and 48 layers for the layer
study) with the paper's Jop fit, mu_1 = tan 16.83 deg, mu_2 = tan 54.08 deg, I_0 = 3.25
(`--set '{JOP[0]}'`), and with I_0 = 0.279 and 0.01
(`--set '{JOP_TINY_I0[0]}'`): the smaller I_0, the further downstream the layer stays at
I >> I_0.  Where I < I_0 the Jop law is at its small-I, linear form
mu_1 + (mu_2 - mu_1) I / I_0, i.e. alpha = 1 with m = (mu_2 - mu_1) / I_0; the last
column compares delta* with that classical Blasius layer (eq. 4.24).  Whether a wall
layer exists is read from the profile at the end of the fixed window: the speed of the
bottom layer (centre 0.1 mm above the base) relative to U_e, and the velocity deficit at
mid-depth relative to delta*/h (0 when the deficit sits in a wall layer, 1 when it is
spread linearly over the depth).  For the power-law layers these are {power_profiles}.

{
        table(
            [
                "law",
                "x where the bottom-layer I falls below I_0 (m)",
                "I at x = 0.01 / 0.061 m",
                "exponent of delta*, 0.01-0.061 m",
                "at x = 0.061 m: u_bottom / U_e and mid-depth deficit / (delta*/h)",
                "delta* with 48 layers / 24 layers",
                "exponent of delta*, 0.2-0.8 m",
                "delta* / theta, 0.2-0.8 m",
                "delta* / (alpha = 1 layer with m = (mu_2 - mu_1) / I_0), 0.2-0.8 m",
            ],
            rows,
        )
    }

{_jop_verdict(metrics)}
"""


def _jop_verdict(metrics: dict[str, dict[str, float]]) -> str:
    """Sec. 4.5 is tested where the law is at its asymptote (I >> I_0 over the whole window)."""
    tiny, fit = metrics.get("jop_tiny_i0"), metrics.get("jop")
    lines = ["Verdicts:"]
    if tiny is None:
        lines.append("- the run at the alpha = -1 asymptote failed: sec. 4.5 **not tested**.")
    else:
        grid = (
            ""
            if not math.isfinite(tiny["grid"])
            else f"; with 48 layers delta* changes by a factor {tiny['grid']:.2f}"
        )
        lines.append(
            f"- **No self-similar layer at the alpha = -1 asymptote** (sec. 4.5), I_0 = 0.01: the "
            f"bottom-layer I stays at {tiny['i_end']:.1f} to {tiny['i_start']:.1f}, i.e. "
            f"{tiny['i_end'] / 0.01:.0f} to {tiny['i_start'] / 0.01:.0f} I_0, over the fixed window.  At "
            f"x = 0.061 m the bottom layer still moves at {tiny['bottom_speed']:.2f} U_e, i.e. the shear "
            "concentrates below the centre of the bottom layer (the wall friction tends to mu_2 p "
            "whatever the shear rate, so nothing spreads the shear into a layer), and the rest of "
            f"the deficit is spread over the depth (mid-depth deficit {tiny['mid_deficit']:.2f} delta*/h; "
            f"the interior shears slowly, I = {tiny['i_mid']:.3f} = {tiny['i_mid'] / 0.01:.1f} I_0 at "
            f"mid-depth): the column decelerates as a whole and delta* grows with exponent "
            f"{tiny['slope_fixed']:.2f}{grid}.  No resolved wall layer forms, self-similar or not, as "
            f"sec. 4.5 implies (criterion: bottom-layer I above {ASYMPTOTE:g} I_0, bottom-layer speed above "
            f"{WALL_LAYER_SPEED:g} U_e and mid-depth deficit above {SPREAD_DEFICIT:g}, against at most 0.1 "
            "for "
            f"the similarity layers): {met(no_wall_layer(tiny, 0.01))}."
        )
    if fit is not None:
        lines.append(
            f"- **The paper's Jop fit (I_0 = 3.25)** is at its asymptote only upstream of x = "
            f"{fit['x_cross']:.3f} m here; downstream the bottom-layer I is below I_0 and the law is at "
            "its linear small-I form, and the layer that grows is the classical Blasius layer of "
            f"that form (delta* = {fit['linear_ratio']:.2f} x its prediction over 0.2-0.8 m, delta* / theta "
            f"{fit['shape_far']:.2f} against 2.59).  So with this Froude number and H/d = 50 the Jop fit "
            "does give a growing layer, through its small-I branch; sec. 4.5 concerns I >> I_0 and is "
            "not contradicted, but the statement that the Jop fit admits no growing layer holds only "
            "where the layer's I stays well above I_0."
        )
    return "\n".join(lines)


LABELS = {
    "alpha034": "alpha = 0.34, 16 deg",
    "alpha034_level": "alpha = 0.34, horizontal, g cos 16 deg",
    "alpha1": "alpha = 1, 16 deg",
    "alpha1_level": "alpha = 1, horizontal, g cos 16 deg",
    "jop": "Jop fit, I_0 = 3.25",
    "jop_small_i0": "Jop fit with I_0 = 0.279",
    "jop_tiny_i0": "Jop fit with I_0 = 0.01",
}
RESOLUTION_LABELS = {"220": "5 mm", "440": "2.5 mm", "880": "1.25 mm", "440x48": "2.5 mm, 48 layers"}


def section(ctx: Context) -> str:
    scenario = ctx.load(SCENARIO)
    h_in, speed = inflow(scenario)
    chute_runs = runs(scenario)
    results = ctx.execute([*chute_runs.values(), *(file_run(n) for n in FILE_CELLS)])
    an: Analyses = {}
    for key, run in chute_runs.items():
        ds = results[run.name]
        if not isinstance(ds, str):
            an[key] = analyse(ds, run.load(ctx.scenarios))
    failed = [r.name for r in chute_runs.values() if isinstance(results[r.name], str)]
    froude = similarity.froude_number(speed, h_in, scenario.gravity)
    h_bag = _bagnold_depth(scenario)

    def get(case: str, res: str, key: str) -> float:
        return an[(case, res)][key] if (case, res) in an else math.nan

    # ---------------------------------------------------------------- figure 1: boundary layer
    fig = Figure(figsize=(13, 9))
    axes = fig.subplots(2, 2)
    ax = axes[0, 0]
    for case, color in zip(("alpha034", "alpha1", "alpha1_level"), ("C0", "C1", "C2")):
        a = an.get((case, "440"))
        if a is None:
            continue
        pos = a["x"] > 0
        ax.loglog(a["x"][pos], a["disp"][pos] * 1000, color=color, label=LABELS[case])
        ax.loglog(a["x"][pos], a["predicted"][pos] * 1000, color=color, ls=":", lw=1)
    ax.axvspan(*FIXED_WINDOW, color="0.9", label="fixed window 0.01-0.061 m")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("displacement thickness delta* (mm)")
    ax.set_title("delta* (2.5 mm cells); dotted: similarity prediction", fontsize=9)
    ax.legend(fontsize=7)
    ax = axes[0, 1]
    for case, color in zip(("alpha034", "alpha1"), ("C0", "C1")):
        a = an.get((case, "440"))
        if a is None:
            continue
        sol = a["sol"]
        zeta = np.linspace(0, 3, 300)
        ax.plot(sol.velocity(zeta * sol.displacement_thickness), zeta, color=color, lw=3, alpha=0.35)
        for xs, marker in zip((0.01, 0.02, 0.04, 0.4), ("o", "s", "^", "v")):
            i = int(np.argmin(np.abs(a["x"] - xs)))
            z = (np.cumsum(a["frac"]) - a["frac"] / 2) * a["h"][i]
            ax.plot(
                a["u"][:, i] / a["u"][-1, i],
                z / a["disp"][i],
                marker,
                color=color,
                ms=3.5,
                ls="none",
                label=f"{LABELS[case]}, x = {xs} m",
            )
    ax.set_xlabel("u / U_e")
    ax.set_ylabel("z / delta*")
    ax.set_ylim(0, 3)
    ax.set_title("profiles in similarity variables; thick: f'(zeta) (eq. 4.16)", fontsize=9)
    ax.legend(fontsize=6)
    ax = axes[1, 0]
    for case, color in zip(("alpha034", "alpha1", "alpha1_level"), ("C0", "C1", "C2")):
        pts = [
            (an[(case, n)]["dx"], an[(case, n)]["slope_fixed"])
            for n in ("220", "440", "880")
            if (case, n) in an
        ]
        if pts:
            ax.plot(*np.array(pts).T * [[1000], [1]], "o-", color=color, label=LABELS[case])
        if (case, "440x48") in an:
            ax.plot(2.5, an[(case, "440x48")]["slope_fixed"], "s", color=color, mfc="none", ms=9)
    for alpha in (0.34, 1.0):
        ax.axhline(1 / (1 + alpha), color="k", ls="--", lw=0.8)
    ax.set_xlabel("dx (mm); open squares: 48 layers")
    ax.set_ylabel("exponent of delta*, 0.01-0.061 m")
    ax.set_xlim(0, 6)
    ax.legend(fontsize=7)
    ax = axes[1, 1]
    for case, color in zip(("alpha034", "alpha1", "alpha1_level"), ("C0", "C1", "C2")):
        a = an.get((case, "440"))
        if a is None:
            continue
        pos = a["x"] > 0
        ax.loglog(a["x"][pos], a["chi"][pos] - 1, color=color, label=LABELS[case])
        xr_ = np.array([0.01, 0.5])
        c0 = np.interp(0.03, a["x"], a["chi"] - 1)
        ax.loglog(xr_, c0 * (xr_ / 0.03) ** (1 / (1 + a["alpha"])), color=color, ls=":", lw=1)
    ax.axvspan(*FIXED_WINDOW, color="0.9")
    ax.axvspan(0.1 * froude**2 * h_in, froude**2 * h_in, color="0.95")
    ax.set_xlabel("x (m); shaded: fixed window and 0.1 Fr^2 H to Fr^2 H")
    ax.set_ylabel("chi - 1")
    ax.set_title("shape factor; dotted: slope 1/(1+alpha) (eq. 4.26)", fontsize=9)
    ax.legend(fontsize=7)
    figure = ctx.figure(fig, "chute")

    # ---------------------------------------------------------------- figure 2: far field and Jop
    fig = Figure(figsize=(13, 9))
    axes = fig.subplots(2, 2)
    long = an.get(("alpha034", "long"))
    far: dict[str, Any] = {}
    if long is not None:
        x = long["x"]
        axes[0, 0].plot(x, long["h"] * 100, "C0", label="depth h (8 m run)")
        axes[0, 0].axhline(h_bag * 100, color="k", ls="--", label=f"h_Bag = {h_bag * 100:.2f} cm (eq. 4.3)")
        axes[0, 0].axhline(h_in * 100, color="0.5", ls=":", label="inflow depth H")
        axes[0, 1].plot(x, long["chi"], "C0", label="chi (8 m run)")
        axes[0, 1].axhline(1.25, color="k", ls="--", label="5/4 (Bagnold)")
        band_x = (x.max() - 1.5, x.max() - 0.5)  # away from the outflow
        band = (x >= band_x[0]) & (x <= band_x[1])
        ds_long = results[chute_runs[("alpha034", "long")].name]
        assert not isinstance(ds_long, str)
        h_prev = ds_long["h"].isel(time=-2).values
        far = dict(
            band=band_x,
            x_max=float(x.max()),
            h=float(long["h"][band].mean()),
            dhdx=float(np.polyfit(x[band], long["h"][band], 1)[0]),
            h_change=float(np.abs(long["h"][band] - h_prev[band]).max()),
            interval=float(ds_long["time"][-1] - ds_long["time"][-2]),
            chi=float(long["chi"][band].mean()),
            flux=float((long["h"] * np.sum(long["frac"][:, None] * long["u"], axis=0))[band].mean()),
            q=h_in * speed,
            peak=float(long["h"].max()),
            x_peak=float(x[np.argmax(long["h"])]),
        )
        for ax_ in axes[0]:
            ax_.axvspan(*band_x, color="0.9")
            ax_.set_xlabel("x (m)")
            ax_.legend(fontsize=7)
        axes[0, 0].set_ylabel("h (cm)")
        axes[0, 1].set_ylabel("shape factor chi")
    jop_cases = (
        ("jop", "440", "C3-"),
        ("jop_small_i0", "440", "C4-"),
        ("jop_tiny_i0", "440", "C5-"),
        ("jop_tiny_i0", "440x48", "C5--"),
        ("alpha1", "440", "C1:"),
        ("alpha034", "440", "C0:"),
    )
    for case, res, style in jop_cases:
        a = an.get((case, res))
        if a is None:
            continue
        pos = a["x"] > 0
        label = f"{LABELS[case]}, {RESOLUTION_LABELS[res]}"
        axes[1, 0].loglog(a["x"][pos], a["disp"][pos] * 1000, style, label=label)
        axes[1, 1].loglog(a["x"][pos], a["wall_inertial"][pos], style, label=label)
    for i_0, color in ((3.25, "C3"), (0.279, "C4"), (0.01, "C5")):
        axes[1, 1].axhline(i_0, color=color, lw=0.8, ls="-.", label=f"I_0 = {i_0}")
    for ax_ in axes[1]:
        ax_.axvspan(*FIXED_WINDOW, color="0.9")
        ax_.set_xlabel("x (m)")
        ax_.legend(fontsize=6)
    axes[1, 0].set_ylabel("delta* (mm)")
    axes[1, 1].set_ylabel("inertial number at the bottom layer")
    figure2 = ctx.figure(fig, "chute_far_field")

    # ---------------------------------------------------------------- tables and verdicts
    def f3(v: float) -> str:
        return "n/a" if not math.isfinite(v) else f"{v:.3f}"

    main_rows = []
    for case in ("alpha034", "alpha034_level", "alpha1", "alpha1_level"):
        a = an.get((case, "440"))
        if a is None:
            main_rows.append([LABELS[case], "run failed"] + [""] * 10)
            continue
        main_rows.append(
            [
                LABELS[case],
                f"{1 / (1 + a['alpha']):.3f}",
                f"{a['thin'][0]:.3f}-{a['thin'][1]:.3f}",
                f3(a["slope_thin"]),
                f3(a["slope_fixed"]),
                f"{a['ratio']:.2f}",
                f"{a['outer_gain']:+.1%}",
                f3(a["chi_fixed"]),
                f3(a["chi_paper"]),
                f"{a['steady']:.1e} / {a['steady_all']:.1e}",
            ]
        )
    study_rows = []
    for case in ("alpha034", "alpha1", "alpha1_level"):
        study_rows.append(
            [LABELS[case], f"{1 / (1 + (1.0 if 'alpha1' in case else 0.34)):.3f}"]
            + [f3(get(case, res, "slope_fixed")) for res in ("220", "440", "880", "440x48")]
        )
    gravity_rows, explained = [], {}
    for res in ("220", "440", "880"):
        inclined, horizontal = get("alpha1", res, "slope_fixed"), get("alpha1_level", res, "slope_fixed")
        explained[res] = (horizontal - inclined) / (0.5 - inclined)
        gravity_rows.append(
            [
                RESOLUTION_LABELS[res],
                f3(inclined),
                f3(horizontal),
                f3(0.5 - inclined),
                f3(horizontal - inclined),
                f"{explained[res]:.0%}" if math.isfinite(explained[res]) else "n/a",
                f"{get('alpha1', res, 'outer_gain'):+.1%} / {get('alpha1_level', res, 'outer_gain'):+.1%}",
            ]
        )
    verdicts = []
    for case in ("alpha034", "alpha034_level", "alpha1", "alpha1_level"):
        a = an.get((case, "440"))
        if a is None:
            continue
        verdicts.append(
            f"{LABELS[case]}: exponent {a['slope_fixed']:.3f} against {1 / (1 + a['alpha']):.3f} "
            f"{met(follows_exponent(a, 'slope_fixed'))}, size {a['ratio']:.2f} x predicted "
            f"{met(has_predicted_size(a))}"
        )
    chi_verdicts = [
        f"{LABELS[case]}: {an[(case, '440')]['chi_fixed']:.3f} "
        f"{met(follows_exponent(an[(case, '440')], 'chi_fixed'))}"
        for case in ("alpha034", "alpha034_level", "alpha1", "alpha1_level")
        if (case, "440") in an
    ]
    a34 = similarity.solve_similarity(0.34)
    short = {res: 0.5 - get("alpha1", res, "slope_fixed") for res in ("440", "880")}
    gain = {
        res: get("alpha1_level", res, "slope_fixed") - get("alpha1", res, "slope_fixed")
        for res in ("440", "880")
    }
    level_short = {res: 0.5 - get("alpha1_level", res, "slope_fixed") for res in ("220", "440", "880")}
    main = results[chute_runs[("alpha034", "440")].name]
    main_resolution = "n/a" if isinstance(main, str) else resolution(main)
    text = f"""## Smooth-to-rough chute (granular Blasius boundary layer)

Scenario `smooth_to_rough_chute.yaml`: plug inflow H = 5 cm, U = {speed} m/s (Fr = {froude:.2f})
on a 16 deg chute, free slip for x < 0 and no slip for x > 0, power-law
mu(I) = 0.56 I^0.34 (Tsang, Dalziel & Vriend 2019, Table 1), d = 1 mm, 24 geometric layers
(ratio 1.12, the bottom one 0.5 % of h).  Cases: the file (alpha = 0.34); the linear law
(`{" ".join("--set " + o for o in LINEAR)}`, the classical Blasius layer); each of them
also on a horizontal chute with the same normal gravity g cos(16 deg), so that only the
downslope gravity that accelerates the outer flow is removed
(`{" ".join("--set " + o for o in level(scenario))}`); and the Jop law
(`--set '{JOP[0]}'`, the paper's Table 1 fit; more below).  Every run uses
`{" ".join("--set " + o for o in TIME)}` and `--set domain.cells=440` (dx = 2.5 mm);
the resolution study adds 220 cells (dx = 5 mm) for alpha = 0.34, alpha = 1 and the Jop
fit, 880 cells (1.25 mm) for
alpha = 1 on both chutes, and 48 layers
(`{" ".join("--set " + o for o in FINE_LAYERS)}`, each layer about halved) for alpha = 1
on the inclined chute.  Resolution of the main runs:
{main_resolution}.

The displacement thickness is delta* = sum_a h_a (1 - u_a / U_e), U_e the top-layer
speed.  The similarity solution f of eq. 4.16 is computed by `multilayer.reference.similarity`
(shooting); the theory predicts delta* = zeta_disp eps H (x/H)^(1/(1+alpha)) with eps of
eq. 4.13 (for the horizontal runs with the reduced gravity and cos(theta) = 1, which gives
the same eps), no fitted constant.  The theory is leading order for a layer thin
compared with the flow.  **Fit windows.**  The fixed window 0.01 m <= x <= 0.061 m is
where the predicted delta* of the alpha = 0.34 layer stays below H/10; every exponent
compared across laws, slopes and resolutions below is fitted there.  The same H/10
criterion applied to each law separately gives its own window (column "own H/10 window"):
for alpha = 1 it runs to 0.169 m, where delta* = H/10 means a layer about 0.3 H thick
(the 99 % thickness is about 3 delta*).  The paper's shape-factor plots (its figures 9
and 10) span 0.1 Fr^2 H to Fr^2 H = {0.1 * froude**2 * h_in:.3f} to {froude**2 * h_in:.2f} m.

{figure}

Runs at dx = 2.5 mm:

{
        table(
            [
                "case",
                "predicted exponent 1/(1+alpha)",
                "own H/10 window (m)",
                "exponent of delta* there",
                "exponent of delta*, 0.01-0.061 m",
                "delta* / predicted, 0.01-0.061 m",
                "U_e(0.061 m) / U_e(0.01 m) - 1",
                "exponent of chi - 1, 0.01-0.061 m",
                "exponent of chi - 1, 0.1-1 Fr^2 H",
                "change of delta* over the last 0.1 s: window / 0.1-1 Fr^2 H",
            ],
            main_rows,
        )
    }

The window is steady in every run (second-last column: the largest relative change of
delta* over the last output interval).  Further downstream the horizontal runs are not
steady at t = 1.2 s, the decelerating flow thickening there; no fit uses that region
except the shape-factor exponent over 0.1-1 Fr^2 H.

Resolution study of the exponent of delta* (fixed window 0.01-0.061 m):

{table(["case", "predicted", "dx = 5 mm", "2.5 mm", "1.25 mm", "2.5 mm, 48 layers"], study_rows)}

Equal-gravity comparison for alpha = 1 (fixed window): the horizontal run keeps
g cos(theta), so the only difference is the downslope gravity g sin(theta), which
accelerates the frictionless outer flow (last column: the rise of U_e across the window,
inclined / horizontal):

{
        table(
            [
                "dx",
                "exponent, 16 deg",
                "exponent, horizontal",
                "shortfall at 16 deg (0.5 - exponent)",
                "recovered on the horizontal chute",
                "share of the shortfall",
                "U_e gain, 16 deg / horizontal",
            ],
            gravity_rows,
        )
    }

The shooting solver gives f''(0) = 0.33206 for alpha = 1 (the classical Blasius value)
and {a34.fpp0:.4f} for alpha = 0.34, where the paper quotes about 0.164 (its figure 2), and
zeta_disp = {a34.displacement_thickness:.3f} where the paper quotes about 4.35.  Ours is independent of
the integration range (the algebraic tail 1 - f' ~ zeta^(-2/(1-alpha)) is added
analytically); the integral of 1 - f' cut at zeta = 100 gives 4.355, so the paper's value
corresponds to an integration range of about 100 (tested in tests/test_similarity.py).

Verdicts (criterion: within {THEORY_ACCURACY:.0%} of the prediction.  The theory is leading
order in the layer thickness; at the end of the fixed window delta* reaches H/10, where
the neglected outer-flow perturbation, h/H = 1 + O(delta*/H) by the paper's sec. 4.6, is
of that relative size):
- **Growth exponent and size of the similarity layer** (eq. 4.13, 4.15-4.18), fixed
  window, dx = 2.5 mm: {"; ".join(verdicts)}.
- **Why alpha = 1 falls short on the 16 deg chute.**  With the window and the normal
  gravity held equal, the horizontal chute recovers {f3(gain["440"])} of the
  {f3(short["440"])} shortfall at dx = 2.5 mm and {f3(gain["880"])} of {f3(short["880"])} at 1.25 mm
  ({explained["440"]:.0%} and {explained["880"]:.0%}): the gravity-driven acceleration of the outer flow,
  which the leading-order theory ignores (it keeps U_e fixed; as in the paper's own
  simulations, sec. 5.3, U_e grows along the chute here) explains part of the shortfall,
  **not all of it**.  The horizontal run itself falls short of 1/2 by
  {f3(level_short["220"])}, {f3(level_short["440"])}, {f3(level_short["880"])} at dx = 5, 2.5, 1.25 mm:
  the remainder changes by {f3(level_short["440"] - level_short["880"])} between the two finest
  resolutions, so discretisation error may account for part of it, but three resolutions do
  not establish its limit (finer runs were not made).  Halving the layer thicknesses (48
  layers) changes the 16 deg exponent by {
        get("alpha1", "440x48", "slope_fixed") - get("alpha1", "440", "slope_fixed"):+.3f}.
- **Shape factor growth, chi - 1 proportional to x^(1/(1+alpha))** (eq. 4.26, 5.2-5.3),
  exponent of chi - 1 in the fixed window: {"; ".join(chi_verdicts)}.  In the paper's
  window 0.1-1 Fr^2 H the exponent is {f3(get("alpha034", "440", "chi_paper"))} for alpha = 0.34
  (predicted 0.746): **not met** there; our layer fills the flow well before Fr^2 H (the
  paper's DPM curves follow the power law further, its figure 10).
"""
    text += _file_text(ctx, results)
    text += _far_field_text(far, h_bag, figure2)
    text += _jop_text(an, chute_runs, ctx)
    if failed:
        text += f"\nRuns that failed (not shown): {', '.join(failed)}.\n"
    return text


# --------------------------------------------------------------------------- column collapse
