"""The ``multilayer`` command: exit codes, messages for every class of invalid input,
and the round trip scenario -> result.nc."""

from __future__ import annotations

import contextlib
import json
import math
import signal
import subprocess
import sys
import warnings
from pathlib import Path

import fipy
import numpy as np
import pytest
import xarray as xr
import yaml

import multilayer
from multilayer.app import runner
from multilayer.app.commands.run import summary_lines
from multilayer.errors import RunError

DELETE = object()


def set_key(data, path, value):
    """``data`` with ``path`` (dotted) set to ``value``; ``value=DELETE`` removes the key."""
    *parents, last = [int(p) if p.isdigit() else p for p in path.split(".")]
    for part in parents:
        data = data[part]
    if value is DELETE:
        del data[last]
    else:
        data[last] = value


# (case, edits applied to the tiny scenario, key path in the message, text in the message)
INVALID = [
    ("unknown key", {"gravty": 9.8}, "gravty", "unknown key; accepted: name, description"),
    ("unknown nested key", {"domain.cellz": 10}, "domain.cellz", "accepted: x_min, x_max, cells"),
    ("wrong type", {"domain.cells": "ten"}, "domain.cells", "valid integer (got 'ten')"),
    ("missing key", {"time.end": DELETE}, "time.end", "required key is missing"),
    ("negative density", {"material.density": -1500.0}, "material.density", "greater than 0"),
    (
        "negative thickness",
        {"initial.0": {"shape": "layer", "thickness": -0.01}},
        "initial.0.thickness",
        "accepted: a number >= 0 (m); 0: no layer",
    ),
    ("layers < 1", {"domain.layers": 0}, "domain.layers", "accepted: an integer from 1 to 100000"),
    ("cfl >= 1", {"time.cfl": 1.0}, "time.cfl", "accepted: a number in (0, 1)"),
    ("cfl <= 0", {"time.cfl": 0.0}, "time.cfl", "accepted: a number in (0, 1)"),
    (
        "fractions not summing to 1",
        {"domain.layer_fractions": [0.2, 0.3, 0.4]},
        "domain.layer_fractions",
        "fractions sum to 0.9",
    ),
    ("domain x_min >= x_max", {"domain.x_max": 0.0}, "domain.x_max", "x_max = 0.0 is not > x_min = 0.0"),
    (
        "rectangle x_min >= x_max",
        {"initial.0.x_min": 0.3},
        "initial.0.x_max",
        "x_max = 0.1 is not > x_min = 0.3",
    ),
    (
        "unknown basal condition",
        {"base": [{"condition": "sticky"}]},
        "base.0.condition",
        "got 'sticky'; accepted: no_slip, coulomb (with mu) or free_slip",
    ),
    (
        "coulomb without mu",
        {"base": [{"condition": "coulomb"}]},
        "base.0.mu",
        "condition coulomb requires mu",
    ),
    (
        "unknown boundary type",
        {"boundaries.right": "open"},
        "boundaries.right",
        "accepted: wall, outflow, inflow or periodic",
    ),
    (
        "periodic on one side",
        {"boundaries.left": "periodic"},
        "boundaries.right",
        "periodic must be set on both sides",
    ),
    (
        "inflow without its state",
        {"boundaries.left": "inflow"},
        "boundaries.inflow",
        "an inflow side requires boundaries.inflow",
    ),
    (
        "walls without width",
        {"walls": {"name": "wall_friction", "mu_w": 0.2}},
        "walls",
        "walls need the channel width domain.width",
    ),
    (
        "unknown rheology name",
        {"rheology.name": "bingam"},
        "rheology.name",
        "unknown rheology 'bingam'; accepted: dilatant_coulomb, drucker_prager, jop_mu_i, "
        "pouliquen_forterre, power_law_mu_i",
    ),
    (
        "walls law used for the bulk",
        {"rheology": {"name": "wall_friction", "mu_w": 0.2}},
        "rheology.name",
        "'wall_friction' applies to walls, not bulk",
    ),
    (
        "unknown rheology parameter",
        {"rheology.mu_2": 0.6},
        "rheology.mu_2",
        "unknown parameter of drucker_prager; accepted: "
        "drucker_prager(mu_s: float, nu: float, mu_start: float | None = None)",
    ),
    (
        "wrong rheology parameter type",
        {"rheology.nu": "thick"},
        "rheology.nu",
        "drucker_prager: Input should be a valid number (got 'thick')",
    ),
    (
        "invalid rheology parameter value",
        {"rheology.nu": -0.01},
        "rheology",
        "drucker_prager: nu must be >= 0, got -0.01",
    ),
    (
        "expect without tolerance",
        {"expect": [{"kind": "regression", "quantity": "runout", "value": 0.1}]},
        "expect.0.rtol",
        "needs a tolerance",
    ),
    (
        "unknown expect quantity",
        {"expect": [{"kind": "regression", "quantity": "speed", "value": 1, "rtol": 0.1}]},
        "expect.0.quantity",
        "accepted: front_final, mass_final, runout",
    ),
]


