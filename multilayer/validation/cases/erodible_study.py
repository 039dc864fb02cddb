"""The erodible-bed collapse as a three-mesh study against the experiments' targets
(Mangeney et al. 2010; Farin, Mangeney & Roche 2014).

Runs: ``erodible_bed_collapse.yaml`` (the recommended configuration, as shipped) at the
slopes :data:`THETAS` over the beds :data:`BEDS` on the meshes :data:`CELLS` (dx = 9.3,
4.6 and 2.3 mm: the 20 cm column is 21 to 86 cells long).  Measures
(``multilayer.io.observables``), lengths from the column's front: the deposit tip at
:data:`TIP_DIAMETERS` grain diameters above the bed, the mass front (95 % of the material
above the bed upslope of it), the time the front speed falls below 1 cm/s for good and
the time to 95 % of the run-out.  Criteria (``erosion_targets.yaml``): the gain of the
run-out from the rigid bed within :data:`ZERO` of zero below the critical slope, within
:data:`WITHIN` of the published gain near the repose angle, the duration growing with the
bed above the critical slope only; each on the finest mesh, with its change between the
two finest meshes.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr
import yaml
from matplotlib.figure import Figure

from multilayer.io import observables as obs
from multilayer.validation import published
from multilayer.validation.cases import stopping
from multilayer.validation.markdown import met, table
from multilayer.validation.runs import SCENARIOS, Context, Run

NAME = "erodible_study"
SCENARIO = "erodible_bed_collapse"
BEADS = "inclined_channel_beads.yaml"
TARGETS = "erosion_targets.yaml"
THETAS = (0.0, 10.0, 16.0, 19.0, 22.0, 23.0)
BEDS = (0.0, 0.001, 0.002, 0.003, 0.004, 0.005)
CELLS = (324, 648, 1296)
END = {0.0: 2.0, 10.0: 2.0, 16.0: 3.0, 19.0: 4.0, 22.0: 5.0, 23.0: 6.0}
"""Simulated time per slope (s): long enough for the fronts to stop, except the creep at 23 deg."""
OUTPUT = 0.02
"""Output interval (s): the resolution in time of the durations."""
ORIGIN = -0.05
"""The column's front (m): run-outs are measured from it."""
TIP_DIAMETERS = 3.0
TAPER = (1.0, 3.0, 5.0, 10.0)
"""Tip thresholds (grain diameters) of the taper table."""
ZERO = 0.05
"""Below the critical slope a gain counts as zero within 5 % (of the rigid-bed run-out)."""
WITHIN = 0.30
"""Near the repose angle the gain must be within 30 % (relative) of the published one."""
NEAR_REPOSE = 23.0
"""The slope compared with the published gain "near the repose angle"."""
MEASURES = ("tip", "m95")
MEASURE_NAMES = {"tip": f"tip at {TIP_DIAMETERS:g} d", "m95": "95 % mass front"}
Key = tuple[float, float, int]
"""(slope in degrees, bed thickness in m, cells)."""


@dataclass(frozen=True)
class Law:
    """The law of a study: the prefix of its run names and the overrides that set it."""

    prefix: str
    overrides: tuple[str, ...] = ()


SHIPPED = Law(NAME)
"""The law of the scenario file as shipped."""
STOPPING = "erodible_stopping"
"""The prefix of the runs with :func:`stopping_law`."""


def stopping_law(scenarios: Path = SCENARIOS) -> stopping.Law:
    """``pouliquen_forterre`` for the beads of the scenario file in ``scenarios``, chosen a
    priori: ``mu_1``, ``mu_2`` and the start friction's constant ``mu_3`` are the file's
    ``mu_s``, ``mu_2`` and ``mu_start``; L is the glass beads' L of the stopping case scaled
    by the grain diameter (the same L / d), beta theirs, and I_0 follows from beta with the
    file's packing ``rho / rho_p`` (Jop, Forterre & Pouliquen 2005, appendix A)."""
    shipped = Run(STOPPING, SCENARIO).load(scenarios)
    r, m = shipped.rheology.params, shipped.material
    glass = stopping.law()
    return stopping.Law(
        mu_1=r["mu_s"],
        mu_2=r["mu_2"],
        L=glass.L / stopping.GRAIN * m.grain_diameter,
        beta=glass.beta,
        grain=m.grain_diameter,
        packing=m.density / float(m.particle_density or m.density),
        mu_3=r["mu_start"],
    )


