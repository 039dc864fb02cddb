"""The validation package on cheap cases: its data directory, its runs, its report, its
mesh-study rule (the cases themselves run under ``pytest -m validation``)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from multilayer.validation import published, report
from multilayer.validation.cases import SECTIONS
from multilayer.validation.mesh_study import MeshStudy
from multilayer.validation.runs import Context, Run


def test_every_data_file_has_its_source():
    """One data directory; every file in it listed in sources.yaml with a publication, where
    in it, and a status; every listed file present and readable."""
    listed = published.sources()
    files = {p.name for p in published.DATA.iterdir()} - {published.SOURCES.name}
    assert files == set(listed)
    for name, source in listed.items():
        assert source.source.strip() and source.where.strip(), name
        assert source.status in published.STATUSES, name
        assert source.status == "primary" or source.notes.strip(), f"{name}: say why it is not primary"
        values = published.values(name) if name.endswith(".yaml") else published.table(name)
        assert values and all(np.all(np.isfinite(v)) for v in values.values()), name


def test_a_csv_table_is_read_by_its_header(tmp_path, monkeypatch):
    (tmp_path / "fronts.csv").write_text("# a comment line\nt (s),x_f (m)\n0.0,0.2\n0.5,0.7\n")
    monkeypatch.setattr(published, "DATA", tmp_path)
    columns = published.table("fronts.csv")
    assert list(columns) == ["t (s)", "x_f (m)"]
    np.testing.assert_array_equal(columns["x_f (m)"], [0.2, 0.7])


def test_a_source_is_cited_with_its_status_unless_primary():
    read = published.Source("A & B (2001), J. 1, 2", "table 3", "primary")
    quoted = published.Source("C (2002)", "fig. 4", "secondary", "quoted by D (2010)")
    assert read.cite() == "A & B (2001), J. 1, 2, table 3"
    assert quoted.cite() == "C (2002), fig. 4; secondary: quoted by D (2010)"


def test_the_digitised_collapse_figure_is_read_in_time_order_with_its_sources():
    """The figure of Rondon et al. (2011) as digitised: each curve in time order and cited as
    read off a figure; its loose column runs out further and faster than its dense one, with
    the published signs of the pore pressure below them (rondon2011_collapse.yaml)."""
    from multilayer.validation.cases import submarine_collapse as case

    for files in case.FIGURE.values():
        for name in files:
            assert published.source(name).status == "digitised", name
            assert "Kumar (2015)" in published.source(name).where, name
            assert np.all(np.diff(published.table(name)["t (s)"]) > 0.0), name
    loose, dense = (case.figure_measures(p) for p in case.PACKINGS)
    assert loose["runout"] > case.RUNOUT_RATIO * dense["runout"]
    assert dense["t95"] > case.DURATION_RATIO * loose["t95"]
    signs = published.values("rondon2011_collapse.yaml")
    assert math.copysign(1.0, loose["pressure"]) == signs["pore_pressure_sign_loose"]
    assert math.copysign(1.0, dense["pressure"]) == signs["pore_pressure_sign_dense"]


def test_the_immersed_layers_curves_are_read_in_their_units_with_their_source():
    """The numbers read off the digitised curves of Pailha et al. (2008): cited as digitised,
    with the units' evidence (SedFoam's plotting script) and the uncertainty unknown; every
    number inside the axes that script plots the files on (t / sqrt(d/g) to 160000,
    v / sqrt(g d) to 0.03 with v in mm/s, |p| / (rho_f g h) to 0.12 with p in Pa); the fixed
    times inside each record and below the onset speed before a resolved onset; the onsets
    rising with phi0, as the records show them; the extremes' signs those of the loosest and
    densest layers as published (pailha2008_immersed_layer.yaml)."""
    from multilayer.validation.cases import immersed_layer as case

    d, g, rho_f, h = 160e-6, 9.81, 1041.0, 0.0049
    for name in (case.ONSETS, case.SPEEDS):
        cited = published.source(name)
        assert cited.status == "digitised"
        assert "plot_tuto1DWetAvalanche.py" in cited.notes and "uncertainty is unknown" in cited.notes
    m = case.measured()
    assert sorted(m) == list(case.PHI0S)
    assert np.all(np.diff([m[p].onset for p in case.PHI0S]) > 0.0)
    for phi0, r in m.items():
        assert r.first <= r.onset <= r.last and r.p_first <= r.p_extreme_at <= r.p_last, phi0
        assert max(r.last, r.p_last) < 160000 * math.sqrt(d / g), phi0
        assert abs(r.p_extreme) < 0.12 * rho_f * g * h, phi0
        assert r.speeds and all(r.first <= t <= r.last for t in r.speeds), phi0
        assert all(0.0 <= v < 0.03 * math.sqrt(g * d) for v in r.speeds.values()), phi0
        assert all(v < case.ONSET_SPEED for t, v in r.speeds.items() if r.resolved and t < r.onset), phi0
    signs = published.values(case.DATA)
    assert math.copysign(1.0, m[case.PHI0S[0]].p_extreme) == signs["pore_pressure_sign_loose"]
    assert math.copysign(1.0, m[case.PHI0S[-1]].p_extreme) == signs["pore_pressure_sign_dense"]


def test_the_tolerance_rule_passes_the_file_and_fails_a_twice_coarser_mesh():
    study = MeshStudy((100, 200, 400), (0.04, 0.02, 0.01))
    assert study.orders() == pytest.approx([1.0, 1.0])
    assert study.separates(200, 0.03) and not study.separates(200, 0.05) and not study.separates(200, 0.02)
    assert math.isnan(study.error(800)) and not study.separates(800, 0.01)


def test_runs_are_reused_while_their_scenario_is_unchanged(tmp_path):
    ctx = Context(runs=tmp_path)
    run = Run("static_10", "static_flowing_interface", ("domain.layers=10", "time.end=0.02"))
    first = ctx.execute([run])[run.name]
    assert not isinstance(first, str) and first.sizes["layer"] == 10
    stamp = (tmp_path / "static_10" / "result.nc").stat().st_mtime_ns
    ctx.execute([run])
    assert (tmp_path / "static_10" / "result.nc").stat().st_mtime_ns == stamp
    changed = Run("static_10", "static_flowing_interface", ("domain.layers=10", "time.end=0.04"))
    again = ctx.execute([changed])[run.name]
    assert not isinstance(again, str) and float(again["time"][-1]) == pytest.approx(0.04)
    with pytest.raises(ValueError, match="share a name"):
        ctx.execute([run, changed])


def test_report_keeps_the_sections_not_regenerated(tmp_path):
    path = tmp_path / "validation.md"
    names = list(SECTIONS)
    report.write(path, "# Intro\n", {names[0]: "## First\n\nold\n"}, "regen", "## How\n")
    assert report.read(path) == {
        names[0]: "## First\n\nold\n",
        **{n: f"## {n}\n\nNot generated yet: run `regen {n}`.\n" for n in names[1:]},
    }
    text = path.read_text()
    assert text.startswith("# Intro\n") and text.count("<!-- /section -->") == len(names)
    assert text.endswith("<!-- /section -->\n\n## How\n")  # the closing text after the sections
    report.write(path, f"# Intro\n\n{report.CONTENTS}\n", {names[0]: "## First: a case (1)\n"}, "r")
    assert path.read_text().startswith(f"# Intro\n\n- [First: a case (1)](#first-a-case-1)\n- [{names[1]}]")


def test_report_command_refuses_unknown_sections(capsys):
    with pytest.raises(SystemExit) as exit_:
        report.main(
            ["nonsense"], description="", report=Path("unused.md"), runs=Path("r"), intro="", command="c"
        )
    assert exit_.value.code == 2
    assert "unknown section(s) nonsense; accepted: static" in capsys.readouterr().err


def test_time_step_study_changes_orders_and_signs():
    """The helpers of the immersed-layer section on made-up levels: relative changes, the
    observed order of three levels halving the step, the published signs over a run."""
    from multilayer.validation.cases import immersed_layer as case
    from multilayer.validation.mesh_study import difference_orders

    values = [1.0 + 0.08, 1.0 + 0.04, 1.0 + 0.02, 1.0 + 0.01]  # first-order error 0.08 dt
    assert case.changes(values) == pytest.approx([0.04 / 1.08, 0.02 / 1.04, 0.01 / 1.02])
    assert difference_orders(values) == pytest.approx([1.0, 1.0])
    assert math.isnan(difference_orders([1.0, 1.0, 2.0])[0])
    loose = {"pressure_range": (0.5, 2.0)}
    dense = {"pressure_range": (-2.0, -0.5)}
    assert case.signs_met({("loose", 0.45): loose, ("dense", 0.45): dense})
    assert not case.signs_met({("loose", 0.45): loose, ("dense", 0.45): {"pressure_range": (-2.0, 0.1)}})