@pytest.mark.parametrize("case, edits, key, text", INVALID, ids=[c[0] for c in INVALID])
def test_invalid_scenario_exits_2(cli, tiny_scenario, write_scenario, case, edits, key, text):
    for path, value in edits.items():
        set_key(tiny_scenario, path, value)
    scenario = write_scenario(tiny_scenario)
    for command in ("validate", "run"):
        result = cli(command, scenario)
        assert result.code == 2, result.err
        assert "Traceback" not in result.err
        assert result.err.startswith(f"multilayer: error: {scenario}: {key} (line ")
        assert text in result.err


def test_malformed_yaml_gives_the_line(cli, write_scenario):
    path = write_scenario("name: broken\ndomain:\n  x_min: 0\n   x_max: 1\n")
    result = cli("validate", path)
    assert result.code == 2 and "Traceback" not in result.err
    assert f"{path} (line 4, column 9): malformed YAML" in result.err


def test_missing_file(cli, tmp_path):
    result = cli("run", tmp_path / "nope.yaml")
    assert result.code == 2
    assert (
        result.err == f"multilayer: error: {tmp_path / 'nope.yaml'}: file not found; "
        "accepted: a path to a scenario YAML file\n"
    )


def test_output_directory_that_cannot_be_created(cli, tiny_scenario, write_scenario, tmp_path):
    """-o below a regular file: exit 2, the path named, no traceback, no result left."""
    path = write_scenario(tiny_scenario)
    blocker = tmp_path / "a-file"
    blocker.write_text("not a directory")
    result = cli("run", path, "-o", blocker / "out")
    assert result.code == 2 and "Traceback" not in result.err
    assert str(blocker / "out") in result.err
    assert "accepted: an output directory (-o DIR or output.directory)" in result.err
    assert not (blocker / "out").exists()


def test_a_wrong_thread_variable_stops_the_run_before_its_first_step(
    cli, tiny_scenario, write_scenario, tmp_path, monkeypatch
):
    """exit 2, the variable and what it accepts named, in the run's log too; no result."""
    variable, value = "MULTILAYER_THREADS", "two"
    monkeypatch.setenv(variable, value)
    out = tmp_path / "out"
    result = cli("run", write_scenario(tiny_scenario), "-o", out)
    assert result.code == 2 and "Traceback" not in result.err
    assert f"environment variable {variable}={value!r}; accepted: " in result.err
    assert f"ERROR environment variable {variable}={value!r}" in (out / "run.log").read_text()
    assert not (out / "result.nc").exists()


def test_unknown_set_key(cli, tiny_scenario, write_scenario):
    path = write_scenario(tiny_scenario)
    result = cli("run", path, "--set", "domain.cellz=10")
    assert result.code == 2 and "Traceback" not in result.err
    assert f"{path}: domain.cellz (from --set): unknown key; accepted: x_min, x_max, cells" in result.err
    result = cli("run", path, "--set", "initial.4.height=1")
    assert result.code == 2 and "--set initial.4.height: initial has 1 entries" in result.err