def with_stopping(scenarios: Path = SCENARIOS) -> Law:
    """The study's law :func:`stopping_law`."""
    return Law(STOPPING, (f"rheology={stopping_law(scenarios).rheology()}",))


def run(theta: float, bed: float, cells: int, law: Law = SHIPPED) -> Run:
    return Run(
        f"{law.prefix}_{theta:g}deg_{bed * 1000:g}mm_{cells}",
        SCENARIO,
        (
            *law.overrides,
            f"slope_deg={theta!r}",
            f"initial.0.thickness={bed!r}",
            f"domain.cells={cells}",
            f"time.end={END[theta]!r}",
            f"time.output_interval={OUTPUT!r}",
        ),
    )


def keys(thetas: tuple[float, ...] = THETAS, beds: tuple[float, ...] = BEDS) -> list[Key]:
    return [(t, b, n) for t in thetas for b in beds for n in CELLS]


@dataclass(frozen=True)
class Measures:
    """Run-out (m) by each measure, its duration (s) by the stop and the 95 % times, x_f(t)."""

    runout: dict[str, float]
    stop: dict[str, float]
    t95: dict[str, float]
    t: np.ndarray
    tip: np.ndarray
    tips: dict[float, float]
    """Final tip (m from the column's front) at :data:`TAPER` grain diameters."""
    speed_end: float
    mass_change: float


def measure(ds: xr.Dataset, bed: float) -> Measures:
    x, t, h = ds["x"].values, ds["time"].values, ds["h"].values
    d = float(yaml.safe_load(ds.attrs["scenario"])["material"]["grain_diameter"])
    fronts = {
        "tip": np.array([obs.tip(x, row, d, TIP_DIAMETERS, bed) for row in h]) - ORIGIN,
        "m95": np.array([obs.mass_front(x, row, obs.MASS_FRACTION, bed) for row in h]) - ORIGIN,
    }
    mass = ds["mass"].values
    return Measures(
        {k: float(f[-1]) for k, f in fronts.items()},
        {k: obs.front_stop_time(t, f, obs.STOP_SPEED) for k, f in fronts.items()},
        {k: obs.time_to_fraction(t, f, obs.MASS_FRACTION) for k, f in fronts.items()},
        t,
        fronts["tip"],
        {n: float(obs.tip(x, h[-1], d, n, bed)) - ORIGIN for n in TAPER},
        float(np.abs(ds["u"].values[-1]).max()),
        float(mass[-1] / mass[0] - 1.0),
    )


def measure_all(ctx: Context, wanted: list[Key], law: Law = SHIPPED) -> dict[Key, Measures | str]:
    """The measures of the runs ``wanted`` with ``law`` (run or reused), or their failure messages."""
    runs = {key: run(*key, law) for key in wanted}
    results = ctx.execute(list(runs.values()))
    out: dict[Key, Measures | str] = {}
    for key, r in runs.items():
        ds = results[r.name]
        out[key] = ds if isinstance(ds, str) else measure(ds, key[1])
    return out


def gain(found: dict[Key, Measures | str], theta: float, bed: float, cells: int, what: str = "tip") -> float:
    """Relative change of the run-out from the rigid bed (nan if a run failed)."""
    a, b = found.get((theta, 0.0, cells)), found.get((theta, bed, cells))
    if not isinstance(a, Measures) or not isinstance(b, Measures):
        return math.nan
    return b.runout[what] / a.runout[what] - 1.0


