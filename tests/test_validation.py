"""Full-resolution validation against the references that the model meets.

Marked ``validation``: deselected by default, run with ``python -m pytest -m validation``.
Each test runs the runs of a case of :mod:`multilayer.validation` (into a temporary
directory) and asserts the criteria of that case that docs/validation.md reports as met;
the criteria and their thresholds are the case's own, so the report and the tests cannot
disagree.
"""

from __future__ import annotations

import pytest

from multilayer.validation.cases import (
    bagnold,
    chute,
    collapse_channel,
    column_collapse,
    dam_break,
    erodible_bed,
    erodible_stopping,
    erodible_study,
    immersed_layer,
    static_interface,
    stopping,
    submarine_collapse,
    well_posedness,
)
from multilayer.validation.mesh_study import MeshStudy, file_comparison
from multilayer.validation.runs import Context

pytestmark = pytest.mark.validation


@pytest.fixture(scope="module")
def ctx(tmp_path_factory: pytest.TempPathFactory) -> Context:
    return Context(runs=tmp_path_factory.mktemp("validation"))


# --------------------------------------------------------------------------- static/flowing


@pytest.mark.parametrize("theta", static_interface.THETAS)
def test_inviscid_interface_follows_the_exact_solution(ctx, theta):
    """Bouchut, Ionescu & Mangeney (2016), Prop. 2.2: b(t) = b0 + S t / 70 within one layer,
    and the column exactly at rest (u == 0) from the exact stop time on."""
    r = static_interface.run(theta, "inviscid")
    ds = ctx.execute([r])[r.name]
    assert not isinstance(ds, str), ds
    run = static_interface.Interface.of(ds)
    assert static_interface.follows_exact_interface(run, static_interface.reference(ctx, theta))


def test_viscosity_makes_the_interface_erode_first(ctx):
    """With a viscosity the interface first drops (erosion), then rises (deposition)."""
    runs = [
        static_interface.run(theta, law) for theta in static_interface.THETAS for law in ("viscous", "mu(I)")
    ]
    results = ctx.execute(runs)
    for r in runs:
        ds = results[r.name]
        assert not isinstance(ds, str), ds
        assert static_interface.erodes_first(static_interface.Interface.of(ds)), r.name


def test_layer_velocities_within_their_error_bound_and_the_file_tolerance_justified(ctx):
    """The file's comparison with the exact solution at 10 to 160 layers is within the
    bound of the layer discretisation, and its tolerance passes its resolution and fails a
    twice coarser one."""
    results = ctx.execute([static_interface.layer_run(n) for n in static_interface.LAYERS])
    levels = static_interface.layer_study(ctx, results)
    assert static_interface.within_bound(levels)
    file = ctx.load(static_interface.SCENARIO)
    study = MeshStudy(tuple(lv.layers for lv in levels), tuple(lv.error for lv in levels))
    assert study.separates(file.domain.layers, file_comparison(file).tolerance)


# --------------------------------------------------------------------------- dam breaks


@pytest.mark.parametrize("case", dam_break.CASES)
def test_dam_break_converges_at_first_order_and_conserves_mass(ctx, case):
    """Mangeney, Heinrich & Roche (2000) and Ritter (1892): the relative L1 error of h
    falls at an order of at least 0.9 between every pair of 100-1600 cells."""
    results = ctx.execute([dam_break.run(case, n) for n in dam_break.CELLS])
    levels = dam_break.levels(ctx, results, case)
    assert dam_break.converges(dam_break.study(levels))
    assert dam_break.conserves_mass(levels)


def test_dam_break_file_tolerance_is_justified(ctx):
    results = ctx.execute([dam_break.run("coulomb", n) for n in dam_break.CELLS])
    study = dam_break.study(dam_break.levels(ctx, results, "coulomb"))
    cells, tolerance = dam_break.file_tolerance(ctx)
    assert study.separates(cells, tolerance)


# --------------------------------------------------------------------------- Bagnold


def test_h_stop_is_exact_and_the_flow_rule_is_met_under_layer_refinement(ctx):
    """Layers 0.1 % below h_stop(theta) stay at u == 0.0, 0.1 % above flow; the steady
    Froude number converges to beta h / h_stop (pouliquen_forterre, docs/validation.md)."""
    results = ctx.execute([*stopping.rest_runs(), *stopping.flow_runs()])
    assert stopping.rest_met(results)
    assert stopping.flow_rule_met(results)