def test_validate_reports_every_file(cli, tiny_scenario, write_scenario):
    good = write_scenario(tiny_scenario, "good.yaml")
    tiny_scenario["domain"]["cells"] = 0
    bad = write_scenario(tiny_scenario, "bad.yaml")
    result = cli("validate", good, bad)
    assert result.code == 2
    assert f"{good}: ok (tiny: 40 cells x 3 layers, rheology drucker_prager" in result.out
    assert f"{bad}: domain.cells (line " in result.err
    assert cli("validate", good).code == 0


def test_console_script_exit_code_without_traceback(tmp_path):
    """The installed ``multilayer`` script, as a separate process."""
    path = tmp_path / "bad.yaml"
    path.write_text("name: [unclosed\n")
    result = subprocess.run(
        [sys.executable, "-m", "multilayer", "validate", str(path)], capture_output=True, text=True
    )
    assert result.returncode == 2
    assert "Traceback" not in result.stderr and "malformed YAML" in result.stderr


def test_version_help_and_plugins(cli):
    result = cli("--version")
    assert result.code == 0
    assert result.out.startswith(f"multilayer {multilayer.__version__} (commit ")
    assert result.out.endswith(f"; FiPy {fipy.__version__})\n")
    result = cli("--help")
    assert result.code == 0 and all(c in result.out for c in ("run", "validate", "plugins"))
    result = cli("plugins")
    assert result.code == 0
    assert "jop_mu_i [bulk]: Jop et al. (2006) mu(I)" in result.out
    assert (
        "parameters: jop_mu_i(mu_s: float, mu_2: float, I_0: float, mu_start: float | None = None, "
        "mu_inf: float = 0.0)" in result.out
    )
    assert "wall_friction [walls]" in result.out
    assert cli("frobnicate").code == 2  # argparse usage error