def duration_change(
    found: dict[Key, Measures | str], theta: float, bed: float, kind: str, what: str
) -> float:
    """Relative change of a duration (``stop`` or ``t95``) from the rigid bed, finest mesh."""
    a, b = found.get((theta, 0.0, CELLS[-1])), found.get((theta, bed, CELLS[-1]))
    if not isinstance(a, Measures) or not isinstance(b, Measures):
        return math.nan
    return getattr(b, kind)[what] / getattr(a, kind)[what] - 1.0


def critical_slope() -> float:
    """theta_c = (critical slope / repose angle) x repose angle (deg)."""
    return published.values(TARGETS)["critical_slope_over_repose"] * published.values(BEADS)["repose_angle"]


def beds(found: dict[Key, Measures | str]) -> list[float]:
    """The beds (m) of the runs in ``found``, the rigid bed first."""
    return sorted({b for _, b, _ in found})


def zero_below_critical(found: dict[Key, Measures | str], what: str) -> bool:
    """Criterion: every gain below the critical slope within :data:`ZERO` of zero (finest mesh)."""
    return worst_zero(found, what) <= ZERO


def worst_zero(found: dict[Key, Measures | str], what: str) -> float:
    """The largest |gain| below the critical slope over the erodible beds (finest mesh; nan if
    a run failed)."""
    gains = [
        abs(gain(found, t, b, CELLS[-1], what))
        for t in THETAS
        if t < critical_slope()
        for b in beds(found)[1:]
    ]
    return math.nan if any(math.isnan(g) for g in gains) else max(gains)


def at_repose(found: dict[Key, Measures | str], what: str) -> float:
    """The gain over the thickest bed at :data:`NEAR_REPOSE` (finest mesh)."""
    return gain(found, NEAR_REPOSE, BEDS[-1], CELLS[-1], what)


def published_gain_met(found: dict[Key, Measures | str], what: str) -> bool:
    """Criterion: the gain over the thickest bed at :data:`NEAR_REPOSE` within :data:`WITHIN`
    of the published largest gain (finest mesh)."""
    target = published.values(TARGETS)["largest_runout_gain"]
    return abs(at_repose(found, what) / target - 1.0) <= WITHIN


def duration_trend_met(found: dict[Key, Measures | str], what: str) -> bool:
    """Criterion: the time to 95 % of the run-out grows with the bed (5 mm) above the
    critical slope and is unchanged (within :data:`ZERO`) below it."""
    theta_c = critical_slope()
    for t in THETAS:
        c = duration_change(found, t, BEDS[-1], "t95", what)
        if not (c > 0.0 if t > theta_c else abs(c) <= ZERO):
            return False
    return True


def verdicts(found: dict[Key, Measures | str]) -> dict[str, tuple[bool, bool, bool]]:
    """Measure -> (zero below theta_c, the published gain, the duration trend) met."""
    return {
        w: (zero_below_critical(found, w), published_gain_met(found, w), duration_trend_met(found, w))
        for w in MEASURES
    }


def end_span(found: dict[Key, Measures | str], theta: float, bed: float) -> float:
    """Length (m) of the deposit's end between the first and last :data:`TAPER` thresholds."""
    m = found.get((theta, bed, CELLS[-1]))
    return (m.tips[TAPER[0]] - m.tips[TAPER[-1]]) if isinstance(m, Measures) else math.nan


def tip_change(found: dict[Key, Measures | str], theta: float, n: float) -> float:
    """Change of the tip at ``n`` grain diameters from the rigid bed to the thickest bed."""
    a, b = found.get((theta, 0.0, CELLS[-1])), found.get((theta, BEDS[-1], CELLS[-1]))
    if not isinstance(a, Measures) or not isinstance(b, Measures):
        return math.nan
    return b.tips[n] / a.tips[n] - 1.0