def test_bagnold_profile_converges_and_the_file_tolerance_is_justified(ctx):
    """Tsang et al. (2019), eq. 4.1: the layer velocities converge to Bagnold's profile."""
    levels = bagnold.levels(ctx, ctx.execute([bagnold.run(n) for n in bagnold.LAYERS]))
    assert bagnold.converges(levels)
    file = ctx.load(bagnold.SCENARIO)
    study = MeshStudy(tuple(lv.layers for lv in levels), tuple(lv.error for lv in levels))
    assert study.separates(file.domain.layers, file_comparison(file).tolerance)


# --------------------------------------------------------------------------- chute


def _chute(ctx: Context, case: str) -> chute.Analysis:
    r = chute.runs(ctx.load(chute.SCENARIO))[(case, "440")]
    ds = ctx.execute([r])[r.name]
    assert not isinstance(ds, str), ds
    return chute.analyse(ds, r.load(ctx.scenarios))


BLASIUS_CASES = pytest.mark.parametrize("case", ["alpha034", "alpha1_level"])


@BLASIUS_CASES
def test_granular_blasius_layer_grows_like_x_to_the_one_over_one_plus_alpha(ctx, case):
    """Tsang et al. (2019), eq. 4.13 and 4.15-4.17: delta* = zeta_disp eps H (x/H)^(1/(1+alpha)),
    exponent and size without a fitted constant.  Not asserted: alpha = 1 on the 16 deg
    chute, whose exponent falls short (docs/validation.md)."""
    a = _chute(ctx, case)
    assert chute.follows_exponent(a, "slope_fixed")
    assert chute.has_predicted_size(a)


@BLASIUS_CASES
def test_shape_factor_excess_grows_like_x_to_the_one_over_one_plus_alpha(ctx, case):
    """Tsang et al. (2019), eq. 4.26 (sec. 4.6, 5.4): chi - 1 proportional to x^(1/(1+alpha))
    while the layer is thin."""
    assert chute.follows_exponent(_chute(ctx, case), "chi_fixed")


def test_chute_file_within_the_accuracy_of_the_leading_order_theory(ctx):
    """The file's comparison of delta* with the similarity solution is within delta*/H at the
    end of its window (the order the theory neglects) at 110 to 880 cells."""
    results = ctx.execute([chute.file_run(n) for n in chute.FILE_CELLS])
    scenario = ctx.load(chute.SCENARIO)
    assert chute.tolerance_is_theory_order(scenario)
    assert chute.within_theory(chute.file_study(ctx, results), file_comparison(scenario).tolerance)


def test_jop_law_at_its_alpha_minus_one_asymptote_forms_no_wall_layer(ctx):
    """Tsang et al. (2019), sec. 4.5: for I >> I_0 the Jop law admits no self-similar layer."""
    scenario = chute.runs(ctx.load(chute.SCENARIO))[("jop_tiny_i0", "440")].load(ctx.scenarios)
    metrics = chute.jop_metrics({("jop_tiny_i0", "440"): _chute(ctx, "jop_tiny_i0")}, "jop_tiny_i0", scenario)
    assert chute.no_wall_layer(metrics, scenario.rheology.params["I_0"])


# --------------------------------------------------------------------------- column collapse


def _collapses(ctx: Context, pressure: str) -> dict[float, column_collapse.Collapse]:
    runs = {a: column_collapse.run(pressure, a) for a in column_collapse.RATIOS}
    results = ctx.execute(list(runs.values()))
    gravity = ctx.load(column_collapse.SCENARIO).gravity
    out = {}
    for a, r in runs.items():
        ds = results[r.name]
        assert not isinstance(ds, str), ds
        out[a] = column_collapse.Collapse.of(ds, a, gravity)
    return out


@pytest.mark.parametrize("pressure", ["hydrostatic", "non_hydrostatic"])
def test_collapse_stops_within_the_experiments_duration(ctx, pressure):
    """The front stops within 20 % of 3 sqrt(H0/g) at every aspect ratio on the 4 mm cells of
    the section (one resolution and an unverified factor: a property of these runs that the
    section reports, not a verdict; docs/validation.md)."""
    assert column_collapse.stops_in_time(_collapses(ctx, pressure))