def test_a_command_imports_its_own_module_only():
    """``multilayer run`` parses its arguments as the full parser does, without importing
    the other commands' modules (``validate`` and ``check`` hold the exact solutions and
    SciPy's integrators, a fifth of a second at every start)."""
    code = (
        "import sys\n"
        "from multilayer.app import cli\n"
        "argv = ['run', 'a.yaml', '--set', 'time.end=1', '-q']\n"
        "mine = cli.build_parser(cli._command(argv)).parse_args(argv)\n"
        "loaded = sorted(m for m in sys.modules if m.startswith('multilayer.app.commands.'))\n"
        "print(loaded, 'multilayer.app.exact_solutions' in sys.modules)\n"
        "full = cli.build_parser().parse_args(argv)\n"
        "print(vars(mine) == vars(full))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.splitlines() == ["['multilayer.app.commands.run'] False", "True"]


def test_validate_imports_neither_xarray_nor_scipys_integrators():
    """``validate`` of a scenario without an exact comparison needing them imported xarray
    (for a type annotation) and SciPy's integrators (the granular Blasius solution's), two
    thirds of its 0.9 s: it checks the scenario without them."""
    code = (
        "import sys\n"
        "from multilayer.app.cli import main\n"
        "try:\n"
        "    main(['validate', 'scenarios/erodible_bed_collapse.yaml'])\n"
        "except SystemExit as exit:\n"
        "    assert not exit.code, exit.code\n"
        "print(sorted(m for m in ('xarray', 'scipy.integrate', 'fipy', 'numba') if m in sys.modules))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        cwd=Path(__file__).resolve().parents[1],
    )
    assert result.stdout.splitlines()[-1] == "[]", result.stdout


@pytest.mark.parametrize(
    "argv, command",
    [
        (["run", "a.yaml"], "run"),
        (["--version"], None),
        (["-h", "plot"], "plot"),
        (["runs"], None),
        ([], None),
    ],
)
def test_the_command_is_the_first_word_that_is_not_an_option(argv, command):
    from multilayer.app.cli import _command

    assert _command(argv) == command


@pytest.mark.parametrize(
    "words, value",
    [
        (["--at", "-1e308"], {"at": [-1e308]}),
        (["--at", "-inf", "--at", "-.5"], {"at": [-math.inf, -0.5]}),
        (["--xlim", "-1e-2", "-2E-3"], {"xlim": [-1e-2, -2e-3]}),
    ],
)
def test_a_negative_number_in_any_notation_is_read_as_the_value_of_its_option(words, value):
    """argparse read ``-1e308``, ``-inf``, ``-.5`` as options ("expected one argument"), where
    ``--at=-1e308`` worked: the value is then checked as any other (a position in the domain)."""
    from multilayer.app.cli import build_parser

    args = build_parser("plot").parse_args(["plot", ".", *words])
    assert {key: getattr(args, key) for key in value} == value


@pytest.mark.parametrize("error, code", [(RunError("solver diverged"), 1), (KeyboardInterrupt(), 130)])
def test_run_failures_exit_codes(cli, tiny_scenario, write_scenario, monkeypatch, error, code):
    def failing(*args, **kwargs):
        raise error

    monkeypatch.setattr(runner, "run", failing)
    result = cli("run", write_scenario(tiny_scenario), "-q")
    assert result.code == code and "Traceback" not in result.err


def test_run_round_trip_writes_result(cli, tiny_scenario, write_scenario, tmp_path):
    """``multilayer run`` on the tiny scenario writes result.nc with the docs/results.md
    variables and attributes; mass (m^2 per unit width) is conserved with a wall upstream
    while nothing has reached the outflow: 0.1 m x 0.05 m = 0.005 m^2."""
    outdir = tmp_path / "out"
    result = cli("run", write_scenario(tiny_scenario), "-o", outdir, "--set", "domain.cells=20")
    assert result.code == 0, result.err
    assert f"tiny: wrote {outdir / 'result.nc'}" in result.out
    with xr.open_dataset(outdir / "result.nc") as ds:
        assert {"h", "u", "bed", "static_interface", "front", "mass"} <= set(ds.data_vars)
        assert ds["h"].dims == ("time", "x") and ds["u"].dims == ("time", "layer", "x")
        np.testing.assert_allclose(ds["time"], [0.0, 0.025, 0.05])
        np.testing.assert_array_equal(ds["layer"], [1, 2, 3])
        np.testing.assert_allclose(ds["mass"], 0.005, rtol=1e-12)
        assert ds.attrs["cells"] == 20 * 3 and ds.attrs["steps"] > 0
        assert ds.attrs["fipy_version"] == fipy.__version__
        assert ds.attrs["multilayer_version"] == multilayer.__version__
        assert ds.attrs["wall_time_s"] > 0
        scenario = yaml.safe_load(ds.attrs["scenario"])
        assert scenario["domain"]["cells"] == 20 and scenario["numerics"]["order"] == 2


WITHOUT_STUDIES = """
import contextlib, io, json, sys
sys.modules["distributed"] = sys.modules["dask.distributed"] = sys.modules["SALib"] = None  # not installed
from multilayer.app.cli import main
said = {}
for command in ("sweep", "calibrate", "sensitivity"):
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main([command, sys.argv[1]])
    said[command] = (code, err.getvalue())
print(json.dumps(said))
"""


@pytest.mark.slow
def test_the_study_commands_without_their_extra_say_how_to_install_it(tmp_path):
    """exit 2 and the extra to install, before the file is read (none exists here); the
    three commands in one process."""
    done = subprocess.run(
        [sys.executable, "-c", WITHOUT_STUDIES, str(tmp_path / "study.yaml")], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    for command, (code, err) in json.loads(done.stdout.strip().splitlines()[-1]).items():
        assert code == 2 and "Traceback" not in err
        assert f"multilayer {command} needs " in err
        assert "accepted: install the studies extra with pip install 'multilayer[studies]'" in err


def test_the_run_summary_gives_units_and_says_why_a_quantity_has_no_value(
    cli, tiny_scenario, write_scenario, tmp_path
):
    """The material slides out of the domain over a free-slip bed, leaving a film thinner
    than the front threshold: no front at the end."""
    tiny_scenario["base"] = [{"condition": "free_slip"}]
    tiny_scenario["time"] = {"end": 20.0, "output_interval": 20.0}
    tiny_scenario["numerics"] = {"front_threshold": 0.01}
    result = cli("run", write_scenario(tiny_scenario), "-o", tmp_path / "out")
    assert result.code == 0, result.err
    lines = result.out.splitlines()[1:]
    assert "  t_final = 20 s" in lines and any(
        line.startswith("  mass_final = ") and line.endswith(" m2") for line in lines
    )
    assert any(line.startswith("  max_speed_final = ") and line.endswith(" m/s") for line in lines)
    assert "  front_final = nan m (no cell thicker than the front threshold (0.01 m) at the end)" in lines
    assert any(line.startswith("  steps = ") and line[len("  steps = ") :].isdigit() for line in lines)


def test_the_run_summary_says_why_a_force_has_no_value() -> None:
    """No force without an interval to average it over; none at all for a mixture, whose
    result holds no force variables (docs/mixture.md): the line says which."""
    nan = float("nan")
    dry = summary_lines({"peak_seismic_force_x": nan}, 1e-3)
    wet = summary_lines({"peak_seismic_force_x": nan, "pore_pressure_bed_mean_final": 1.4}, 1e-3)
    assert dry[0].endswith("(a single output time: no interval to average the force over)")
    assert wet[0] == "peak_seismic_force_x = nan N/m (not computed for a grain-fluid mixture)"


def test_the_command_leaves_its_host_process_as_it_found_it(cli, tiny_scenario, write_scenario):
    """``main`` called in a process (a notebook, a test runner) puts back the warning printer
    and the signal handlers it replaced while the command ran."""
    shown = warnings.showwarning
    handlers = {n: signal.getsignal(n) for n in (signal.SIGTERM, signal.SIGHUP)}
    assert cli("validate", write_scenario(tiny_scenario)).code == 0
    assert warnings.showwarning is shown
    assert {n: signal.getsignal(n) for n in handlers} == handlers


STDOUT_FAILED = "multilayer: error: cannot write to the standard output ("


@pytest.mark.parametrize("argv", [["plugins"], ["--version"], ["--help"], ["validate", "{scenario}"]])
def test_a_full_stdout_is_named_with_exit_2(cli, tiny_scenario, write_scenario, monkeypatch, argv):
    """A stdout on a full device (``> /dev/full``) is said to be the standard output with
    exit code 2: it was reported as a directory that cannot be written (``validate``,
    ``plugins``), a traceback (``--version``) or nothing and exit 0 (``--help``)."""
    path = write_scenario(tiny_scenario)
    with open("/dev/full", "w") as full:
        monkeypatch.setattr(sys, "stdout", full)
        result = cli(*[a.format(scenario=path) for a in argv])
        assert sys.stdout is full  # set back after the command
    assert result.code == 2
    assert STDOUT_FAILED + "No space left on device); accepted:" in result.err
    assert "directory" not in result.err.split(";")[0]


def test_a_closed_stdout_is_refused_once_written_to(cli, tiny_scenario, write_scenario, monkeypatch):
    """``multilayer plugins >&-`` (stdout None in Python) exited 0 with the listing nowhere;
    a command writing nothing to it (``run -q``) is not refused."""
    monkeypatch.setattr(sys, "stdout", None)
    listed = cli("plugins")
    assert listed.code == 2
    assert STDOUT_FAILED + "it is closed)" in listed.err
    path = write_scenario(tiny_scenario)
    assert cli("run", path, "-q", "-o", path.parent / "out").code == 0


def test_an_unwritable_stderr_keeps_the_exit_code(cli, tiny_scenario, write_scenario, monkeypatch):
    """An invalid input's message not written (``2>/dev/full``) still exits 2: it exited 1,
    the failed print's error taking the place of the invalid input's."""
    tiny_scenario["domain"]["cells"] = -1
    path = write_scenario(tiny_scenario)
    full = open("/dev/full", "w")  # noqa: SIM115 (closed below, its unwritten message dropped)
    monkeypatch.setattr(sys, "stderr", full)
    assert cli("validate", path).code == 2
    assert cli("run", path, "-o", path.parent / "out").code == 2
    monkeypatch.undo()
    with contextlib.suppress(OSError):
        full.close()


def test_a_closed_stderr_sends_no_message_to_stdout(cli, tiny_scenario, write_scenario, monkeypatch, capsys):
    """Under ``2>&-`` (``sys.stderr`` None) an error or a warning is written nowhere, the
    exit code saying the outcome: ``print(file=None)`` writes on stdout, where ``validate``
    wrote its error beside the lines of its output and ``run`` its warning; the library
    called by a host without stderr (pythonw) wrote its warnings on the host's stdout."""
    monkeypatch.setattr(sys, "stderr", None)
    bad = write_scenario("domain: [\n", "bad.yaml")
    result = cli("validate", bad)
    assert (result.code, result.out) == (2, "")
    tiny_scenario["numerics"] = {"front_threshold": 1.0}  # above any cell: a warning, exit 0
    path = write_scenario(tiny_scenario)
    result = cli("run", path, "-q", "-o", path.parent / "out")
    assert (result.code, result.out) == (0, "")
    multilayer.run(path, path.parent / "api", quiet=False)
    assert capsys.readouterr().out == ""


def test_a_closed_stderr_shows_no_study_progress(monkeypatch):
    """``multilayer sweep`` and ``calibrate`` without ``-q`` under ``2>&-`` (``sys.stderr``
    None) ran no member: asking None whether it is a terminal raised ``AttributeError``,
    exit 1 (fault battery round 28 runs both)."""
    from multilayer.app.commands.sweep import _Report

    monkeypatch.setattr(sys, "stderr", None)
    report = _Report("a local Dask cluster", quiet=False)
    assert not report.live
    report.progress(1, 2)  # writes nothing, raises nothing


@pytest.mark.parametrize("command", ["run", "validate", "check", "sweep", "calibrate", "sensitivity"])
def test_an_empty_file_path_is_named_as_empty(command, cli):
    """An empty path as a command's file is refused as such, not read as the working
    directory (`Path('')` is `.`)."""
    result = cli(command, "")
    assert result.code == 2 and "Traceback" not in result.err
    assert "an empty path; accepted: the path of a YAML file" in result.err
    assert ".: not a regular file" not in result.err


@pytest.mark.parametrize("ending", ["/", "/.", "//"])
@pytest.mark.parametrize("command", ["run", "validate", "check", "sweep", "calibrate", "sensitivity"])
def test_a_file_path_ending_in_a_slash_is_refused_naming_it(
    command, ending, cli, write_scenario, tiny_scenario
):
    """``s.yaml/`` names a directory, never the file (the system refuses to open it, "Not a
    directory"), and pathlib drops the ending: ``validate s.yaml/`` read ``s.yaml``.  Refused
    as the command's file, exit 2, naming the path as given."""
    path = write_scenario(tiny_scenario)
    with pytest.raises(NotADirectoryError):
        open(f"{path}{ending}")  # noqa: SIM115 - the system's answer
    result = cli(command, f"{path}{ending}")
    assert result.code == 2 and "Traceback" not in result.err, result.err
    assert f"{path}{ending}: a path ending in '{'/.' if ending == '/.' else '/'}'" in result.err
    assert "accepted: the path of a YAML file, without a '/' at its end" in result.err