def slopes_where(found: dict[Key, Measures | str], test: Callable[[float], bool]) -> str:
    """The slopes where the change of t95 by the tip over the thickest bed passes ``test``."""
    chosen = [t for t in THETAS if test(duration_change(found, t, BEDS[-1], "t95", "tip"))]
    return ", ".join(f"{t:g}" for t in chosen) or "no"


def largest_change(found: dict[Key, Measures | str]) -> float:
    """The largest change of a thickest-bed gain between the two finest meshes."""
    return max(
        abs(gain(found, t, BEDS[-1], CELLS[-1], w) - gain(found, t, BEDS[-1], CELLS[-2], w))
        for t in THETAS
        for w in MEASURES
    )


def _pct(v: float, signed: bool = True) -> str:
    return "n/a" if not math.isfinite(v) else (f"{v * 100:+.1f}" if signed else f"{v * 100:.1f}")


def setup(found: dict[Key, Measures | str], law: str) -> str:
    """The paragraphs saying what is run (the scenario file ``law``), measured and compared."""
    failed = [k for k, v in found.items() if isinstance(v, str)]
    theta_c = critical_slope()
    target = published.values(TARGETS)["largest_runout_gain"]
    below = ", ".join(f"{t:g}" for t in THETAS if t < theta_c)
    spacings = ", ".join(f"{3000 / n:.1f}" for n in CELLS)
    bed_list = ", ".join(f"{b * 1000:g}" for b in beds(found))
    repose_angle = published.values(BEADS)["repose_angle"]
    return f"""`{SCENARIO}.yaml` {law}, with
`--set slope_deg`, `initial.0.thickness` (the erodible bed, {bed_list} mm;
0 is the rigid bed), `domain.cells` ({", ".join(str(n) for n in CELLS)} cells over 3 m: dx = {spacings} mm,
the 20 cm column {", ".join(f"{n * 0.2 / 3:.0f}" for n in CELLS)} cells long), `time.end`
({", ".join(f"{e:g} s at {t:g} deg" for t, e in END.items())}) and outputs every {OUTPUT:g} s:
{len(found)} runs, {len(failed)} failed.

**Measures** (`multilayer.io.observables`), from the column's front: the deposit tip, where
h falls through the bed + {TIP_DIAMETERS:g} grain diameters; the mass front m95, upslope of
which 95 % of the material above the bed lies; durations by the front speed falling below
{obs.STOP_SPEED * 100:g} cm/s for good ("stop") and by the time to 95 % of the run-out
("t95").  A gain is the change of the run-out from the rigid bed on the same mesh.

**Targets** ({published.source(TARGETS).cite()}): no effect of the bed below the critical slope
theta_c ~ theta_r / 2 = {theta_c:.2f} deg (repose angle {repose_angle:g} deg): gains
within {ZERO:.0%} of zero at {below} deg; a gain "up to {target:.0%}" near the repose angle, compared
here with the {BEDS[-1] * 1000:g} mm bed at {NEAR_REPOSE:g} deg (within {WITHIN:.0%} of it); the duration
growing with the bed above theta_c only.  The per-slope gains at 19 and 22 deg and the
durations of the experiments are in the papers' figures, which we could not read: those
slopes are reported, not judged."""