def test_non_hydrostatic_collapse_runout_grows_with_the_laws_exponent(ctx):
    """The run-out exponent beyond the glass beads' law's transition within 0.15 of 2/3 on the
    4 mm cells of the section (one resolution: a property of these runs that the section
    reports, not a verdict; the size is not within 15 % at a = 10 on the finest mesh)."""
    assert column_collapse.follows_exponent(_collapses(ctx, "non_hydrostatic"))


def test_channel_collapse_rests_exactly_and_its_verdicts_are_settled_by_the_mesh(ctx):
    """The recommended channel collapse on four meshes: every deposit exactly at rest, the
    volume conserved, and at every aspect ratio the change of the tip run-out between the two
    finest meshes smaller than its distance to the 15 % band (the verdict, not met, does not
    depend on the mesh; docs/validation.md)."""
    runs = {
        (a, dx): collapse_channel.run(a, dx) for a in collapse_channel.RATIOS for dx in collapse_channel.CELLS
    }
    scenario = ctx.load(collapse_channel.SCENARIO)
    failures: list[str] = []
    measured = collapse_channel.deposits(
        ctx.execute(list(runs.values())), runs, scenario.material.grain_diameter, scenario.gravity, failures
    )
    assert not failures, failures
    tips: dict[float, dict[float, float]] = {}
    for (a, dx), d in measured.items():
        assert d.speed == 0.0 and abs(d.mass_change) < 1e-12
        tips.setdefault(a, {})[dx] = d.tip
    glass_beads = collapse_channel.LAWS[collapse_channel.REFERENCE]
    for a, values in tips.items():
        assert collapse_channel.verdict(values, collapse_channel.law(a, glass_beads))[1], a


def test_channel_collapse_with_the_normal_stress_conserves_volume_and_rests_exactly(ctx):
    """The recommended channel collapse with model.normal_stress on four meshes: the volume
    conserved and every deposit exactly at rest at the end, held by its friction and its
    normal stress together (docs/model.md, "Rest of the two together")."""
    c = collapse_channel
    runs = {(a, dx): c.run(a, dx, c.STRESSED) for a in c.RATIOS for dx in c.STRESSED_CELLS}
    scenario = ctx.load(c.SCENARIO)
    failures: list[str] = []
    measured = c.deposits(
        ctx.execute(list(runs.values())), runs, scenario.material.grain_diameter, scenario.gravity, failures
    )
    assert not failures, failures
    for d in measured.values():
        assert abs(d.mass_change) < 1e-12
        assert d.speed == 0.0


# --------------------------------------------------------------------------- erodible bed


def test_erodible_bed_lengthens_the_runout_with_mu_i_and_start_stop_friction(ctx):
    """Mangeney et al. (2010), Farin et al. (2014), Fernandez-Nieto et al. (2016): the run-out
    grows with the erodible-bed thickness at 19, 22, 23 deg, flat or growing at 16 deg."""
    keys = [
        (erodible_bed.RECOMMENDED, theta, bed)
        for theta in (erodible_bed.NOT_SHORTER, *erodible_bed.GROWING)
        for bed in erodible_bed.BEDS
    ]
    measures, failed = erodible_bed.measure_all(ctx, keys)
    assert not failed
    assert erodible_bed.grows_with_the_bed(erodible_bed.trends(measures))


def test_pure_coulomb_friction_reverses_the_trend(ctx):
    """Fernandez-Nieto et al. (2016): with a constant friction coefficient the erodible bed
    shortens the run-out at 16 and 19 deg."""
    keys = [("pure Coulomb", theta, bed) for theta in erodible_bed.REVERSED for bed in erodible_bed.BEDS]
    measures, failed = erodible_bed.measure_all(ctx, keys)
    assert not failed
    assert erodible_bed.reverses_with_coulomb(erodible_bed.trends(measures))


def test_mass_front_sees_no_effect_of_the_bed_below_the_critical_slope(ctx):
    """Mangeney et al. (2010): no effect of the erodible bed below theta_c ~ theta_r / 2; the
    95 % mass front of the finest mesh moves by less than 5 % at 0 and 10 deg."""
    below = tuple(t for t in erodible_study.THETAS if t < erodible_study.critical_slope())
    found = erodible_study.measure_all(ctx, erodible_study.keys(below))
    assert not [v for v in found.values() if isinstance(v, str)]
    assert erodible_study.zero_below_critical(found, "m95")