def results(ctx: Context, found: dict[Key, Measures | str], figure: str) -> str:
    """The figure ``validation_<figure>.png``, the tables of the runs and the verdicts."""
    finest = CELLS[-1]
    theta_c = critical_slope()
    target = published.values(TARGETS)["largest_runout_gain"]
    bed_list = beds(found)
    rows = []
    for theta in THETAS:
        for bed in bed_list:
            m = found.get((theta, bed, finest))
            if not isinstance(m, Measures):
                rows.append([f"{theta:g}", f"{bed * 1000:g}", "failed", "", "", "", "", "", ""])
                continue
            rows.append(
                [
                    f"{theta:g}",
                    f"{bed * 1000:g}",
                    f"{m.runout['tip']:.3f} / {m.runout['m95']:.3f}",
                    " / ".join(_pct(gain(found, theta, bed, n, "tip")) for n in CELLS),
                    " / ".join(_pct(gain(found, theta, bed, n, "m95")) for n in CELLS),
                    f"{m.stop['tip']:.2f} / {m.t95['tip']:.2f}",
                    f"{_pct(duration_change(found, theta, bed, 'stop', 'tip'))} / "
                    f"{_pct(duration_change(found, theta, bed, 't95', 'tip'))}",
                    f"{_pct(duration_change(found, theta, bed, 't95', 'm95'))}",
                    f"{m.speed_end:.1e}",
                ]
            )
    # convergence of the 5 mm gains: change between the two finest meshes (percentage points)
    conv = []
    for theta in THETAS:
        g = {w: [gain(found, theta, BEDS[-1], n, w) for n in CELLS] for w in MEASURES}
        conv.append(
            [f"{theta:g}"]
            + [f"{(g[w][2] - g[w][1]) * 100:+.2f} / {(g[w][1] - g[w][0]) * 100:+.2f}" for w in MEASURES]
        )
    # linearity of the gain in the bed thickness above the critical slope (finest mesh)
    linear = []
    for theta in [t for t in THETAS if t > theta_c]:
        gains = np.array([gain(found, theta, b, finest, "tip") for b in bed_list])
        if np.all(np.isfinite(gains)):
            slope, offset = np.polyfit(np.array(bed_list) * 1000, gains, 1)
            residual = float(np.max(np.abs(gains - (slope * np.array(bed_list) * 1000 + offset))))
            linear.append([f"{theta:g}", f"{slope * 100:+.2f}", f"{residual * 100:.2f}"])

    # the shape of the deposit's end below theta_c: where it falls through 1-10 d above the bed
    taper = []
    for theta in [t for t in THETAS if t < theta_c]:
        for bed in (0.0, BEDS[-1]):
            m = found.get((theta, bed, finest))
            if isinstance(m, Measures):
                taper.append(
                    [
                        f"{theta:g}",
                        f"{bed * 1000:g}",
                        " / ".join(f"{m.tips[n]:.3f}" for n in TAPER),
                        f"{m.runout['m95']:.3f}",
                    ]
                )
    fig = Figure(figsize=(14, 4))
    axes = fig.subplots(1, 3)
    for k, theta in enumerate(THETAS):
        for ax, w in zip(axes[:2], MEASURES):
            ax.plot(
                np.array(bed_list) * 1000,
                [gain(found, theta, b, finest, w) * 100 for b in bed_list],
                "-o",
                color=f"C{k}",
                label=f"{theta:g} deg",
            )
    for ax, w in zip(axes[:2], MEASURES):
        ax.axhline(target * 100, color="k", ls=":", lw=0.8)
        ax.set_xlabel("erodible bed (mm)")
        ax.set_ylabel(f"run-out gain, {MEASURE_NAMES[w]} (%)")
    axes[0].legend(fontsize=7)
    for bed in (0.0, BEDS[-1]):
        m = found.get((22.0, bed, finest))
        if isinstance(m, Measures):
            axes[2].plot(m.t, m.tip, label=f"22 deg, {bed * 1000:g} mm")
    axes[2].set_xlabel("t (s)")
    axes[2].set_ylabel("tip from the column's front (m)")
    axes[2].legend(fontsize=7)
    image = ctx.figure(fig, figure)

    met_by = verdicts(found)
    header = [
        "theta (deg)",
        "bed (mm)",
        "run-out tip / m95, finest (m)",
        "gain tip, 3 meshes (%)",
        "gain m95, 3 meshes (%)",
        "stop / t95 by the tip (s)",
        "change of stop / t95, tip (%)",
        "change of t95, m95 (%)",
        "max speed at end (m/s)",
    ]
    verdict_rows = [
        [
            MEASURE_NAMES[w],
            f"{met(met_by[w][0])} (largest {worst_zero(found, w) * 100:.1f} %)",
            f"{met(met_by[w][1])} ({at_repose(found, w) * 100:+.1f} % against {target * 100:g} %)",
            met(met_by[w][2]),
        ]
        for w in MEASURES
    ]
    verdict_header = [
        "measure",
        f"zero within {ZERO:.0%} below theta_c",
        f"gain at {NEAR_REPOSE:g} deg, {BEDS[-1] * 1000:g} mm",
        "duration trend (t95)",
    ]
    return f"""{image}

{table(header, rows)}

**Convergence** of the 5 mm gain: change between the two finest meshes / between the two
coarsest (percentage points):

{table(["theta (deg)", "tip", "m95"], conv)}

**The end of the deposit below theta_c** (finest mesh): the tip at {" / ".join(f"{n:g}" for n in TAPER)}
grain diameters above the bed, and the mass front (m from the column's front):

{table(["theta (deg)", "bed (mm)", "tip (m)", "m95 (m)"], taper)}

**Linearity** in the bed thickness (the experiments: "almost linear"), tip, finest mesh:
slope of the least-squares line and the largest deviation from it:

{table(["theta (deg)", "gain per mm (%)", "largest deviation (%)"], linear)}

**Verdicts** (finest mesh):

{table(verdict_header, verdict_rows)}"""


def failures(found: dict[Key, Measures | str]) -> str:
    """The runs that failed, with their messages."""
    failed = [f"{k}: {v}" for k, v in found.items() if isinstance(v, str)]
    return f"Runs that failed: {'; '.join(failed) if failed else 'none'}."


def moving_fronts(found: dict[Key, Measures | str]) -> int:
    """How many finest-mesh runs have a front still moving at the end."""
    return sum(isinstance(m, Measures) and m.speed_end > 0.0 for k, m in found.items() if k[2] == CELLS[-1])


def targets_met(found: dict[Key, Measures | str]) -> int:
    """How many of the six verdicts (two measures, three criteria) are met."""
    return sum(sum(v) for v in verdicts(found).values())


def column_law_text() -> str:
    """The constants of the column-collapse configuration's law and their h_stop against
    the thickest bed."""
    glass = stopping.law()
    thin = [t for t in THETAS if glass.mu_1 < math.tan(math.radians(t)) and glass.h_stop(t) < BEDS[-1]]
    h_stops = ", ".join(
        f"{glass.h_stop(t) * 1000:.1f} mm at {t:g} deg"
        for t in THETAS
        if glass.mu_1 < math.tan(math.radians(t))
    )
    bed_verdict = (
        f"thinner than the {BEDS[-1] * 1000:g} mm bed at {', '.join(f'{t:g}' for t in thin)} deg, so with "
        "them the erodible bed, which stays at rest on its own in the experiments, would flow"
        if thin
        else "thicker than every bed of the study"
    )
    angles = f"{math.degrees(math.atan(glass.mu_1)):.1f}-{math.degrees(math.atan(glass.mu_2)):.2f}"
    return f"""The configuration chosen for the column collapse (`column_collapse_channel.yaml`) uses
`pouliquen_forterre` with the glass-bead constants of the stopping case
({stopping.source_text()}), whose h_stop is {h_stops}: {bed_verdict}.  Those constants
belong to other beads (friction angles {angles} deg, against the repose angle
{published.values(BEADS)["repose_angle"]:g} deg of these)."""


SHIPPED_TEXT = (
    "as shipped (the recommended configuration: Jop mu(I) with start/stop\nfriction, side walls, "
    "no-slip rigid bed, hydrostatic pressure, instantaneous release)"
)