def test_the_erodible_bed_stays_at_rest_with_the_stopping_law(ctx):
    """Mangeney et al. (2010): the 5 mm bed alone at rest at every slope of the study; with
    the a-priori ``pouliquen_forterre`` law exactly (u == 0.0 at every output)."""
    assert all(v == 0.0 for v in erodible_stopping.bed_speeds(ctx).values())


def test_mass_front_sees_no_effect_of_the_bed_below_the_critical_slope_with_the_stopping_law(ctx):
    """As above with the a-priori ``pouliquen_forterre`` law: the 95 % mass front of the
    finest mesh moves by less than 5 % at 0 and 10 deg."""
    below = tuple(t for t in erodible_study.THETAS if t < erodible_study.critical_slope())
    found = erodible_study.measure_all(ctx, erodible_study.keys(below), erodible_study.with_stopping())
    assert not [v for v in found.values() if isinstance(v, str)]
    assert erodible_study.zero_below_critical(found, "m95")


# --------------------------------------------------------------------------- well-posedness


@pytest.mark.parametrize("theta", well_posedness.STEADY_SLOPES)
def test_regularised_law_flows_as_bagnold_at_its_own_inertial_number(ctx, theta):
    """Barker & Gray (2017): the steady uniform flow of the regularised law is Bagnold's
    profile at the I_theta of its low branch (26 deg) or of Jop's law (30 deg)."""
    found = well_posedness.steady(ctx, theta, well_posedness.STEADY_LAYERS[-1])
    assert found.error < well_posedness.MAX_STEADY_ERROR


# --------------------------------------------------------------------------- submarine collapse


def test_loose_column_runs_further_than_dense_with_the_published_pore_pressure_signs(ctx):
    """Rondon, Pouliquen & Aussillous (2011): the loose column's run-out at least 1.5 times
    the dense one's, with positive against negative basal excess pore pressure, at every
    resolution of the case; the dense collapse at least twice as long (to stop: a lower
    bound where its wedge still creeps at the end; and to 95 % of the run-out) at the
    shipped files' resolution, the first of the case.  On the finest meshes the loose
    deposit creeps for longer and the durations are not converged (docs/validation.md,
    reported there as not met)."""
    m = submarine_collapse.measures(ctx)
    assert len(m) == 2 * len(submarine_collapse.CELLS)
    for n in submarine_collapse.CELLS:
        assert submarine_collapse.ratios(m, n)[0] >= submarine_collapse.RUNOUT_RATIO
        assert submarine_collapse.signs_met(m, n)
    _, stop, t95 = submarine_collapse.ratios(m, submarine_collapse.CELLS[0])
    assert min(stop, t95) >= submarine_collapse.DURATION_RATIO


# --------------------------------------------------------------------------- immersed layer


def test_immersed_layer_files_have_the_published_signs_at_every_step(ctx):
    """Pailha et al. (2008) as the abstracts describe them: positive basal excess pore
    pressure in the loose file, negative in the dense one, at every output time of every
    step of the study; the values at 5 s independent of the step."""
    m = immersed_layer.scenario_measures(ctx)
    assert len(m) == len(immersed_layer.PACKINGS) * len(immersed_layer.CFLS)
    assert immersed_layer.signs_met(m)
    assert all(immersed_layer.step_independent(m, p) for p in immersed_layer.PACKINGS)


@pytest.mark.parametrize("phi0", immersed_layer.PHI0S)
def test_uniform_layers_start_and_press_as_published(phi0):
    """Loose layers start within one 1/gamma, dense ones after ten and then flow; the early
    pore pressure has the published sign (Radau IIA at rtol 1e-10)."""
    u = immersed_layer.uniform(phi0)
    assert immersed_layer.start_met(u) and immersed_layer.sign_met(u), (u.packing, u.onset, u.pressure)


def test_uniform_layers_start_when_the_experiments_curves_do():
    """Against the numbers read off the digitised curves of Pailha et al. (2008) (Radau IIA at
    rtol 1e-10, the model's surface velocity): every onset within a factor 2 of a resolved
    measured one, or before the record's first time where that only bounds it, and every order
    of two onsets the records establish.  The velocity, the sign and the magnitude of the pore
    pressure are not met at every fraction: docs/validation.md reports them."""
    data = immersed_layer.measured()
    comparisons = [immersed_layer.compare(immersed_layer.uniform(p), data[p]) for p in immersed_layer.PHI0S]
    assert all(c.onset_met() for c in comparisons), [(c.data.phi0, c.onset) for c in comparisons]
    assert immersed_layer.order_met(comparisons)