def section(ctx: Context) -> str:
    found = measure_all(ctx, keys())
    stop = measure_all(ctx, keys(), with_stopping(ctx.scenarios))
    moving = moving_fronts(stop)
    creep = (
        f" (with the stopping thickness {moving} fronts of the finest mesh still move at the end)"
        if moving
        else " (with the stopping thickness no front of the finest mesh moves at the end)"
    )
    target = published.values(TARGETS)["largest_runout_gain"]
    worst = {w: worst_zero(found, w) for w in MEASURES}
    worst_stop = worst_zero(stop, "tip")
    below_c = [t for t in THETAS if t < critical_slope()]
    wedge = (
        "the stopping thickness does not remove the tip's loss; measured at "
        f"{TAPER[-1]:g} grain diameters it is "
        + " and ".join(f"{tip_change(stop, t, TAPER[-1]) * 100:+.1f} %" for t in below_c)
        + f" at {', '.join(f'{t:g}' for t in below_c)} deg, so which height above the bed the "
        "experiments' run-out is measured at (in the papers' methods) would decide whether the "
        "tip's target applies"
        if not zero_below_critical(stop, "tip")
        else "with the stopping thickness the tip meets its target"
    )
    repose = {w: at_repose(found, w) for w in MEASURES}
    return f"""## Erodible bed: three-mesh study against the experiments

{setup(found, SHIPPED_TEXT)}

{results(ctx, found, NAME)}

**Why not met.**  Below theta_c the tip loses up to {worst["tip"] * 100:.0f} % while the mass
front moves by {worst["m95"] * 100:.1f} % at most: on the rigid bed the deposit ends in a
taper {end_span(found, 0.0, 0.0) * 100:.1f} cm long between {TAPER[0]:g} and {TAPER[-1]:g} grain diameters
at 0 deg ({end_span(found, 10.0, 0.0) * 100:.1f} cm at 10 deg), over the {BEDS[-1] * 1000:g} mm bed in
{end_span(found, 0.0, BEDS[-1]) * 100:.1f} cm ({end_span(found, 10.0, BEDS[-1]) * 100:.1f} cm); measured at
{TAPER[-1]:g} grain diameters the change is {tip_change(found, 0.0, TAPER[-1]) * 100:+.1f} % at 0 deg and
{tip_change(found, 10.0, TAPER[-1]) * 100:+.1f} % at 10 deg.
Jop's mu(I) has no thickness below which flow stops, so on the rigid bed material keeps
spreading into a wedge a few grains thick, which real beads do not (Pouliquen 1999).  The
section [Erodible bed with a stopping thickness](#erodible-bed-with-a-stopping-thickness)
tests this with `pouliquen_forterre`, its constants chosen a priori for these beads: there
the tip changes by up to {worst_stop * 100:.1f} % below theta_c, the rigid-bed taper at 0 deg
is {end_span(stop, 0.0, 0.0) * 100:.1f} cm, and it meets {targets_met(stop)} of the 6 targets of the table
(this configuration: {targets_met(found)}): {wedge}.
Near the repose angle the measures give {repose["tip"] / target:.2f} and {repose["m95"] / target:.2f} of
the published {target:.0%} ({repose["tip"] * 100:+.1f} % and {repose["m95"] * 100:+.1f} %), converged
(no 5 mm gain moves by more than {largest_change(found) * 100:.1f} percentage points between the two
finest meshes): the shortfall is the model's, not the mesh's.  The published gain is an
upper bound over the study's slopes and beds; a per-slope comparison needs the values in
the papers' figures.  The time to 95 % of the run-out by the tip over the
{BEDS[-1] * 1000:g} mm bed grows at {slopes_where(found, lambda c: c > 0.0)} deg and falls at
{slopes_where(found, lambda c: c < 0.0)} deg; a front still moving at the end creeps at the speed
given in the last column{creep}.  What would be needed for the gain near the repose angle:
the published gains per slope and bed (in the papers' figures) and physics that neither
law has (the section cited above; the options of the section "Erodible bed with the
non-hydrostatic pressure and the normal stress" bring it no closer).

**The law of the column-collapse study.**  {column_law_text()}  The section "Erodible bed
with a stopping thickness" configures the law for these beads instead, from their own angles.

{failures(found)}
"""
