"""Hostile inputs of the Python API, the files a scenario names, ``--set``, the output
directory, the gate and ``validate`` (docs/reliability.md): each is an
:class:`InputError` (exit 2) naming what is wrong and what is accepted, never a
traceback, a hang or a value read otherwise than the user meant."""

from __future__ import annotations

import copy
import functools
import gc
import json
import math
import os
import re
import shutil
import subprocess
import sys
import threading
import time
import typing

import numpy as np
import pytest
import xarray as xr
import yaml
from conftest import TINY_SCENARIO

import multilayer
from multilayer.app import sweep as sweeps
from multilayer.engine.bed_force import FORCES
from multilayer.errors import InputError, RunError
from multilayer.io import results
from multilayer.io.results import CHECKPOINT_FILE, RESULT_FILE

BED = "x (m), z (m)\n0.0, 0.0\n0.5, -0.1\n"


def _recursive() -> dict:
    data = copy.deepcopy(TINY_SCENARIO)
    data["rheology"]["self"] = data
    return data


def _deep() -> dict:
    data = copy.deepcopy(TINY_SCENARIO)
    node = data["rheology"]
    for _ in range(5000):
        node["a"] = node = {}
    return data


@pytest.mark.parametrize(
    ("call", "phrase"),
    [
        (lambda: multilayer.load(5), "scenario: got 5; accepted: a Scenario, a mapping"),
        (lambda: multilayer.load(None), "scenario: got None"),
        (lambda: multilayer.load(b"scenario.yaml"), "scenario: got b'scenario.yaml'"),
        (lambda: multilayer.load(TINY_SCENARIO, 5), "overrides: got 5; accepted: a mapping of dotted keys"),
        (lambda: multilayer.load(TINY_SCENARIO, None), "overrides: got None"),
        (lambda: multilayer.load(TINY_SCENARIO, [5]), "overrides: got [5]"),
        (lambda: multilayer.load(TINY_SCENARIO, {5: 1}), "overrides: key 5; accepted"),
        (lambda: multilayer.load(TINY_SCENARIO, {"a=b": 1}), "overrides: key 'a=b'; accepted"),
        (
            lambda: multilayer.load(TINY_SCENARIO, {"time.end": np.nan}),
            "overrides: time.end: nan is not a value",
        ),
        (
            lambda: multilayer.load(TINY_SCENARIO, {"time.end": 5e-324}),
            "time.end (from --set): 5e-324 s, too short to step (half of a denormal step is zero)",
        ),
        (
            lambda: multilayer.load(_recursive()),
            "<scenario>: rheology.self.rheology.self.(...): more than 100",
        ),
        (lambda: multilayer.load(_deep()), "<scenario>: rheology.a.a.a.(...): more than 100 nested"),
        (
            lambda: multilayer.run(TINY_SCENARIO, 5),
            "outdir: got 5; accepted: None or the path of a directory",
        ),
    ],
)
def test_the_api_refuses_what_it_does_not_take_naming_the_argument(call, phrase):
    """Wrong types of ``source``, ``overrides`` and ``outdir``, and Python data that no YAML
    text could hold (a mapping holding itself, nesting 5000 deep) are an InputError; they
    were a TypeError, an AttributeError or a RecursionError from deep inside."""
    with pytest.raises(InputError) as caught:
        call()
    assert phrase in str(caught.value)


def test_numpy_values_in_a_mapping_are_read_as_the_numbers_they_hold():
    """A notebook's numpy scalars and arrays (``np.int64`` cells, an array of fractions)
    give the scenario of the plain numbers, where cells were refused and an array gave
    "the truth value of an array is ambiguous"."""
    data = copy.deepcopy(TINY_SCENARIO)
    data["domain"].update(
        cells=np.int64(40), x_max=np.float32(0.5), layer_fractions=np.array([0.5, 0.25, 0.25])
    )
    plain = copy.deepcopy(TINY_SCENARIO)
    plain["domain"]["layer_fractions"] = [0.5, 0.25, 0.25]
    assert multilayer.load(data).resolved_yaml() == multilayer.load(plain).resolved_yaml()
    overridden = multilayer.load(
        TINY_SCENARIO, {"domain.cells": np.int64(30), "rheology.mu_s": np.float64(0.4)}
    )
    assert overridden.domain.cells == 30 and overridden.rheology.params["mu_s"] == 0.4


@pytest.mark.slow  # 1-3 s of a child process or a large input, no physics
def test_a_long_value_is_quoted_cut_in_the_message():
    """A list of 300 000 fractions was quoted whole: a message of 1.5 MB."""
    data = copy.deepcopy(TINY_SCENARIO)
    data["domain"]["layer_fractions"] = [1.0] * 300_000
    with pytest.raises(InputError, match=r"domain\.layer_fractions: expected 3 numbers > 0") as caught:
        multilayer.load(data)
    assert len(str(caught.value)) < 400
    data["domain"]["layer_fractions"] = [1, 10**400, 1]  # their sum was quoted whole, 400 digits
    with pytest.raises(InputError, match=r"domain\.layer_fractions: fractions sum to 1000") as caught:
        multilayer.load(data)
    assert len(str(caught.value)) < 400


@pytest.mark.parametrize("x", [0.0, 0.006, 0.5, 0.494])
def test_a_gate_on_an_end_face_of_the_domain_is_refused(x):
    """The gate stands on the face nearest to ``x``; on an end face (40 cells of 12.5 mm:
    x within 6.25 mm of an end) the side's boundary holds or releases the material.  A
    gate there on periodic sides created 37 % of the mass with no error."""
    data = copy.deepcopy(TINY_SCENARIO)
    data["gate"] = {"x": x, "lift_speed": 0.0}
    with pytest.raises(
        InputError, match=r"gate\.x: gate at x = .* stands on an end face of the domain"
    ) as caught:
        multilayer.load(data)
    assert "accepted: a number in (0.00625, 0.49375] (m)" in str(caught.value)
    data["gate"]["x"] = 0.007 if x < 0.25 else 0.49375
    assert multilayer.load(data).gate.x == data["gate"]["x"]


@pytest.mark.parametrize(
    ("bed", "phrase"),
    [
        ("\ufeff" + BED.replace("\n", "\r\n"), None),  # a spreadsheet's byte order mark and line ends
        (BED.replace("-0.1", "\u0661"), "got '0.5, \u0661'"),  # an Arabic-Indic digit, read as 1 by float
        (BED.replace("-0.1", "1_000"), "got '0.5, 1_000'"),  # read as 1000 by float
    ],
)
def test_csv_numbers_are_ascii_decimals_and_a_byte_order_mark_is_no_header(tmp_path, bed, phrase):
    (tmp_path / "bed.csv").write_text(bed, encoding="utf-8", newline="")
    data = {**copy.deepcopy(TINY_SCENARIO), "bed": {"file": "bed.csv"}}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(data))
    if phrase is None:
        (tmp_path / "plain.csv").write_text(BED)
        (tmp_path / "plain.yaml").write_text(yaml.safe_dump({**data, "bed": {"file": "plain.csv"}}))
        plain = multilayer.load(tmp_path / "plain.yaml").bed.points
        np.testing.assert_array_equal(multilayer.load(tmp_path / "s.yaml").bed.points, plain)
        return
    with pytest.raises(InputError, match="bed.csv: line 3: expected two numbers") as caught:
        multilayer.load(tmp_path / "s.yaml")
    assert phrase in str(caught.value)


def test_a_csv_number_of_a_million_digits_and_a_letter_is_refused_at_once(tmp_path):
    """The pattern of an ASCII decimal, ``[0-9]+\\.?[0-9]*``, split the digits of a number
    between its two runs in every way before refusing one ended by a letter: quadratic in
    its digits, a row ``0, 999...9x`` of 10^6 digits held ``validate`` for 11 hours (and an
    ``--at`` of 10^5 digits ``plot`` for minutes).  Refused at once (a child, which a
    quadratic match would hold past the timeout), the row quoted in 60 characters."""
    (tmp_path / "bed.csv").write_text("x (m), z (m)\n0, 0\n0.5, " + "9" * 10**6 + "x\n")
    data = {**copy.deepcopy(TINY_SCENARIO), "bed": {"file": "bed.csv"}}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(data))
    result = subprocess.run(
        [sys.executable, "-m", "multilayer", "validate", str(tmp_path / "s.yaml")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2 and "Traceback" not in result.stderr
    row = f"'0.5, {'9' * 51}..."
    assert f"bed.csv: line 3: expected two numbers separated by a comma, got {row}" in result.stderr
    assert len(result.stderr) < 500


@pytest.mark.parametrize(
    ("bed", "phrase"),
    [
        ("x (km), z (m)\n0, 0\n1e306, 0\n", "'1e306, 0'"),
        ("x (m), z (km)\n0, 0\n0.5, 1e306\n", "'0.5, 1e306'"),
    ],
)
def test_a_csv_number_beyond_the_floats_in_metres_is_refused(tmp_path, bed, phrase):
    """``1e306`` km is inf m: an x of inf validated, a z of inf was refused as an elevation
    "where floats are nan m apart"."""
    (tmp_path / "bed.csv").write_text(bed)
    data = {**copy.deepcopy(TINY_SCENARIO), "bed": {"file": "bed.csv"}}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(data))
    with pytest.raises(InputError, match=f"bed.csv: line 3: {phrase} in metres is beyond the largest float"):
        multilayer.load(tmp_path / "s.yaml")


@pytest.mark.parametrize(
    ("text", "phrase"),
    [
        ("!!float abc", "tag:yaml.org,2002:float cannot read 'abc'"),
        ("!!int 1e5", "tag:yaml.org,2002:int cannot read '1e5'"),
        ("!!bool maybe", "tag:yaml.org,2002:bool cannot read 'maybe'"),
        ("!!timestamp 2001-13-45", "tag:yaml.org,2002:timestamp cannot read '2001-13-45'"),
        ("4" * 5000, "tag:yaml.org,2002:int cannot read '444"),  # beyond Python's 4300 digits
    ],
)
def test_a_value_its_tag_cannot_read_is_malformed_yaml_at_its_place(
    tmp_path, cli, write_scenario, text, phrase
):
    """PyYAML's constructors raised ``ValueError`` or ``KeyError`` for them: a traceback of
    ``validate``, of ``--set``, of numba's configuration file and of a result's scenario."""
    data = yaml.safe_dump(TINY_SCENARIO, sort_keys=False).replace("cells: 40", f"cells: {text}")
    result = cli("validate", write_scenario(data))
    assert result.code == 2 and "Traceback" not in result.err
    assert re.search(
        r"scenario.yaml \(line \d+, column 10\): malformed YAML: " + re.escape(phrase), result.err
    )
    result = cli("validate", write_scenario(TINY_SCENARIO), "--set", f"domain.cells={text}")
    assert result.code == 2 and f"--set domain.cells: malformed YAML value {text[:10]!r}"[:-1] in result.err
    from multilayer.scenario.source import safe_load

    with pytest.raises(yaml.YAMLError, match=re.escape(phrase)):
        safe_load(f"num_threads: {text}")


@pytest.mark.parametrize("item", ["=", "a..b=1", ".domain=1", "domain.=1", "domain..cells=1"])
def test_a_key_path_with_an_empty_part_is_malformed(tmp_path, cli, write_scenario, item):
    """``--set a..b=1`` was "a: unknown key" and ``.domain=1`` "(top level): unknown key"."""
    result = cli("validate", write_scenario(TINY_SCENARIO), "--set", item)
    assert result.code == 2 and "Traceback" not in result.err
    assert (
        f"--set '{item}': expected KEY=VALUE or KEY+=VALUE; accepted: a dotted key path (no part empty"
        in result.err
    )


@pytest.mark.slow
def test_file_names_holding_a_terminal_escape_sequence_are_quoted_in_what_commands_print(
    tmp_path, cli, write_scenario
):
    """A scenario file or output directory named with ``ESC [2J`` was printed as named by
    ``validate``, ``run``, ``plot`` and ``export`` on success (the paths they wrote): the line
    cleared the terminal.  Every line a command prints writes such characters as Python
    writes them in a string, as its error messages do."""
    escape = "\x1b[2J"
    short = {**TINY_SCENARIO, "time": {"end": 0.02, "output_interval": 0.01}}
    path = write_scenario(short, f"s{escape}.yaml")
    outdir = tmp_path / f"out{escape}"
    for argv in (
        ("validate", path),
        ("run", path, "-o", outdir),
        ("plot", outdir),
        ("export", outdir, "--vtk"),
    ):
        result = cli(*argv)
        assert result.code == 0, result.err
        assert "\x1b" not in result.out + result.err and "\\x1b[2J" in result.out, result.out


def test_a_key_holding_a_terminal_escape_sequence_is_quoted_not_sent_to_the_terminal(cli, write_scenario):
    """A key of a scenario or sweep file, or of ``--set``, holding ``ESC [2J`` was printed as
    written: the message cleared the terminal (a title set, colours changed, by others).
    Keys that are not printable text are quoted as Python writes them, and the command line
    writes every character of a message that is not printable (but newlines and tabs) so."""
    escape = "\x1b[2J"
    scenario = write_scenario(
        {**TINY_SCENARIO, f"a{escape}": 1, "rheology": {**TINY_SCENARIO["rheology"], "\u202e": 1}}
    )
    sweep = write_scenario({"base": "tiny.yaml", "parameters": {f"rheology.{escape}": [1]}}, "sweep.yaml")
    write_scenario(TINY_SCENARIO, "tiny.yaml")
    for argv, said in (
        ((scenario,), ("'a\\x1b[2J' (line ", "rheology.'\\u202e' (line ")),
        ((sweep,), ("parameters.'rheology.\\x1b[2J' (line 3): not a scenario key",)),
        ((scenario, "--set", f"rheology.{escape}=1"), ("--set 'rheology.\\x1b[2J=1': expected KEY=VALUE",)),
    ):
        result = cli("validate", *argv)
        assert result.code == 2 and "\x1b" not in result.err and "\u202e" not in result.err, result.err
        assert all(text in result.err for text in said), result.err
    # a value quoted by a message (a rheology's name, a file's): what the command line prints
    named = write_scenario({**TINY_SCENARIO, "rheology": {"name": f"dp{escape}"}}, "named.yaml")
    result = cli("validate", named)
    assert result.code == 2 and "unknown rheology 'dp\\x1b[2J'; accepted" in result.err, result.err


@pytest.mark.parametrize(
    ("key", "said"),
    [
        ("mu_\u0455", "rheology.'mu_\\u0455' (line 15): unknown parameter of drucker_prager; accepted"),
        (
            "mu_s\u200b",
            "rheology.'mu_s\\u200b' (line 14): unknown parameter of drucker_prager (mu_s missing)",
        ),
        ("mu_z", "rheology.mu_z (line 14): unknown parameter of drucker_prager (mu_s missing)"),
    ],
)
def test_a_key_that_only_looks_like_a_parameter_is_named_as_unknown(write_scenario, key, said):
    """A Cyrillic s in ``mu_s`` was "unknown" printed as ``mu_s``, and a typo or an invisible
    character in ``mu_s`` was said as "mu_s: missing parameter", naming no key of the file:
    a key that is not printable ASCII is quoted with its escapes, and an unknown key is
    named before the parameters it leaves missing."""
    rheology = {"name": "drucker_prager", "nu": 0.01, key: 0.3}
    if "\u0455" in key:
        rheology = {"name": "drucker_prager", "mu_s": 0.3, "nu": 0.01, key: 0.3}
    text = yaml.safe_dump({**TINY_SCENARIO, "rheology": rheology}, sort_keys=False, allow_unicode=True)
    with pytest.raises(InputError) as caught:
        multilayer.load(write_scenario(text))
    assert said in str(caught.value)


def test_an_empty_key_is_named_as_one(write_scenario):
    """``"": 1`` at the top level was "(top level): unknown key"."""
    with pytest.raises(InputError, match="scenario.yaml: '' \\(line \\d+\\): unknown key; accepted: name,"):
        multilayer.load(write_scenario({**TINY_SCENARIO, "": 1}))


def test_spaces_around_a_key_are_not_part_of_it(write_scenario):
    """``--set "domain.cells = 30"`` named the key ``"domain.cells "``, unknown."""
    assert multilayer.load(write_scenario(TINY_SCENARIO), ["domain.cells = 30"]).domain.cells == 30


@pytest.mark.parametrize("name", [RESULT_FILE, CHECKPOINT_FILE, "run.log"])
@pytest.mark.parametrize("kind", ["directory", "pipe", "device"])
def test_an_output_file_that_is_no_regular_file_is_refused_before_the_run(
    tmp_path, cli, write_scenario, name, kind
):
    """``result.nc`` linked to /dev/zero was written into it and the summary was a
    traceback; a pipe hung the command after its message."""
    outdir = tmp_path / "out"
    outdir.mkdir()
    path = outdir / name
    {
        "directory": path.mkdir,
        "pipe": lambda: os.mkfifo(path),
        "device": lambda: path.symlink_to("/dev/zero"),
    }[kind]()
    result = cli("run", write_scenario(TINY_SCENARIO), "-o", outdir, "-q")
    assert result.code == 2 and "Traceback" not in result.err
    assert f"{path}: exists and is not a regular file" in result.err


@pytest.mark.parametrize("name", [RESULT_FILE, "run.log"])
def test_an_output_file_linked_to_a_file_elsewhere_is_refused_and_the_file_kept(
    tmp_path, cli, write_scenario, name
):
    """``out/result.nc`` (or ``run.log``) a symbolic link to a file outside the directory:
    the run wrote its result (its log) over that file.  Refused naming the link; the file
    is as it was."""
    outdir = tmp_path / "out"
    outdir.mkdir()
    elsewhere = tmp_path / "precious.txt"
    elsewhere.write_text("precious")
    (outdir / name).symlink_to(elsewhere)
    result = cli("run", write_scenario(TINY_SCENARIO), "-o", outdir, "-q")
    assert result.code == 2 and "Traceback" not in result.err
    assert (
        f"{outdir / name}: a symbolic link (to {elsewhere}), whose target the write would replace"
        in result.err
    )
    assert elsewhere.read_text() == "precious"


@pytest.mark.slow  # a child process; the fault battery tries it too
@pytest.mark.parametrize("kind", ["a pipe", "a link"])
def test_a_file_at_the_checkpoints_temporary_name_is_replaced_not_written_through(
    tmp_path, write_scenario, kind
):
    """``out/checkpoint.npz.tmp`` a named pipe held the run for ever at its first checkpoint
    (nothing reads the pipe); a symbolic link had its target written over by the checkpoint.
    The temporary file is made afresh: the run completes and the target is as it was."""
    outdir, elsewhere = tmp_path / "out", tmp_path / "precious.txt"
    outdir.mkdir()
    elsewhere.write_text("precious")
    if kind == "a pipe":
        os.mkfifo(outdir / "checkpoint.npz.tmp")
    else:
        (outdir / "checkpoint.npz.tmp").symlink_to(elsewhere)
    path = write_scenario({**TINY_SCENARIO, "time": {"end": 0.02, "output_interval": 0.01}})
    done = subprocess.run(  # a child: a hang fails the test rather than holding the suite
        [sys.executable, "-m", "multilayer", "run", str(path), "-o", str(outdir), "-q"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr
    assert elsewhere.read_text() == "precious" and not (outdir / "checkpoint.npz.tmp").exists()
    assert results.open_result(outdir).attrs["run_status"] == "completed"


@pytest.mark.parametrize(("command", "directory"), [("plot", "plots"), ("export", "vtk")])
def test_an_output_directory_linked_elsewhere_is_refused_and_its_target_kept(
    tmp_path, cli, write_scenario, command, directory
):
    """``out/plots`` (``out/vtk``) a symbolic link to a directory elsewhere: the figures
    (the VTK files) were written into it, replacing its files of the same names.  Refused
    naming the link, as a linked output file is; the directory is as it was."""
    outdir, short = tmp_path / "out", {**TINY_SCENARIO, "time": {"end": 0.02, "output_interval": 0.01}}
    assert cli("run", write_scenario(short), "-o", outdir, "-q").code == 0
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "section.png").write_text("precious")
    (outdir / directory).symlink_to(elsewhere)
    result = cli(command, outdir, *(["--vtk"] if command == "export" else []))
    assert result.code == 2 and "Traceback" not in result.err, result.err
    assert result.err.count("\n") == 1
    linked = f"{outdir / directory}: a symbolic link (to {elsewhere}), into whose target the files would be"
    assert linked in result.err
    assert [p.name for p in elsewhere.iterdir()] == ["section.png"]
    assert (elsewhere / "section.png").read_text() == "precious"


@pytest.mark.parametrize("name", [RESULT_FILE, "run.log"])
def test_an_output_file_with_another_name_elsewhere_is_refused_and_the_file_kept(
    tmp_path, cli, write_scenario, name
):
    """``out/result.nc`` (or ``run.log``) a hard link to a file elsewhere: netCDF and the log
    write the file in place, so the result (the log) replaced that file's content under its
    other name too.  Refused naming it; the file is as it was."""
    outdir, elsewhere = tmp_path / "out", tmp_path / "precious.txt"
    outdir.mkdir()
    elsewhere.write_text("precious")
    os.link(elsewhere, outdir / name)
    result = cli("run", write_scenario(TINY_SCENARIO), "-o", outdir, "-q")
    assert result.code == 2 and "Traceback" not in result.err, result.err
    assert f"{outdir / name}: a file of 2 names (hard links), which the write would change" in result.err
    assert elsewhere.read_text() == "precious"


def test_a_checks_result_directory_linked_elsewhere_is_refused_before_anything_runs(
    tmp_path, cli, write_scenario
):
    """``multilayer check FILE -o DIR`` whose ``DIR/<scenario name>`` is a symbolic link to
    a directory elsewhere: the run wrote into it.  Refused (exit 2) naming the link."""
    expect = [{"kind": "regression", "quantity": "runout", "value": 0.1, "rtol": 0.5}]
    path = write_scenario({**TINY_SCENARIO, "expect": expect})
    outdir, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    outdir.mkdir()
    elsewhere.mkdir()
    (outdir / TINY_SCENARIO["name"]).symlink_to(elsewhere)
    result = cli("check", path, "-o", outdir)
    assert result.code == 2 and "Traceback" not in result.err, result.err
    linked = outdir / TINY_SCENARIO["name"]
    assert f"{linked}: a symbolic link (to {elsewhere}), into whose target" in result.err
    assert not list(elsewhere.iterdir())


def test_a_sweep_member_directory_linked_elsewhere_is_refused_before_anything_runs(
    tmp_path, cli, write_scenario
):
    """A member's directory of a sweep a symbolic link to a directory elsewhere: its run
    wrote there.  The sweep is refused (exit 2) naming the link, before any member runs."""
    from multilayer.app import sweep

    write_scenario({**TINY_SCENARIO, "time": {"end": 0.02, "output_interval": 0.01}}, "base.yaml")
    path = write_scenario({"base": "base.yaml", "parameters": {"rheology.mu_s": [0.3, 0.4]}}, "sweep.yaml")
    outdir, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    elsewhere.mkdir()
    member = sweep.load(path).members()[1].id
    outdir.mkdir()
    (outdir / member).symlink_to(elsewhere)
    result = cli("sweep", path, "-o", outdir)
    assert result.code == 2 and "Traceback" not in result.err, result.err
    assert f"{outdir / member}: a symbolic link (to {elsewhere}), into whose target" in result.err
    assert not list(elsewhere.iterdir()) and not list(outdir.glob("*/result.nc"))


@pytest.mark.parametrize(
    ("command", "results"),
    [("sweep", "summary.csv"), ("calibrate", "calibration.nc"), ("sensitivity", "sensitivity.nc")],
)
@pytest.mark.parametrize("kind", ["a pipe", "a link"])
def test_a_study_file_that_is_a_pipe_or_a_link_is_refused_before_anything_runs(
    tmp_path, cli, write_scenario, command, results, kind
):
    """A sweep's ``summary.csv`` a named pipe held the sweep for ever once its members had
    run (nothing reads it), a symbolic link had its target written over by the summary.
    Every study's file is refused as a run's are, before anything runs."""
    write_scenario({**TINY_SCENARIO, "time": {"end": 0.02, "output_interval": 0.01}}, "base.yaml")
    (tmp_path / "front.csv").write_text("t,x_f,sigma\n0.01,0.12,0.01\n")
    bounds = {"rheology.mu_s": {"bounds": [0.2, 0.4]}}
    columns = ["t", "x_f", "sigma"]
    observation = {"name": "front", "quantity": "front", "file": "front.csv", "columns": columns}
    config = {
        "sweep": {"base": "base.yaml", "parameters": {"rheology.mu_s": [0.3]}},
        "calibrate": {"base": "base.yaml", "parameters": bounds, "observations": [observation]},
        "sensitivity": {"base": "base.yaml", "parameters": bounds, "outputs": ["runout"], "samples": 8},
    }[command]
    outdir, elsewhere = tmp_path / "out", tmp_path / "precious.txt"
    outdir.mkdir()
    elsewhere.write_text("precious")
    if kind == "a pipe":
        os.mkfifo(outdir / results)
    else:
        (outdir / results).symlink_to(elsewhere)
    result = cli(command, write_scenario(config, "study.yaml"), "-o", outdir, "--workers", "1")
    assert result.code == 2 and "Traceback" not in result.err, result.err
    said = "exists and is not a regular file" if kind == "a pipe" else "a symbolic link (to"
    assert f"{outdir / results}: {said}" in result.err
    assert elsewhere.read_text() == "precious" and not (outdir / "members").exists()


def test_validate_checks_sweep_and_study_files_with_every_member(tmp_path, cli, write_scenario):
    """``validate`` refused every sweep file as a scenario missing name, domain, ...; it
    checks a sweep with each of its members, and calibration and sensitivity files as
    their commands read them."""
    write_scenario(TINY_SCENARIO, "base.yaml")
    sweep = write_scenario({"base": "base.yaml", "parameters": {"rheology.mu_s": [0.3, 0.4]}}, "sweep.yaml")
    result = cli("validate", sweep)
    assert result.code == 0 and f"{sweep}: ok (sweep of 2 members of" in result.out
    bad = write_scenario({"base": "base.yaml", "parameters": {"domain.cells": [40, 0]}}, "bad.yaml")
    result = cli("validate", bad)
    assert result.code == 2 and "Traceback" not in result.err
    assert "bad.yaml: member m001-" in result.err and "(domain.cells=0)" in result.err
    sensitivity = {
        "base": "base.yaml",
        "parameters": {"rheology.mu_s": {"bounds": [0.3, 0.4]}},
        "outputs": ["runout"],
        "samples": 32,  # 2 is refused by the design's check, as the command refuses it
    }
    result = cli("validate", write_scenario(sensitivity, "sobol.yaml"))
    assert result.code == 0 and "ok (sensitivity of runout to rheology.mu_s)" in result.out, result.err
    # a base that is no path: read as a scenario, it was seven messages (time missing,
    # parameters unknown, ...) none naming the base; now the study's own, one
    for base, given in ((["base.yaml"], "['base.yaml']"), (3, "3")):
        accepted = f"got {given}; accepted: the path of a scenario file, relative to this file"
        listed = write_scenario({"base": base, "parameters": {"rheology.mu_s": [0.3]}}, "listed.yaml")
        result = cli("validate", listed)
        assert result.code == 2 and result.err == f"multilayer: error: {listed}: base (line 1): {accepted}\n"
    # a base that is the sweep or study file itself, or another one: seven lines, none
    # saying that the base is no scenario; now one
    accepted = "not a scenario; accepted: the path of a scenario file, relative to this file"
    studies = (("itself.yaml", {"parameters": {"rheology.mu_s": [0.3]}}), ("study.yaml", sensitivity))
    for name, config in studies:
        path = write_scenario({"base": name, **{k: v for k, v in config.items() if k != "base"}}, name)
        result = cli("validate", path)
        itself = f"multilayer: error: {path}: base (line 1): {path} is this file itself, {accepted}\n"
        assert result.code == 2 and result.err == itself, result.err
        other = write_scenario({"base": name, "parameters": {"rheology.mu_s": [0.3]}}, "of_another.yaml")
        result = cli("validate", other)
        study = f"{path} is a sweep or study file (it has the key parameters), {accepted}\n"
        assert result.code == 2 and result.err == f"multilayer: error: {other}: base (line 1): {study}"


def test_a_base_that_is_no_valid_scenario_is_read_once(write_scenario, monkeypatch):
    """Its error path read the file again to look for ``parameters``: twice the time for a
    large file, and a file changed between the two reads was judged by another text."""
    from multilayer.scenario import loading

    reads = []
    read = loading.read_yaml
    monkeypatch.setattr(loading, "read_yaml", lambda path: reads.append(path) or read(path))
    base = write_scenario({**TINY_SCENARIO, "gravity": -1.0}, "base.yaml")
    study = write_scenario({"base": "base.yaml", "parameters": {"rheology.mu_s": [0.3]}}, "sweep.yaml")
    with pytest.raises(InputError, match=r"sweep.yaml: base: the base scenario is invalid:\n.*gravity"):
        loading.load_base(study, "base.yaml", f"{study}: base", "the base scenario")
    assert reads == [base]


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished run of the tiny scenario (its checkpoint and result), copied per test."""
    directory = tmp_path_factory.mktemp("finished")
    path = directory / "scenario.yaml"
    path.write_text(yaml.safe_dump(TINY_SCENARIO))
    multilayer.run(path, directory / "out")
    return path, directory / "out"


@pytest.mark.parametrize(
    ("entry", "value", "phrase"),
    [
        (
            "state.u",
            lambda a: a.T.copy(),
            "u: float64 values of shape (40, 3), where float64 of shape (3, 40)",
        ),
        ("state.seed_window", lambda a: np.array([-5, 400]), "seed_window = [-5, 400], outside the columns"),
        ("state.steps", lambda a: np.array(-5), "steps = -5, where a number >= 0"),
        ("state.bogus", lambda a: np.zeros(3), "bogus: not an entry of this simulation's state"),
        (
            "state.t",
            lambda a: np.array(np.nan),
            "corrupt checkpoint (state.t holds values that are not finite)",
        ),
        ("state.t", lambda a: np.array("abc"), "corrupt checkpoint (state.t holds <U3)"),
        ("meta.scenario", lambda a: np.array(5), "corrupt checkpoint (meta.scenario is not text"),
        ("meta.scenario", lambda a: np.array("[1"), "meta.scenario is not the YAML mapping of a scenario"),
        ("meta.scenario", lambda a: np.array("&a [*a]"), "meta.scenario is not the YAML mapping of a scen"),
    ],
)
def test_a_checkpoint_of_another_layout_is_refused_naming_the_entry(
    tmp_path, cli, finished, entry, value, phrase
):
    """A checkpoint whose checksum holds but whose entries this version does not write as
    they are (another version, or edited): a transposed or shorter array, a step count of
    another type were tracebacks (ValueError from deep inside), a seed window outside the
    mesh was read into a compiled loop, a NaN time resumed as "completed", a scenario that is
    malformed YAML was yaml's traceback."""
    path, source = finished
    outdir = tmp_path / "out"
    shutil.copytree(source, outdir)
    ckpt = outdir / CHECKPOINT_FILE
    arrays = dict(np.load(ckpt))
    arrays.pop("checksum")
    arrays[entry] = value(arrays.get(entry))
    arrays["checksum"] = np.asarray(results._checksum(arrays))
    with open(ckpt, "wb") as stream:
        np.savez(stream, **arrays)
    result = cli("run", path, "-o", outdir, "--resume", "--set", "time.end=0.1", "-q")
    assert result.code == 2 and "Traceback" not in result.err
    assert f"{ckpt}: " in result.err and phrase in result.err and "start again without --resume" in result.err


@pytest.mark.parametrize("key", ["file", "dem"])
def test_a_pipe_as_a_bed_file_is_refused_without_waiting_for_a_writer(tmp_path, key):
    """A DEM is read by GDAL, which would wait for ever on a pipe: checked as the CSV is."""
    os.mkfifo(tmp_path / "bed")
    extra = {"polyline": [[0.0, 0.0], [1.0, 0.0]]} if key == "dem" else {}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump({**TINY_SCENARIO, "bed": {key: "bed", **extra}}))
    with pytest.raises(InputError, match=f"bed.{key} .*bed: not a regular file"):
        multilayer.load(tmp_path / "s.yaml")


@pytest.mark.parametrize(
    ("call", "phrase"),
    [
        (lambda sim: multilayer.Simulation(TINY_SCENARIO), "Simulation: got {'name': 'tiny'"),
        (lambda sim: sim.advance(np.nan), "advance(t_target=nan): accepted: a finite number (s)"),
        (lambda sim: sim.advance(np.inf), "advance(t_target=inf): accepted: a finite number (s)"),
        (lambda sim: sim.advance(None), "advance(t_target=None): accepted"),
        (lambda sim: sim.step("0.1"), "step(t_max='0.1'): t_max must be a number at least"),
        (
            lambda sim: sim.step(5e-324),
            "step(t_max=5e-324): t_max must be a number at least 4.45e-308 s later",
        ),
        (
            lambda sim: sim.advance(1e308),
            "advance(t_target=1e+308): 1e+308 s from t = 0 s in steps of at most",
        ),
        (lambda sim: sim.advance(1.0, max_steps=10), "more than max_steps = 10; accepted: a nearer t_target"),
        (
            lambda sim: sim.advance(0.01, max_steps=0),
            "advance(max_steps=0): accepted: an integer >= 1, or None",
        ),
        (lambda sim: sim.advance(0.01, max_steps=2.5), "advance(max_steps=2.5): accepted"),
        (lambda sim: sim.advance(0.01, max_steps=True), "advance(max_steps=True): accepted"),
    ],
)
def test_stepping_by_hand_refuses_what_is_no_scenario_or_no_time(call, phrase):
    """``Simulation(mapping)`` was an AttributeError, ``advance(nan)`` did nothing,
    ``advance(inf)`` never ended, nor ``advance(1e308)`` (10^311 steps), a time of text was a
    TypeError, a step of 5e-324 s a ZeroDivisionError in the implicit step (half of it is 0)."""
    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    with pytest.raises(InputError) as caught:
        call(sim)
    assert phrase in str(caught.value)
    sim.advance(np.array(0.01))  # a 0-d array (a time read from a Dataset) is a time
    assert sim.t == 0.01


def test_advance_stops_at_its_step_bound_and_continues_to_the_same_state():
    """``advance(t, max_steps=n)`` takes n steps and stops short of ``t`` with a RunError,
    the state of its last step kept: advancing again ends on the state of one uninterrupted
    advance, to the last bit."""
    whole = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    whole.advance(0.05)
    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    with pytest.raises(
        RunError, match=r"advance\(t_target=0.05\): took max_steps = 6 time steps, reaching t = "
    ):
        sim.advance(0.05, max_steps=6)  # 5.9 Courant steps of the initial state: 7 steps
    assert sim.steps == 6 and 0.0 < sim.t < 0.05 < whole.steps
    sim.advance(0.05)
    assert (sim.steps, sim.t) == (whole.steps, whole.t)
    assert np.array_equal(sim.h, whole.h) and np.array_equal(sim.u, whole.u)


@pytest.mark.parametrize("x1", ["inf", "1e308"])
def test_a_plot_window_without_end_is_refused(tmp_path, cli, finished, x1):
    """``--xlim 0 inf`` and ``--xlim 0 1e308`` were an OverflowError in the vertical
    exaggeration."""
    _, source = finished
    outdir = tmp_path / "out"
    shutil.copytree(source, outdir)
    result = cli("plot", outdir, "--xlim", "0", x1)
    assert result.code == 2 and "Traceback" not in result.err
    assert "at most 1000 and at least 1e-06 times as wide" in result.err


@pytest.mark.parametrize("command", [["plot"], ["export", "--vtk"]])
def test_a_result_file_given_as_the_directory_is_named_with_its_directory(tmp_path, cli, finished, command):
    """``plot DIR/result.nc`` checked the result, then said ``DIR/result.nc/plots: Not a
    directory; accepted: a directory this user can write`` (``export``: ``.../vtk``), naming
    a path that is not there and asking for permissions; the file is named, with the
    directory holding it, before anything is read."""
    _, source = finished
    outdir = tmp_path / "out"
    shutil.copytree(source, outdir)
    result = cli(command[0], outdir / "result.nc", *command[1:])
    assert result.code == 2 and "Traceback" not in result.err
    accepted = "accepted: the output directory of `multilayer run`"
    assert f"{outdir / 'result.nc'}: a file, not a directory; {accepted}" in result.err
    assert result.err.rstrip().endswith(f"(here {outdir})")
    assert sorted(p.name for p in outdir.iterdir()) == sorted(p.name for p in source.iterdir())


@pytest.mark.parametrize(("x0", "x1"), [("-1e-320", "1e-320"), ("0.2", "0.2000000000000001")])
def test_a_plot_window_matplotlib_would_widen_is_refused(tmp_path, cli, finished, x0, x1):
    """Matplotlib widens a window narrower than 1e-15 of its largest end, or within
    2.2e-287 of zero, to +-5 % of it: ``--xlim -1e-320 1e-320`` was drawn over -0.05 .. 0.05 m
    and ``0.2 0.2000000000000001`` over 0.19 .. 0.21 m, exit 0.  A window narrower than 1e-6
    of the domain is refused, its ends written as given; a wider one is drawn as asked."""
    _, source = finished
    outdir = tmp_path / "out"
    shutil.copytree(source, outdir)
    result = cli("plot", outdir, "--xlim", x0, x1)
    assert result.code == 2 and "Traceback" not in result.err
    assert f"--xlim {float(x0)!r} {float(x1)!r}: accepted: X0 < X1 (m)" in result.err
    assert "at least 1e-06 times as wide (Matplotlib widens a narrower window)" in result.err
    assert not (outdir / "plots").exists()
    from multilayer.io.plotting import checked_xlim

    ds = xr.Dataset(coords={"x_bnds": (("x", "nv"), [[0.0, 0.25], [0.25, 0.5]])})
    assert checked_xlim(ds, (0.2, 0.2 + 1e-6)) == (0.2, 0.2 + 1e-6)  # 2e-6 of the domain


@pytest.mark.parametrize(
    ("text", "value"),
    [("010", 10), ("0o10", 8), ("0x28", 40), ("1:20", "1:20"), ("0_3", "0_3"), ("1e1", 10.0)],
)
def test_numbers_are_read_by_the_yaml_1_2_core_schema(text, value):
    """YAML 1.1 (PyYAML's rule) read ``010`` as eight, ``1:20`` as 80 and ``0_3`` as 3:
    ``cells: 0100`` ran 64 cells without a word; text is refused where a number is expected."""
    from multilayer.scenario.source import Loader

    read = yaml.load(text, Loader=Loader)
    assert read == value and type(read) is type(value)
    if isinstance(value, str):
        with pytest.raises(
            InputError, match=f"domain.cells .*Input should be a valid integer \\(got '{value}'\\)"
        ):
            multilayer.load(TINY_SCENARIO, [f"domain.cells={text}"])


def test_a_base_or_result_that_exists_but_is_no_file_is_not_called_missing(tmp_path, cli, write_scenario):
    """A sweep's base ``/dev/zero`` was "not found", a directory named result.nc "no result file"."""
    sweep = write_scenario({"base": "/dev/zero", "parameters": {"rheology.mu_s": [0.3]}}, "sweep.yaml")
    result = cli("validate", sweep)
    assert result.code == 2 and "scenario file /dev/zero is not a regular file" in result.err
    (tmp_path / "out" / RESULT_FILE).mkdir(parents=True)
    result = cli("plot", tmp_path / "out")
    assert result.code == 2 and f"{tmp_path / 'out' / RESULT_FILE}: not a regular file" in result.err


@pytest.mark.parametrize(("command", "file"), [("plot", "plots/front.png"), ("export", "vtk/result.pvd")])
def test_a_figure_or_vtk_file_that_is_a_pipe_is_refused(tmp_path, cli, finished, command, file):
    """``export --vtk`` waited for ever on a pipe named vtk/result.pvd (plot as well on a
    pipe named after one of its figures)."""
    _, source = finished
    outdir = tmp_path / "out"
    shutil.copytree(source, outdir)
    (outdir / file).parent.mkdir(exist_ok=True)
    os.mkfifo(outdir / file)
    result = cli(command, outdir, *(["--vtk"] if command == "export" else []))
    assert result.code == 2 and "Traceback" not in result.err
    assert f"{outdir / file}: exists and is not a regular file" in result.err


def test_a_damaged_result_is_named_without_numpy_warnings(tmp_path, finished):
    """A NaN thickness and an infinite velocity in result.nc: the checks name the record;
    numpy's "invalid value encountered in multiply" was printed before the message."""
    import warnings

    import netCDF4

    from multilayer.io.result_check import check_result

    _, source = finished
    outdir = tmp_path / "out"
    shutil.copytree(source, outdir)
    with netCDF4.Dataset(outdir / RESULT_FILE, "a") as ds:
        ds["h"][1, 2:9] = np.nan
        ds["u"][1, 1, :] = np.inf
    with (
        warnings.catch_warnings(record=True) as caught,
        pytest.raises(InputError, match="fails its checks: h = nan"),
    ):
        warnings.simplefilter("always")
        check_result(outdir)
    assert not [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)]


READ_ONLY_CHILD = """
import contextlib, io, json, sys
from multilayer.app.cli import main
for argv in json.loads(sys.argv[1]):
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(argv)
    print(json.dumps([code, err.getvalue()]))
"""


@pytest.mark.slow  # a child process: plot and export import matplotlib and VTK writers (7 s)
@pytest.mark.skipif(os.geteuid() != 0 or not shutil.which("setpriv"), reason="drops root's capabilities")
def test_read_only_output_directories_and_files_are_named(tmp_path, finished):
    """Run as a user who may not write there (root without the capabilities that override
    the permission bits): a run into a read-only directory, over a read-only result.nc,
    ``--resume`` of a read-only result.nc, ``plot`` and ``export`` of a read-only run
    directory and of one this user cannot enter: exit 2 naming the path and the cause, no
    traceback (a read-only file was reported as "a directory that can be created and
    written")."""
    path, source = finished
    (tmp_path / "locked").mkdir(mode=0o555)
    for name in ("over", "resumed", "shown"):
        shutil.copytree(source, tmp_path / name)
    for name in ("over", "resumed"):
        (tmp_path / name / RESULT_FILE).chmod(0o444)
    (tmp_path / "shown").chmod(0o555)
    shutil.copytree(source, tmp_path / "unlisted")
    (tmp_path / "unlisted").chmod(0o444)  # neither listed nor entered: calibration.nc was named
    cases = [
        (["run", path, "-o", "locked", "-q"], "locked: cannot be created or written (Permission denied)"),
        (
            ["run", path, "-o", "locked/sub", "-q"],
            "locked/sub: cannot be created or written (Permission denied)",
        ),
        (
            ["run", path, "-o", "over", "-q"],
            f"over/{RESULT_FILE}: Permission denied; accepted: a directory this",
        ),
        (
            ["run", path, "-o", "resumed", "-q", "--resume", "--set", "time.end=0.1"],
            f"resumed/{RESULT_FILE}: Permission denied",
        ),
        (["plot", "shown"], "shown/plots: Permission denied"),
        (["export", "shown", "--vtk"], "shown/vtk: Permission denied"),
        (
            ["plot", "unlisted"],
            "unlisted: a directory this user cannot list or enter (permissions dr--r--r--)",
        ),
        (["export", "unlisted", "--vtk"], "unlisted: a directory this user cannot list or enter"),
    ]
    child = subprocess.run(
        ["setpriv", "--bounding-set=-dac_override,-dac_read_search,-fowner", sys.executable, "-c",
         READ_ONLY_CHILD, json.dumps([[str(a) for a in argv] for argv, _ in cases])],
        cwd=tmp_path, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert child.returncode == 0, child.stderr
    for (argv, phrase), line in zip(cases, child.stdout.splitlines(), strict=True):
        code, err = json.loads(line)
        assert code == 2 and phrase in err and "Traceback" not in err, (argv, err)


@pytest.mark.parametrize(
    ("override", "phrase"),
    [
        (
            "initial.0.height=1e308",
            "initial.0 (rectangle on x in [0, 0.1] m): its mass, the integral of its thickness",
        ),
        (
            "initial=[{shape: profile, points: [[0, 1e308], [0.2, 1e308]]}]",
            "initial.0 (profile on x in [0, 0.2] m)",
        ),
        ("initial=[{shape: layer, thickness: 1e308}]", "about inf time steps"),
        ("domain.x_max=1e308", "no number of cells is enough"),
    ],
)
def test_an_initial_state_whose_sums_overflow_is_named(cli, write_scenario, override, phrase):
    """A thickness near 1e308 m: the rectangle's and the profile's mass overflowed (a numpy
    warning, then a ZeroDivisionError traceback of the step estimate: waves faster than
    1e308 m/s), a layer's waves too; a 0.1 m shape in a 1e308 m domain asked for ``inf``
    cells.  Each is exit 2 naming the entry or the step estimate, without a warning."""
    result = cli("validate", write_scenario(TINY_SCENARIO), "--set", override)
    assert result.code == 2 and "Traceback" not in result.err and "warning" not in result.err, result.err
    assert phrase in result.err and result.err.count("\n") == 1, result.err


LONG = "/".join(["a" * 200] * 25)
"""A path of 5024 characters: longer than the system takes (``File name too long``)."""


@pytest.mark.parametrize(
    "argv",
    [
        ["validate", f"{LONG}/scenario.yaml"],
        ["check", f"{LONG}/scenario.yaml"],
        ["run", "SCENARIO", "-o", LONG, "-q"],
        ["plot", LONG],
        ["validate", "SCENARIO", "--set", f"bed={{file: {LONG}/bed.csv}}"],
    ],
)
def test_a_path_too_long_for_the_system_is_quoted_once(tmp_path, cli, write_scenario, monkeypatch, argv):
    """The system's error quotes the path it could not open: the message, which names the
    path, quoted it a second time, 10 kB for a path of 5 kB."""
    scenario = str(write_scenario(TINY_SCENARIO))
    monkeypatch.chdir(tmp_path)
    result = cli(*[scenario if word == "SCENARIO" else word for word in argv])
    assert result.code == 2 and "Traceback" not in result.err, result.err
    assert result.err.count(LONG) == 1 and "File name too long" in result.err, result.err[-300:]


@pytest.mark.parametrize(
    ("text", "phrase"),
    [
        ("1: x\n", "(top level): key 1 is not text; accepted: name, description, gravity"),
        ("true: x\n", "(top level): key True is not text"),  # pydantic's own message said "1"
        ("null: x\n", "(top level): key None is not text"),
        (
            "domain: {x_min: 0.0, x_max: 0.5, cells: 40, 5: 1}\n",
            "domain (line 21): key 5 is not text; accepted: x_min",
        ),
        (
            "rheology: {name: drucker_prager, mu_s: 0.3, nu: 0.01, true: 2}\n",
            "rheology (line 22): key True is not text; accepted: name and the parameters of the law, as text",
        ),
        (
            "rheology: {name: drucker_prager, mu_s: 0.3, nu: 0.01, null: 2}\n",
            "rheology (line 22): key None is not text; accepted: name and the parameters of the law",
        ),
    ],
)
def test_a_key_yaml_reads_as_no_text_is_named_with_the_keys_accepted(cli, write_scenario, text, phrase):
    """YAML reads ``1:``, ``true:`` and ``null:`` as keys that are a number, a boolean and
    null: pydantic's "Keys should be strings" named the key ``True`` as ``1``, and said
    nothing of what is accepted (in a law's parameters: ``rheology.params.1.[key]``, a key
    of no file, and nothing accepted)."""
    data = {key: value for key, value in TINY_SCENARIO.items() if not text.startswith(key)}
    result = cli("validate", write_scenario(yaml.safe_dump(data) + text))
    assert result.code == 2 and "Traceback" not in result.err
    assert phrase in result.err, result.err


@pytest.mark.parametrize("key", ["? [a, b]\n: 1\n", "? {a: 1}\n: 1\n", "domain:\n  ? [a]\n  : 1\n"])
def test_a_list_or_mapping_as_a_key_is_malformed_yaml(cli, write_scenario, key):
    """A key that is a list or a mapping (``? [a, b]``) has no key path: the map of the
    lines, read from the composed document before its data, stopped on it with a traceback
    ("unhashable type: 'list'"). It is malformed YAML, said with its line."""
    data = {name: value for name, value in TINY_SCENARIO.items() if not key.startswith(name)}
    result = cli("validate", write_scenario(yaml.safe_dump(data) + key))
    assert result.code == 2 and "Traceback" not in result.err
    assert "found unhashable key" in result.err and "line" in result.err, result.err


@pytest.mark.parametrize(
    ("content", "phrase"),
    [
        ("x".encode("utf-16"), "UTF-16 text (it starts with the byte order mark FF FE), not UTF-8"),
        ("x".encode("utf-32"), "UTF-32 text (it starts with the byte order mark FF FE 00 00), not UTF-8"),
        (b"name: tiny\ndescription: caf\xe9\n", "not UTF-8 text: byte 0xE9 at line 2"),
        (b"name: tiny\ndescription: a\x00b\n", "(line 2, column 15): malformed YAML: the character U+0000"),
    ],
)
def test_a_scenario_file_in_another_encoding_is_named_with_the_place(tmp_path, cli, content, phrase):
    """An editor's "Unicode" (UTF-16 with its byte order mark) was "'utf-8' codec can't
    decode byte 0xff in position 0"; a control character, a message of two lines quoting
    "<unicode string>" and a position in characters."""
    path = tmp_path / "scenario.yaml"
    path.write_bytes(content)
    result = cli("validate", path)
    assert result.code == 2 and "Traceback" not in result.err and result.err.count("\n") == 1
    assert phrase in result.err, result.err


def test_a_name_longer_than_a_file_name_is_refused(cli, write_scenario):
    """The default output directory is ``results/<name>``: a name of 300 characters
    validated, and the run then failed to make its directory."""
    result = cli("validate", write_scenario({**TINY_SCENARIO, "name": "n" * 300}))
    assert result.code == 2 and "name (line 1): String should have at most 255 characters" in result.err


@pytest.mark.parametrize(
    ("hidden", "line", "column"),
    [
        ("name: tiny  # slope 25\x85slope_deg: 40\n", 1, 23),
        ("description: chute at 25 degrees\u2028slope_deg: 40\n", 1, 33),
        ("description: 'a\u2029b'\nslope_deg: 40\n", 1, 16),
        ("# note\r\n# note\rdescription: a\u2028b\n", 3, 15),
    ],
)
def test_a_line_break_of_yaml_1_1_only_is_refused_where_the_editor_shows_it(
    cli, write_scenario, hidden, line, column
):
    """libyaml's parser (YAML 1.1) ends a line at U+0085, U+2028 and U+2029, which YAML 1.2,
    the ``csv`` module and an editor do not: ``name: tiny  # slope 25<U+0085>slope_deg: 40``
    ran at 40 degrees, a key every reader of the file sees as a comment, and each such
    character shifted the line numbers of the messages after it.  It is refused at the line
    and column an editor shows (lines ended by ``\\n``, ``\\r\\n`` or ``\\r``), in a file and
    a ``--set`` value; written as an escape in a double-quoted string it is text."""
    data = {k: v for k, v in TINY_SCENARIO.items() if k not in ("name", "slope_deg")}
    body = yaml.safe_dump({"name": "tiny", **data} if "name" not in hidden else data, sort_keys=False)
    path = write_scenario(hidden + body)
    result = cli("validate", path)
    assert result.code == 2 and "Traceback" not in result.err
    assert f"{path} (line {line}, column {column}): the character U+" in result.err, result.err
    assert "accepted: lines ending at \\n, \\r\\n or \\r only" in result.err
    result = cli("validate", write_scenario(TINY_SCENARIO), "--set", "description=a\u2028slope_deg: 3")
    assert result.code == 2 and "--set description (line 1, column 2): the character U+2028" in result.err
    escaped = write_scenario(
        'description: "a\\Lb\\u2028c\\N"\n' + yaml.safe_dump(TINY_SCENARIO), "escaped.yaml"
    )
    assert multilayer.load(escaped).description == "a\u2028b\u2028c\x85"


KEY_1E5 = "k" * 100_000


@pytest.mark.parametrize(
    ("change", "overrides", "phrase"),
    [
        ({KEY_1E5: 1}, [], f"{KEY_1E5[:57]}... (line 26): unknown key"),
        ({"rheology": {**TINY_SCENARIO["rheology"], KEY_1E5: 1}}, [], f"rheology.{KEY_1E5[:57]}... (line "),
        ({"rheology": {"name": KEY_1E5}}, [], f"unknown rheology '{KEY_1E5[:56]}...; accepted"),
        ({"output": {"directory": f"~{KEY_1E5}"}}, [],
         f"'~{KEY_1E5[:55]}...: no user '{KEY_1E5[:56]}... on this"),
        ({}, [f"{KEY_1E5}=1"], f"{KEY_1E5[:57]}... (from --set): unknown key"),
        ({}, [f"domain.cells.{KEY_1E5}=1"], f"--set domain.cells.{KEY_1E5[:44]}...: domain.cells is a value"),
    ],
)  # fmt: skip
def test_a_key_or_name_of_100000_characters_is_quoted_shortened(
    cli, write_scenario, change, overrides, phrase
):
    """A key (YAML writes one longer than 1024 characters as ``? key``), a rheology's name,
    a home directory or a ``--set`` key path of 10^5 characters was quoted whole: a message of
    100 kB (200 kB for the home directory, quoted twice).  It is cut to 60 characters, as
    a value is."""
    argv = ["validate", write_scenario({**TINY_SCENARIO, **change})]
    result = cli(*argv, *(a for o in overrides for a in ("--set", o)))
    assert result.code == 2 and "Traceback" not in result.err
    assert phrase in result.err, result.err[:500]
    assert len(result.err) < 500


def test_a_size_or_an_observations_unit_of_100000_characters_is_quoted_shortened(
    tmp_path, cli, write_scenario
):
    """``--max-memory`` and an observation's ``units`` of 10^5 characters were quoted whole."""
    result = cli("validate", write_scenario(TINY_SCENARIO), "--max-memory", f"{KEY_1E5}x")
    assert (
        result.code == 2 and f"argument --max-memory: not a size: '{KEY_1E5[:56]}...; accepted" in result.err
    )
    assert len(result.err) < 800
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(TINY_SCENARIO))
    observation = {"name": "a", "quantity": "mass_final", "value": 0.005, "sigma": 0.001, "units": KEY_1E5}
    config = {"base": "base.yaml", "parameters": {"rheology.mu_s": {"bounds": [0.2, 0.4]}}}
    (tmp_path / "c.yaml").write_text(yaml.safe_dump({**config, "observations": [observation]}))
    result = cli("validate", tmp_path / "c.yaml")
    assert result.code == 2 and "observations.0.units (line " in result.err
    assert f"unknown unit '{KEY_1E5[:56]}...; accepted: m, cm" in result.err and len(result.err) < 500


@pytest.mark.parametrize("command", ["validate", "run"])
def test_a_pressure_beyond_1e308_is_named_before_the_run(tmp_path, cli, write_scenario, command):
    """A density of 1e308 kg/m^3 validated; the run's first step then blamed the rheology
    ("yield_stress() returned inf ... for pressure = inf", exit 1)."""
    argv = [command, write_scenario(TINY_SCENARIO), "--set", "material.density=1e308"]
    result = cli(*argv, *(["-o", tmp_path / "out", "-q"] if command == "run" else []))
    assert result.code == 2 and "Traceback" not in result.err
    assert "material.density, gravity, initial: the pressure under the initial material" in result.err
    assert not (tmp_path / "out" / RESULT_FILE).exists()


def test_a_plugin_value_that_overflows_is_named_without_a_numpy_warning(tmp_path, cli, write_scenario):
    """``mu_s: 1e100`` times a pressure of 4e209 Pa overflows inside the plugin: numpy's
    "overflow encountered in multiply" came before the message that names the value."""
    argv = [
        "run",
        write_scenario(TINY_SCENARIO),
        "--set",
        "rheology.mu_s=1e100",
        "--set",
        "material.density=1e210",
        "-o",
        tmp_path / "out",
        "-q",
    ]
    result = cli(*argv)
    assert result.code == 1 and "warning" not in result.err, result.err
    assert "yield_stress() returned inf (must be finite)" in result.err


def test_an_output_directory_that_is_a_file_is_named_so(tmp_path, cli, write_scenario):
    (tmp_path / "out").write_text("")
    result = cli("run", write_scenario(TINY_SCENARIO), "-o", tmp_path / "out", "-q")
    assert result.code == 2 and f"{tmp_path / 'out'}: a file, not a directory; accepted" in result.err


@pytest.mark.parametrize("name", [RESULT_FILE, CHECKPOINT_FILE, "run.log"])
def test_a_scenario_file_that_is_a_file_of_its_run_is_not_written_over(tmp_path, cli, name):
    """``multilayer run out/run.log -o out`` read the scenario, then wrote its log over it."""
    (tmp_path / "out").mkdir()
    scenario = tmp_path / "out" / name
    scenario.write_text(yaml.safe_dump(TINY_SCENARIO))
    result = cli("run", scenario, "-o", tmp_path / "out", "-q")
    assert (
        result.code == 2 and f"{scenario}: the scenario file itself, which the run would write" in result.err
    )
    assert yaml.safe_load(scenario.read_text()) == TINY_SCENARIO


@pytest.mark.parametrize("target", ["missing/out", "out"])
def test_an_output_directory_that_is_a_link_to_nothing_is_named_so(tmp_path, cli, write_scenario, target):
    """``-o`` a link whose target does not exist, or to itself: "cannot be created or
    written (File exists)", mkdir's words, which name no cause."""
    (tmp_path / "out").symlink_to(target)
    result = cli("run", write_scenario(TINY_SCENARIO), "-o", tmp_path / "out", "-q")
    assert result.code == 2, result.err
    assert f"{tmp_path / 'out'}: a symbolic link to {target}, which does not exist" in result.err


@pytest.mark.parametrize(
    ("call", "phrase"),
    [
        (lambda sim: sim.advance(True), "advance(t_target=True): a boolean; accepted: a number of seconds"),
        (lambda sim: sim.advance(10**400), "more than 1e308 s; accepted: a finite number (s)"),
        (lambda sim: sim.step(np.True_), "step(t_max=np.True_): a boolean"),
        (lambda sim: sim.load_state(None), "load_state(saved=None): accepted: a mapping"),
    ],
)
def test_times_of_the_api_are_numbers_read_as_floats(call, phrase):
    """``advance(True)`` stepped to t = 1 and kept ``t = True``; ``advance(10**400)`` was
    Python's OverflowError; ``load_state(None)`` an AttributeError.  A numpy float is read
    as a Python float: ``advance(np.float32(0.01))`` kept a float32 ``t``."""
    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    with pytest.raises(InputError, match=re.escape(phrase)):
        call(sim)
    sim.advance(np.float32(0.01))
    assert type(sim.t) is float and sim.t == float(np.float32(0.01))


def test_two_threads_stepping_one_simulation_take_turns():
    """Two threads advancing one simulation to 0.1 s interleaved the stages of their steps:
    it ended past 0.1 s with another state, silently.  They now take turns: the state is
    that of one call, to the bit."""
    scenario = multilayer.load(TINY_SCENARIO, {"time.end": 0.5})
    alone = multilayer.Simulation(scenario)
    alone.advance(0.1)
    shared = multilayer.Simulation(scenario)
    threads = [threading.Thread(target=shared.advance, args=(0.1,)) for _ in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert shared.t == 0.1 and shared.steps == alone.steps
    np.testing.assert_array_equal(shared.h, alone.h)
    np.testing.assert_array_equal(shared.u, alone.u)


RISE = " (below, the friction's rise with the inertial number is finer than the vertical step resolves)"


@pytest.mark.parametrize(
    ("override", "phrase"),
    [
        ("rheology.mu_s=1e308", "drucker_prager: mu_s must be at most 1e+100, got 1e+308"),
        ("rheology.nu=1e308", "drucker_prager: nu must be at most 1e+100, got 1e+308"),
        (
            "rheology={name: jop_mu_i, mu_s: 0.3, mu_2: 0.6, I_0: 1e-308}",
            "jop_mu_i: I_0 must be between 1e-08 and 1e+100, got 1e-308" + RISE,
        ),
        (
            "rheology={name: jop_mu_i, mu_s: 0.3, mu_2: 0.6, I_0: 1e-50}",
            "jop_mu_i: I_0 must be between 1e-08 and 1e+100, got 1e-50" + RISE,
        ),
        (
            "rheology={name: pouliquen_forterre, mu_1: 0.3, mu_2: 0.6, L: 1e-3, I_0: 1e-9}",
            "pouliquen_forterre: I_0 must be between 1e-08 and 1e+100, got 1e-09" + RISE,
        ),
        (
            "rheology={name: pouliquen_forterre, mu_1: 0.3, mu_2: 1e308, L: 1e-3, I_0: 0.3}",
            "pouliquen_forterre: mu_2 must be at most 1e+100, got 1e+308",
        ),
    ],
)
def test_a_built_in_laws_parameter_beyond_its_bounds_is_named(
    tmp_path, cli, write_scenario, override, phrase
):
    """``mu_s: 1e308`` (or ``nu``, or ``mu_2``) times any pressure overflowed in the law, and
    ``I_0: 1e-308`` made the vertical step fail: the run stopped at its first step (exit 1,
    blaming the plugin or the transport).  ``I_0: 1e-50``, within those bounds, stopped it
    at step 25 with ``h = nan`` blamed on the transport (numba's "division by zero" before
    the active set took numpy's error model): a mu(I) law's ``I_0`` is at least 1e-8
    (``_checks.SMALLEST_I_0``).  The built-in laws bound their parameters."""
    path = write_scenario(TINY_SCENARIO)
    for argv in (["validate", path], ["run", path, "-o", tmp_path / "out", "-q"]):
        result = cli(*argv, "--set", override)
        assert result.code == 2 and "Traceback" not in result.err and result.err.count("\n") == 1
        assert f"{path}: rheology (from --set): {phrase}; accepted: " in result.err, result.err
    assert not (tmp_path / "out" / RESULT_FILE).exists()


@pytest.mark.parametrize(
    ("values", "phrase"),
    [
        ("[.nan, .nan]", "entry 0 (.nan) is not a finite number"),
        ("[0.3, .inf, .inf]", "entry 1 (.inf) is not a finite number"),
    ],
)
def test_a_sweep_value_that_is_no_finite_number_is_named_so(tmp_path, cli, values, phrase):
    """``[.nan, .nan]`` was refused as a member given twice (NaN read as the same text)."""
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(TINY_SCENARIO))
    path = tmp_path / "sweep.yaml"
    path.write_text(f"base: base.yaml\nparameters:\n  rheology.mu_s: {values}\n")
    for argv in (["validate", path], ["sweep", path, "-o", tmp_path / "out"]):
        result = cli(*argv)
        assert result.code == 2 and "Traceback" not in result.err
        assert f"{path}: parameters.rheology.mu_s (line 3): {phrase}; accepted: finite numbers" in result.err


def test_a_vertical_step_iterate_that_is_not_finite_is_a_run_error_naming_the_column():
    """A mu(I) law given ``I_0 = 1e-50`` past its check: its viscosity at rest, 1e51 Pa s/m
    against layers of 4e3 kg/(m^2 s), cancelled the inertia out of a pivot of the compiled
    active set, whose ``u = inf`` compared as converged (its error bound and change compare
    false with NaN) and reached the transport of Heun's second stage (``h = nan`` "after
    transport").  The iterate is checked: a RunError naming the vertical step, x and layer."""
    scenario = multilayer.load(
        TINY_SCENARIO,
        {"rheology": {"name": "jop_mu_i", "mu_s": 0.3, "mu_2": 0.6, "I_0": 0.3}, "numerics.threads": 1},
    )
    sim = multilayer.Simulation(scenario)
    sim.vertical.stresses.bulk.I_0 = 1e-50
    with pytest.raises(
        RunError, match=r"vertical step's exact solve gave the velocity u = (inf|-inf|nan) at x = "
    ):
        sim.advance(0.2)
    assert np.isfinite(sim.u).all() and np.isfinite(sim.h).all()  # the last good state kept


def test_a_zero_pivot_of_the_normal_stress_step_is_a_run_error_naming_the_face():
    """The compiled normal-stress step was compiled with numba's default error model: a zero
    pivot of its Newton system (here a face between two cells of infinite mass) raised
    numba's bare "division by zero".  It is compiled with numpy's, as the other kernels, and
    its result is checked: a :class:`RunError` naming the face and its numbers."""
    from multilayer.engine.normal_stress import chains, plastic_chain_step

    faces = chains(np.array([False, True, True, False]), 1)
    mass, ustar = np.array([1.0, np.inf, np.inf, 1.0]), np.array([0.0, -0.5, 0.5, 0.0])
    with pytest.raises(
        RunError, match=r"^the normal-stress step is not finite at x = 0.1 m, layer 0 \(a zero pivot"
    ):
        plastic_chain_step(
            ustar, mass, faces, np.array([1e-3]), np.zeros(1), tolerance=1e-12, max_iterations=50,
            compiled=True, where=lambda f: f"x = 0.1 m, layer {f}",
        )  # fmt: skip


NORMAL_STRESS_AT_REST = {
    "walls": {"walls": {"name": "wall_friction", "mu_w": 0.3}, "domain.width": 0.1},
    "periodic sides": {"boundaries.left": "periodic", "boundaries.right": "periodic"},
    "one layer": {"domain.layers": 1},
    "non-hydrostatic": {"model.pressure": "non_hydrostatic"},
    "coulomb base": {"base": [{"condition": "coulomb", "mu": 0.4}]},
    "start friction": {"rheology.mu_start": 0.6},
}


@pytest.mark.parametrize("option", NORMAL_STRESS_AT_REST)
def test_the_normal_stress_with_each_option_keeps_a_layer_below_its_friction_exactly_at_rest(option):
    """``model.normal_stress`` with walls, periodic sides, one layer, the non-hydrostatic
    pressure, a Coulomb base or a start friction: a uniform layer on 10 degrees (friction
    0.5, tan(26.6 degrees)) stays exactly at rest, ``u == 0`` and ``h`` to the bit."""
    at_rest = {
        "slope_deg": 10.0,
        "domain.x_max": 0.2,
        "domain.cells": 20,
        "rheology.mu_s": 0.5,
        "rheology.nu": 0.0,
        "initial": [{"shape": "layer", "thickness": 0.02}],
        "boundaries.right": "wall",
        "model.normal_stress": True,
    }
    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO, {**at_rest, **NORMAL_STRESS_AT_REST[option]}))
    h = sim.h.copy()
    sim.advance(0.05)
    assert sim.steps >= 5 and np.all(sim.u == 0.0)
    np.testing.assert_array_equal(sim.h, h)


@pytest.mark.parametrize(
    "changes",
    [
        {"gate": {"x": 0.1, "lift_speed": 1.0}},
        {"initial": [{"shape": "layer", "thickness": 0.005}, *TINY_SCENARIO["initial"]]},
        {
            "boundaries": {
                "left": "inflow",
                "right": "outflow",
                "inflow": {"thickness": 0.01, "velocity": {"profile": "plug", "speed": 1.0}},
            },
            "initial": [{"shape": "rectangle", "x_min": 0.3, "x_max": 0.4, "height": 0.05}],
        },
    ],
    ids=["gate", "erodible layer", "inflow"],
)
def test_the_normal_stress_with_a_gate_an_erodible_layer_or_an_inflow_keeps_the_mass_balance(changes):
    """With ``model.normal_stress``: a column released by a gate, a column on an erodible
    layer, a supercritical inflow: while the material moves, the mass equals the initial
    mass plus what crossed the two end faces to 1e-12 (relative), and material came in
    through the inflow."""
    sim = multilayer.Simulation(
        multilayer.load({**TINY_SCENARIO, **changes, "model": {"normal_stress": True}})
    )
    mass0, crossed = float(sim.h.sum() * sim.dx), []
    sim.advance(0.05, lambda s, dt: crossed.append(s.boundary_mass.copy()))
    left, right = np.sum(crossed, axis=0)
    mass = float(sim.h.sum() * sim.dx)
    assert abs(mass - mass0 - (left - right)) <= 1e-12 * max(mass, mass0)
    assert np.abs(sim.u).max() > 0.01 and (left > 0.0) == ("inflow" in changes.get("boundaries", {}))


@pytest.mark.slow  # a Dask cluster (5 s); the fault battery tries a calibration on worker processes
def test_a_failed_member_of_a_study_is_reported_by_the_study_not_in_dasks_log(tmp_path, caplog):
    """A member whose run fails raised on its Dask worker, which logged "Compute Failed"
    with the traceback (on the user's terminal from worker processes: 36 tracebacks for a
    calibration whose runs all failed).  The task returns the failure; the study reports
    it (here a sweep on worker threads, whose log this test captures)."""
    import logging

    from dask.distributed import LocalCluster

    from multilayer.app import cli

    jop = {"name": "jop_mu_i", "mu_s": 0.3, "mu_2": 0.6, "I_0": 0.3}  # one iteration is too few
    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump({**TINY_SCENARIO, "rheology": jop}))
    path = tmp_path / "sweep.yaml"
    path.write_text("base: tiny.yaml\nparameters:\n  numerics.max_iterations: [1, 200]\n")
    caplog.set_level(logging.ERROR, logger="distributed")
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as cluster:
        code = cli.main(
            ["sweep", str(path), "-o", str(tmp_path / "out"), "--scheduler", cluster.scheduler_address]
        )
    assert code == 1
    rows = (tmp_path / "out" / "summary.csv").read_text()
    assert ",failed,RunError: " in rows and "did not reach tolerance 1e-10 in 1 iterations" in rows
    assert ",ok," in rows
    assert not [r for r in caplog.records if "Compute Failed" in r.getMessage() or r.exc_info]


def test_a_sobol_design_on_a_range_1e_300_wide_is_checked_as_any_other(tmp_path, cli):
    """With 2 base samples the halves of the design are correlated (|r| = 1): refused.  A
    parameter whose range is 1e-300 wide made the variances 0 and the correlation NaN,
    which passed the check (and printed numpy's "invalid value" warning); ``validate`` did
    not check the design at all."""
    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump(TINY_SCENARIO))
    path = tmp_path / "sobol.yaml"
    path.write_text(
        "base: tiny.yaml\nparameters:\n  rheology.mu_s: {bounds: [0.3, 0.4]}\n"
        "  slope_deg: {bounds: [1.0e-300, 2.0e-300]}\noutputs: [runout]\nsamples: 2\n"
    )
    for argv in (["validate", path], ["sensitivity", path, "-o", tmp_path / "out"]):
        result = cli(*argv)
        assert result.code == 2 and "warning" not in result.err and "Traceback" not in result.err
        assert "samples: with 2 base samples the two halves of the Sobol' design are correlated" in result.err


@pytest.mark.parametrize(
    ("key", "value", "phrase"),
    [
        ("domain.layers", 0, "domain.layers: Input should be greater than or equal to 1 (got 0)"),
        ("domain.cells", -5, "domain.cells: Input should be greater than or equal to 1 (got -5)"),
        ("time.end", float("nan"), "time.end: Input should be a finite number (got nan)"),
        ("gravity", float("inf"), "gravity: Input should be a finite number (got inf)"),
    ],
)
def test_a_scenario_changed_after_loading_is_validated_again_by_the_simulation(key, value, phrase):
    """pydantic checks no assignment: ``scenario.domain.layers = 0`` after ``multilayer.load``
    was built into a simulation whose kernels wrote outside their arrays (a mass error of
    1.8e255 m2, then "double free or corruption" when Python exited), ``cells = -5`` was
    numpy's "negative dimensions" and ``time.end = nan`` a simulation.  ``Simulation``
    validates a changed scenario again (an InputError naming the key) and keeps the
    validated copy; a valid change is honoured."""
    scenario = multilayer.load(TINY_SCENARIO)
    section, name = key.split(".") if "." in key else (None, key)
    setattr(getattr(scenario, section) if section else scenario, name, value)
    with pytest.raises(InputError) as caught:
        multilayer.Simulation(scenario)
    assert phrase in str(caught.value)
    changed = multilayer.load(TINY_SCENARIO)
    changed.domain.cells = 20
    sim = multilayer.Simulation(changed)
    assert sim.h.size == 20 and not sim.scenario.changed_since_validation()


@pytest.mark.parametrize(
    ("change", "phrase"),
    [
        (lambda s: s.rheology.params.update(mu_start=float("nan")),
         "rheology.mu_start: drucker_prager: Input should be a finite number (got nan)"),
        (lambda s: s.rheology.params.update(mu_s=float("-inf")), "(got -inf)"),
        (lambda s: setattr(s.domain, "layer_fractions", {"geometric": float("inf")}),
         "got {'geometric': inf}"),
        (lambda s: setattr(s.numerics, "threads", float("nan")), "numerics.threads: got nan"),
    ],
)  # fmt: skip
def test_a_value_assigned_nan_after_loading_is_named_as_nan_not_read_as_not_given(change, phrase):
    """A scenario changed after loading is validated again from the YAML it writes, where a
    value typed ``Any`` (a law's parameters, the layer fractions, the threads) that is NaN
    or infinite was written as null: ``mu_start = nan`` was read as no ``mu_start`` and the
    run went on without it, silently, and ``mu_s = -inf`` was said to be None."""
    scenario = multilayer.load(TINY_SCENARIO)
    change(scenario)
    with pytest.raises(InputError) as caught:
        multilayer.Simulation(scenario)
    assert phrase in str(caught.value)
    with pytest.raises(InputError, match=re.escape(phrase)):
        multilayer.run(scenario)


def test_load_state_names_a_missing_or_non_finite_entry_and_restores_nothing():
    """``load_state({})`` was a KeyError; a state whose vertical velocity, force impulse or
    Newton seed held NaN was restored and stepped on (the NaN force reached the result).
    Each is an InputError naming the entry, before anything is restored."""
    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    sim.advance(0.01)
    saved = sim.state_dict()
    with pytest.raises(InputError, match=r"^t: missing; accepted: what state_dict\(\) gives"):
        sim.load_state({})
    with pytest.raises(InputError, match=r"^seed_last: missing"):
        sim.load_state({k: v for k, v in saved.items() if k != "seed_last"})
    for key in ("w", "force_impulse", "seed_last", "seed_dt"):
        damaged = dict(saved)
        damaged[key] = np.full_like(np.asarray(saved[key], dtype=float), np.nan)
        with pytest.raises(InputError, match=rf"^{key} holds values that are not finite"):
            sim.load_state(damaged)
    # a negative thickness was restored, then named (a StateError): the simulation kept it, at
    # its time, and the next step blamed a write between steps
    with pytest.raises(InputError, match=r"^h holds negative thicknesses \(down to -0.05"):
        sim.load_state({**saved, "h": -saved["h"], "t": 5.0})
    assert sim.t == saved["t"] and np.array_equal(sim.h, saved["h"])
    # netCDF4 reads a variable as a masked array, its fill values (9.97e36) under the mask:
    # restored, a thickness of 1e37 m stopped the run saying only that the step was too short
    filled = np.ma.masked_array(np.where(saved["h"] > 0, saved["h"], 9.969e36), mask=saved["h"] == 0)
    with pytest.raises(InputError, match=r"^h: a masked array of 30 masked value\(s\)"):
        sim.load_state({**saved, "h": filled})
    sim.load_state({**saved, "h": np.ma.masked_array(saved["h"])})  # none masked: the numbers
    sim.load_state({k: v for k, v in saved.items() if not k.startswith("seed_")})  # restarts the seed


def test_load_state_of_a_mixture_needs_its_solid_and_pore_pressure_within_the_layers():
    """A mixture's state without ``solid`` restored a solid of 0 (the closure then overflowed
    on a packing of 0, blaming its coefficients), without ``pore_pressure`` a pore pressure of
    0 (exit 0, the resumed run no longer the uninterrupted one); a solid outside ``[0, l_a h]``
    was restored and blamed on a write between steps.  Each is an InputError naming the entry,
    before anything is restored; the state as saved restores."""
    mixture = {
        **TINY_SCENARIO,
        "material": {"density": 1500.0, "grain_diameter": 1e-3, "particle_density": 2500.0},
        "fluid": {"density": 1000.0, "viscosity": 1e-3},
        "mixture": {"phi_critical": 0.58, "dilatancy": 4.0, "critical_shift": 25.0},
        "initial": [{**TINY_SCENARIO["initial"][0], "phi": 0.58}],
    }
    sim = multilayer.Simulation(multilayer.load(mixture))
    sim.advance(0.01)
    saved = sim.state_dict()
    for name in ("solid", "pore_pressure"):
        with pytest.raises(
            InputError, match=rf"^{name}: missing; accepted: the state of a grain-fluid mixture"
        ):
            sim.load_state({k: v for k, v in saved.items() if k != name})
    for factor, sign in ((3.0, ""), (-1.0, "-")):
        with pytest.raises(
            InputError, match=rf"^solid holds {sign}0\.0[0-9]+ m at layer 1, column 0, outside \[0, "
        ):
            sim.load_state({**saved, "solid": saved["solid"] * factor, "t": 5.0})
    assert sim.t == saved["t"] and np.array_equal(sim.mixture.solid, saved["solid"])
    sim.load_state(saved)


def test_load_state_refuses_force_impulses_no_run_accumulates_and_an_absurd_seed_changes_nothing():
    """A finite force impulse of 1e308 was restored and written as an infinite mean force at
    the next output (-1e300 as a force of -5e301 N/m). Impulses no run accumulates are an
    InputError naming force_impulse and what is accepted.  A Newton seed of +-1.7e308 is no
    such state: it changes the work, not the answer (the uninterrupted run's within the
    Newton tolerance: found 3.5e-18 m/s apart)."""
    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))  # wall on the left, outflow on the right
    sim.advance(0.01)
    saved = sim.state_dict()
    impulse = saved["force_impulse"]
    index = {name: k for k, name in enumerate(FORCES)}
    for changes, accepted in (
        ({"force_impulse": np.full(8, 1e308)}, "impulses whose means are finite"),
        ({"force_elapsed": np.asarray(0.0)}, "zeros when force_elapsed = 0"),
        ({"force_impulse": np.where(np.arange(8) == index["gravity_force_z"], -1.0, impulse)}, "of the sign"),
        ({"force_impulse": np.where(np.arange(8) == index["gravity_force_x"], 1e300, impulse)}, "tan(theta)"),
    ):
        with pytest.raises(InputError, match=rf"^force_impulse = .*; accepted: .*{re.escape(accepted)}"):
            sim.load_state({**saved, **changes})
    assert np.array_equal(sim.forces.impulse, impulse)
    sim.advance(0.02)
    expected = sim.state_dict()
    for value in (1.7e308, -1.7e308):
        seed = np.full_like(saved["seed_last"], value)
        sim.load_state({**saved, "seed_last": seed, "seed_window": np.array([0, 40])})
        sim.advance(0.02)
        tolerance = sim.scenario.numerics.tolerance * np.abs(expected["u"]).max()
        assert np.abs(sim.u - expected["u"]).max() <= tolerance and np.array_equal(sim.h, expected["h"])


def test_a_simulation_copied_or_pickled_is_refused_naming_state_dict():
    """``copy.copy(sim)`` shared the state's arrays: stepping the copy changed the
    original's thickness but not its time (h of t = 0.0273 s held at t = 0.02 s), silently;
    ``deepcopy`` and ``pickle`` were ``TypeError: cannot pickle '_thread.RLock' object``."""
    import copy
    import pickle

    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    sim.step()
    kept = sim.state_dict()
    for attempt in (copy.copy, copy.deepcopy, pickle.dumps):
        with pytest.raises(
            InputError, match=r"^a Simulation cannot be copied or pickled .*accepted: state_dict"
        ):
            attempt(sim)
    assert np.array_equal(sim.h, kept["h"]) and sim.t == kept["t"]


def test_advance_refuses_a_time_before_now_and_an_on_step_that_is_no_function():
    """``advance(0.005)`` at t = 0.01 s returned with t = 0.01 s, as if it had gone there;
    ``on_step=5`` was a TypeError after the first step was taken."""
    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    sim.advance(0.01)
    with pytest.raises(InputError, match=r"advance\(t_target=0.005\): earlier than the current time"):
        sim.advance(0.005)
    steps = sim.steps
    with pytest.raises(InputError, match=r"advance\(on_step=5\): accepted: None or a function"):
        sim.advance(0.02, on_step=5)
    assert sim.steps == steps and sim.t == 0.01
    sim.advance(0.01)  # where it is: nothing to do


@pytest.mark.parametrize("value", [True, 2.0])
def test_a_transport_order_that_is_no_integer_is_refused(value):
    """``numerics.order: true`` and ``2.0`` validated (pydantic matches a ``Literal`` by
    equality): a boolean where a number goes, which ran as first order."""
    data = copy.deepcopy(TINY_SCENARIO)
    data["numerics"] = {"order": value}
    with pytest.raises(InputError, match=rf"numerics\.order: got {value!r}; accepted: 1 or 2"):
        multilayer.load(data)


@pytest.mark.parametrize(
    ("changes", "phrase"),
    [
        ({"fractions": ()}, "fractions = (); accepted: one number in (0, 1] per layer"),
        ({"fractions": (0.5, 0.3)}, "fractions = (0.5, 0.3); accepted: one number in (0, 1] per layer"),
        ({"cells": 0}, "cells = 0; accepted: integers > 0"),
        ({"x_max": float("nan")}, "accepted: finite numbers, x_max > x_min"),
    ],
)
def test_the_engines_configuration_refuses_a_mesh_its_kernels_cannot_index(changes, phrase):
    """The engine built by a script (docs/architecture.md) with no layer aborted the Python
    process ("double free or corruption": its kernels wrote outside their arrays); no cell
    was a ZeroDivisionError; layer fractions summing to 0.8 would make the layers' thicknesses
    ``l_a h`` add up to 0.8 h.  Its configuration refuses them, naming the field."""
    from multilayer.engine.config import SimulationConfig
    from multilayer.plugins.contract import Material

    base = {
        "x_min": 0.0, "x_max": 1.0, "cells": 10, "fractions": (0.5, 0.5),
        "material": Material(density=1500.0, grain_diameter=1e-3, particle_density=2500.0),
    }  # fmt: skip
    with pytest.raises(InputError, match=re.escape(phrase)):
        SimulationConfig(**{**base, **changes})


@pytest.mark.parametrize(
    ("numerics", "phrase"),
    [
        ({"max_iterations": 10**29}, "numerics.max_iterations: Input should be less than"),
        ({"max_iterations": 10**5 + 1}, "accepted: an integer from 1 to 100000"),
        ({"tolerance": 1e-16}, "numerics.tolerance: Input should be greater than or equal to"),
        ({"tolerance": 5e-324}, "accepted: a number >= 1e-14 (relative to the velocity scale"),
    ],
)
def test_newton_settings_no_run_can_use_are_refused(numerics, phrase):
    """``max_iterations`` of 1.2e29 validated and stopped the run at its first step with
    numba's typing error ("Int value is too large", exit 1); 1e18 would iterate without
    end.  A tolerance below 1e-14 of the velocity scale validated and failed mid-run, its
    convergence decided by round-off (exit 1 at step 37 with 2.3e-16)."""
    data = copy.deepcopy(TINY_SCENARIO)
    data["numerics"] = numerics
    with pytest.raises(InputError) as caught:
        multilayer.load(data)
    assert phrase in str(caught.value)


def test_a_bed_whose_elevations_the_thickness_cannot_be_resolved_against_is_refused():
    """The engine computes the free surface ``h + b``, whose round-off is the spacing of the
    floats at ``b``: a column on a flat bed shifted to 1e15 m ran its front to 0.094 m
    instead of 0.131 m, silently, and a bed of 1e308 m validated and failed at the first
    step blaming the transport (``u = nan``).  Elevations whose floats are farther apart
    than ``numerics.dry_threshold`` are refused, naming the bound; below it the run is the
    flat bed's to within that threshold."""
    data = copy.deepcopy(TINY_SCENARIO)
    for points in ([[0.0, 1e15], [0.5, 1e15]], [[0.0, 0.0], [0.5, 1e308]], [[-1.0, 2**35], [1.0, 0.0]]):
        data["bed"] = {"points": points}
        with pytest.raises(InputError, match=r"bed\.points: an elevation of .* coarser than numerics\.dry"):
            multilayer.load(data)
    data["bed"] = {"points": [[-1.0, 1e300], [0.0, 0.0], [0.5, 0.0]]}  # outside the domain: not used
    multilayer.load(data)
    data["numerics"] = {"dry_threshold": 1e-12}
    data["bed"] = {"points": [[0.0, 1e4], [0.5, 1e4]]}
    with pytest.raises(InputError, match=r"accepted: elevations of magnitude below 8192 m in the domain"):
        multilayer.load(data)
    del data["numerics"]
    flat = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    flat.advance(0.05)
    data["bed"] = {"points": [[0.0, 2**33 - 1], [0.5, 2**33 - 1]]}  # the highest accepted, 1e-6 m default
    shifted = multilayer.Simulation(multilayer.load(data))
    shifted.advance(0.05)
    assert shifted.steps == flat.steps and np.abs(shifted.h - flat.h).max() < 1e-6


@pytest.mark.parametrize(("ratio", "layers"), [(1e308, 3), (1e-308, 3), (1.01, 100_000)])
def test_geometric_layers_whose_fractions_are_not_all_positive_are_refused(ratio, layers):
    """``{geometric: 1e308}`` over 3 layers validated and the run stopped with the
    engine's "SimulationConfig fractions = (0.0, 0.0, nan)" after numpy's overflow
    warning; 1e-308 gave a layer of fraction 0.  Every fraction must be a number > 0."""
    data = copy.deepcopy(TINY_SCENARIO)
    data["domain"] = {**data["domain"], "layers": layers, "layer_fractions": {"geometric": ratio}}
    with pytest.raises(InputError, match=r"domain\.layer_fractions: .* over \d+ layers gives the fractions"):
        multilayer.load(data)


@pytest.mark.slow  # 1-3 s of a child process or a large input, no physics
def test_a_text_that_is_no_unicode_is_named_not_a_traceback(tmp_path):
    """A byte that is not UTF-8 in a command-line argument (Python keeps it as a lone
    surrogate) or such a text given from Python: ``--set name=$'\\xff'`` was libyaml's
    ``UnicodeEncodeError`` with a traceback (exit 1), and a ``description`` of a mapping
    validated and failed at the end of ``multilayer.run``."""
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(TINY_SCENARIO))
    for option in ("name=\udcff", "description=a\udcffb", "na\udcffme=1"):
        done = subprocess.run(
            [sys.executable, "-m", "multilayer", "validate", str(path), "--set", option],
            capture_output=True,
            text=True,
        )
        assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
        assert "which is not UTF-8 (character" in done.stderr
    data = {**copy.deepcopy(TINY_SCENARIO), "description": "a\ud800b"}
    with pytest.raises(InputError, match=r"description: 'a\\ud800b' holds U\+D800, half of a UTF-16 pair"):
        multilayer.run(data)
    with pytest.raises(InputError, match=r"a key: '\\udcff' holds the byte 0xFF"):
        multilayer.load({**TINY_SCENARIO, "\udcff": 1})
    scenario = multilayer.load(TINY_SCENARIO)
    scenario.description = "\udcff"
    with pytest.raises(InputError, match=r"<scenario>: description: '\\udcff' holds the byte 0xFF"):
        multilayer.Simulation(scenario)


def test_an_output_directory_under_the_home_directory_is_read_as_a_shell_reads_it(tmp_path, monkeypatch):
    """``output.directory: ~/runs`` (of a scenario or a sweep) is the home directory's
    ``runs``: it made a directory named ``~`` in the working directory."""
    monkeypatch.setenv("HOME", str(tmp_path))
    data = {**copy.deepcopy(TINY_SCENARIO), "output": {"directory": "~/runs/tiny"}}
    assert multilayer.load(data).output.directory == tmp_path / "runs" / "tiny"
    data["output"]["directory"] = "runs/~tiny"  # a ~ inside a name is a character of the name
    assert str(multilayer.load(data).output.directory) == "runs/~tiny"
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(TINY_SCENARIO))
    sweep = {"base": "base.yaml", "parameters": {"slope_deg": [20.0]}, "output": {"directory": "~/sweeps/s"}}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep))
    assert sweeps.load(tmp_path / "sweep.yaml").output == tmp_path / "sweeps" / "s"


@pytest.mark.slow  # 1-3 s of a child process or a large input, no physics
def test_an_output_directory_holding_the_nul_character_is_named(tmp_path):
    """A YAML ``"\\0"`` in ``output.directory`` (of a scenario, a sweep or a study) or a NUL
    in ``multilayer.run(outdir=...)``: no system call takes it, and the run or the sweep
    stopped with Python's ``ValueError: embedded null byte`` and a traceback (exit 1)."""
    data = {**copy.deepcopy(TINY_SCENARIO), "output": {"directory": "a\0b"}}
    with pytest.raises(InputError, match=r"output\.directory: 'a\\x00b' holds the NUL character"):
        multilayer.load(data)
    with pytest.raises(InputError, match=r"'x\\x00y': a name holding the NUL character; accepted: an output"):
        multilayer.run(TINY_SCENARIO, "x\0y")
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(TINY_SCENARIO))
    sweep = {"base": "base.yaml", "parameters": {"slope_deg": [20.0]}, "output": {"directory": "a\0b"}}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep))
    command = [sys.executable, "-m", "multilayer", "validate", str(tmp_path / "sweep.yaml")]
    done = subprocess.run(command, capture_output=True, text=True)
    assert done.returncode == 2 and "output.directory (line " in done.stderr
    assert "accepted: a directory path (no NUL character)" in done.stderr


@pytest.mark.parametrize("key", ["density", "particle_density"])
def test_a_density_so_small_that_the_stresses_underflow_is_refused(key):
    """A dry flow does not depend on its density: at 1e-100 kg/m^3 the tiny run is that of
    1500 kg/m^3 to round-off.  At 5e-324 the weight underflowed and the material stayed at
    rest (exit 0); at 1e-200 the run wrote forces its own result check refused."""
    with pytest.raises(
        InputError, match=rf"material\.{key} \(from --set\): 5e-324 kg/m\^3, so light that the stresses"
    ):
        multilayer.load(TINY_SCENARIO, {f"material.{key}": 5e-324})
    runs = []
    for density in (1500.0, 1e-100):
        sim = multilayer.Simulation(
            multilayer.load(TINY_SCENARIO, {f"material.{key}": density, "material.density": density})
        )
        sim.advance(0.05)
        runs.append(sim.h.copy())
    np.testing.assert_allclose(runs[1], runs[0], rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize(
    "numerics", [{"dry_threshold": 1.0}, {"dry_threshold": 1e-3}, {"front_threshold": 1e-7}]
)
def test_a_dry_threshold_not_below_the_front_threshold_is_refused(numerics):
    """A dry threshold of 1 m: the 5 cm column on a 25 degree slope stayed at rest, front
    and speed those of material that cannot move, exit 0.  Below the front threshold, the
    material that makes the front moves."""
    with pytest.raises(InputError, match=r"numerics\.dry_threshold.*m, not below front_threshold = "):
        multilayer.load(TINY_SCENARIO, {f"numerics.{key}": value for key, value in numerics.items()})


def test_more_local_workers_than_fit_in_memory_are_refused_before_any_starts(tmp_path, cli, write_scenario):
    """``--workers 100000``: the local cluster started worker after worker, its process at
    5.6 GB after ten minutes, deaf to SIGTERM."""
    (tmp_path / "sweep.yaml").write_text(
        yaml.safe_dump({"base": str(write_scenario(TINY_SCENARIO)), "parameters": {"slope_deg": [20.0]}})
    )
    result = cli("sweep", tmp_path / "sweep.yaml", "-o", tmp_path / "out", "--workers", 10**7)
    assert result.code == 2 and "Traceback" not in result.err
    assert (
        "--workers 10000000: 10000000 worker processes of about 200 MB each need 1.86 PB, more than"
        in result.err
    )
    with pytest.raises(
        InputError, match=r"accepted: at most \d+ workers here \(the default is one per core\)"
    ):
        with sweeps.dask_client(None, 10**7):
            pass


@pytest.mark.parametrize(
    ("answer", "said"),
    [
        (b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n" * 4, "MemoryError: Unable to allocate"),
        pytest.param(
            b"", "TimeoutError: no answer to the handshake within 2 s", marks=pytest.mark.slow
        ),  # the handshake's 2 s
    ],
    ids=["other bytes", "silence"],
)
def test_a_scheduler_address_answered_by_no_dask_scheduler_is_named(answer, said):
    """A server that answers a Dask client with other bytes (an HTTP server's error page):
    Dask read them as a frame length and numpy's ``MemoryError`` ('Unable to allocate 3.07
    EiB') ended ``multilayer sweep --scheduler`` with a traceback.  One that accepts and
    says nothing (an HTTP server awaiting its request line) held it for ever."""
    import socket

    import dask

    server, done = socket.create_server(("127.0.0.1", 0)), threading.Event()

    def serve() -> None:
        connection, _ = server.accept()
        with connection:
            connection.sendall(answer)
            done.wait(30)

    threading.Thread(target=serve, daemon=True).start()
    address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
    with server, dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        with pytest.raises(InputError, match=rf"--scheduler {address}: cannot connect \({said}"):
            with sweeps.dask_client(address, None):
                pass
    done.set()


def test_an_empty_output_directory_is_named_not_the_working_directory(tmp_path, monkeypatch, capsys):
    """``-o ""`` (``-o "$OUT"`` with ``OUT`` unset), ``output.directory: ""`` of a scenario or
    a study and ``multilayer.run(outdir="")``: ``Path("")`` is ``.``, and the run (or the
    calibration) wrote its files into the working directory, exit 0."""
    from multilayer.app.cli import main

    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError, match=r"output\.directory: an empty path; accepted: a directory path"):
        multilayer.load({**copy.deepcopy(TINY_SCENARIO), "output": {"directory": ""}})
    with pytest.raises(InputError, match=r"outdir: an empty path; accepted: None or the path of a directory"):
        multilayer.run(TINY_SCENARIO, "")
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(TINY_SCENARIO))
    for command in ("run", "sweep", "calibrate", "sensitivity"):
        with pytest.raises(SystemExit) as stopped:
            main([command, "base.yaml", "-o", ""])
        assert stopped.value.code == 2
        assert "argument -o/--output: an empty path; accepted: a directory path" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["base.yaml"]


def test_quiet_of_the_api_run_may_be_numpys_bool():
    """``quiet=np.True_`` (an element of a mask) was refused as not True or False: the
    scenario is what is refused here, not ``quiet``."""
    for quiet in (np.True_, np.False_):
        with pytest.raises(InputError, match=r"^<scenario>: "):
            multilayer.run({}, quiet=quiet)


@pytest.mark.parametrize(
    ("value", "said"),
    [
        (np.float64(5.0), "5.0"),
        (np.int16(7), "7"),
        (np.bool_(True), "True"),
        (np.str_("m"), "'m'"),
        (np.array(3.0), "3.0"),
        (np.float32("nan"), "nan"),
        (np.array([1.0, 2.0]), "array([1., 2.])"),
        (np.longdouble("1e400"), "np.longdouble('1e+400')"),  # beyond the floats: as it is
        (np.timedelta64(5), "np.timedelta64(5)"),  # a duration without its unit is no number
    ],
)
def test_a_message_shows_a_numpy_scalar_as_its_plain_value(value, said):
    """Another tool's netCDF attribute is read as a numpy scalar: a message said ``units
    np.float64(5.0)`` where the file holds 5.0."""
    from multilayer.errors import shown

    assert shown(value) == said


@pytest.mark.parametrize("link", ["nothing.yaml", "scenario.yaml"])
def test_a_scenario_file_that_is_a_link_to_nothing_or_in_a_loop_is_said_to_be_one(tmp_path, cli, link):
    """The scenario a symbolic link to nothing was said "file not found" (``ls`` lists it),
    and one in a loop "cannot read the file (Too many levels of symbolic links)"."""
    (tmp_path / "scenario.yaml").symlink_to(tmp_path / link)
    result = cli("validate", tmp_path / "scenario.yaml")
    assert result.code == 2
    said = f"{tmp_path / 'scenario.yaml'} is a symbolic link to nothing or in a loop; accepted: a path"
    assert said in result.err and result.err.count("\n") == 1, result.err
    assert "file not found" in cli("validate", tmp_path / "nothing.yaml").err


@pytest.mark.parametrize("quiet", ["no", 0, None, 1.0])
def test_quiet_of_the_api_run_is_a_bool(quiet):
    """``multilayer.run(quiet="no")`` was truthy: the run went silent where its caller asked
    for the progress line."""
    with pytest.raises(InputError, match=r"^quiet: got .*; accepted: True or False$"):
        multilayer.run(TINY_SCENARIO, quiet=quiet)


@pytest.mark.parametrize("where", ["forces", "state"])
def test_a_ctrl_c_while_a_step_is_kept_is_raised_after_it(monkeypatch, python_sigint, where):
    """Stepping by hand under Python's own SIGINT handler (a notebook), a Ctrl-C raised its
    ``KeyboardInterrupt`` between two statements of the step being kept: after its forces
    were recorded (the step redone recorded them again: 40.25 N/m of bed force where the run
    gives 40.32) or after its state (the time and count of the step before: one step ahead
    of its time).  It is now raised once the step is kept whole; advancing again gives the
    uninterrupted run, forces included, to the bit."""
    import signal

    from multilayer.engine import bed_force, state

    scenario = multilayer.load(TINY_SCENARIO, {"time.end": 0.1})
    alone = multilayer.Simulation(scenario)
    alone.advance(0.1)
    expected = alone.forces.take()
    cls, name = (bed_force.BedForce, "record") if where == "forces" else (state.FlowState, "commit")
    kept, calls = getattr(cls, name), []

    def interrupted(self, *args, **kwargs):
        kept(self, *args, **kwargs)
        calls.append(1)
        if len(calls) == 3:
            os.kill(os.getpid(), signal.SIGINT)  # the user's Ctrl-C, now

    sim = multilayer.Simulation(scenario)
    monkeypatch.setattr(cls, name, interrupted)
    with pytest.raises(KeyboardInterrupt):
        sim.advance(0.1)
    assert sim.steps == 3 and len(calls) == 3
    monkeypatch.undo()
    sim.advance(0.1)
    assert np.array_equal(sim.h, alone.h) and np.array_equal(sim.u, alone.u) and sim.steps == alone.steps
    assert sim.forces.take() == expected


def test_the_mesh_and_bed_of_a_simulation_cannot_be_changed_through_its_attributes():
    """``x = sim.x; x -= 0.25`` (centring the axis of a plot) changed the run silently: the
    front was -0.119 m where the run gives 0.131 m, and ``h`` differed.  ``x``, ``sigma``,
    ``fractions`` and ``bed`` are read-only views, and so are the arrays of ``sim.mesh``
    (``mesh.fractions`` was the very array the transport read): numpy refuses the write at
    the user's line, and the run is the same as one never touched."""
    scenario = multilayer.load(TINY_SCENARIO)
    alone = multilayer.Simulation(scenario)
    alone.advance(0.02)
    alone.advance(0.05)
    sim = multilayer.Simulation(scenario)
    sim.advance(0.02)
    arrays = [getattr(sim, name) for name in ("x", "sigma", "fractions", "bed")]
    arrays += [getattr(sim.mesh, name) for name in ("x", "sigma", "fractions", "interfaces")]
    for array in arrays:
        with pytest.raises(ValueError, match="read-only"):
            array -= 0.25
    sim.advance(0.05)
    assert np.array_equal(sim.h, alone.h) and np.array_equal(sim.u, alone.u)


def test_a_key_that_replaces_one_set_before_it_is_refused_naming_both(tmp_path, cli):
    """``domain.cells=20`` then ``domain={...}`` dropped the 20 silently: a sweep of
    ``domain.cells: [20, 30]`` and ``domain`` ran both members on 40 cells while its
    ``summary.csv`` said 20 and 30.  A key within an earlier one still refines it."""
    domain = json.dumps(TINY_SCENARIO["domain"])
    with pytest.raises(InputError, match=r"--set domain: replaces domain\.cells, set before it"):
        multilayer.load(TINY_SCENARIO, ["domain.cells=20", f"domain={domain}"])
    with pytest.raises(InputError, match=r"--set slope_deg: replaces slope_deg, set before it"):
        multilayer.load(TINY_SCENARIO, ["slope_deg=20", "slope_deg=30"])
    assert multilayer.load(TINY_SCENARIO, [f"domain={domain}", "domain.cells=20"]).domain.cells == 20
    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump(TINY_SCENARIO))
    (tmp_path / "sweep.yaml").write_text(
        f"base: tiny.yaml\nparameters:\n  domain.cells: [20, 30]\n  domain: [{domain}]\n"
    )
    validated = cli("validate", tmp_path / "sweep.yaml")
    assert validated.code == 2 and "replaces domain.cells, set before it" in validated.err


def test_an_expectation_whose_tolerance_overflows_is_refused():
    """``value: 1e308, rtol: 10``: a tolerance of inf, and 0.156 passed for 1e308."""
    entry = {"kind": "regression", "quantity": "front_final", "value": 1e308, "rtol": 10.0}
    with pytest.raises(InputError, match=r"expect\.0\.rtol: .* overflows: every result would pass"):
        multilayer.load({**TINY_SCENARIO, "expect": [entry]})


def test_a_path_stdout_cannot_encode_is_printed_escaped_not_a_traceback(tmp_path):
    """Under ``PYTHONIOENCODING=ascii`` a completed ``validate`` of ``sc\\xe9nario.yaml``
    ended with ``UnicodeEncodeError``, a traceback and exit 1."""
    path = tmp_path / "sc\u00e9nario.yaml"
    path.write_text(yaml.safe_dump(TINY_SCENARIO))
    env = {**os.environ, "PYTHONIOENCODING": "ascii"}
    done = subprocess.run(
        [sys.executable, "-m", "multilayer", "validate", str(path)], capture_output=True, env=env, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert b"sc\\xe9nario.yaml: ok" in done.stdout and not done.stderr


def test_check_into_one_directory_refuses_two_files_of_one_name(tmp_path, cli):
    """``check a.yaml b.yaml -o DIR`` of two scenarios named ``tiny``: the second run
    replaced ``DIR/tiny``, the first's results, silently."""
    expected = [{"kind": "regression", "quantity": "mass_final", "value": 0.005, "rtol": 0.01}]
    for name, slope in (("a.yaml", 25.0), ("b.yaml", 20.0)):
        (tmp_path / name).write_text(
            yaml.safe_dump({**TINY_SCENARIO, "slope_deg": slope, "expect": expected})
        )
    checked = cli("check", tmp_path / "a.yaml", tmp_path / "b.yaml", "-o", tmp_path / "out")
    assert checked.code == 2 and not (tmp_path / "out" / "tiny").exists()
    assert f"b.yaml: name: 'tiny', the name of {tmp_path / 'a.yaml'} too: its results" in checked.err


def test_a_study_parameter_given_a_value_in_set_or_an_experiment_is_refused(tmp_path, cli):
    """An experiment of its own ``rheology.mu_s`` (or ``set``'s) ran with the calibrated
    value: the parameter's replaced it, silently."""
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(TINY_SCENARIO))
    (tmp_path / "front.csv").write_text("t,x_f,sigma\n0.1,0.12,0.01\n")
    observation = {
        "name": "front",
        "quantity": "front",
        "file": "front.csv",
        "columns": ["t", "x_f", "sigma"],
    }
    config = {
        "base": "base.yaml",
        "parameters": {"rheology.mu_s": {"bounds": [0.2, 0.4]}},
        "experiments": {"rough": {"rheology.mu_s": 0.5}, "smooth": {"slope_deg": 20.0}},
        "observations": [{**observation, "experiment": "rough"}],
        "search": {"population": 4, "generations": 1},
    }
    for where, changed in (("experiments.rough", config), ("set", {**config, "set": {"rheology.mu_s": 0.3}})):
        if where == "set":
            changed["experiments"] = {"rough": {"slope_deg": 25.0}}
        (tmp_path / "calibration.yaml").write_text(yaml.safe_dump(changed))
        validated = cli("validate", tmp_path / "calibration.yaml")
        assert validated.code == 2, validated.err
        assert re.search(
            rf"parameters\.rheology\.mu_s \(line \d+\): also given a value in {where},", validated.err
        )


@pytest.mark.parametrize("address", ["tcp://[::1]:99999", "localhost:70000", "tcp://127.0.0.1:0"])
def test_a_scheduler_address_whose_port_is_no_port_is_named_at_once(address):
    """Dask retried a connection to port 99999 for its connection timeout (30 s), then named
    the timeout, not the port."""
    import time

    start = time.monotonic()
    with pytest.raises(
        InputError, match=r"cannot connect \(ValueError: port -?\d+ is no TCP port \(1 to 65535\)"
    ):
        with sweeps.dask_client(address, None):
            pass
    assert time.monotonic() - start < 20


def test_a_run_on_a_bed_read_from_a_file_passes_the_check_of_its_result(tmp_path, write_scenario):
    """The check of a result's mesh and bed against its scenario: a bed of a CSV file of
    more rows than cells, resampled and continued level past its end, is the bed written."""
    from multilayer.io.result_check import check_result

    x = np.linspace(0.0, 0.4, 500)
    (tmp_path / "bed.csv").write_text(
        "x (cm), z (mm)\n" + "".join(f"{100 * a!r}, {3 * math.sin(9 * a)!r}\n" for a in x.tolist())
    )
    scenario = {**TINY_SCENARIO, "bed": {"file": "bed.csv", "extend": "flat"}}
    scenario["domain"] = {**scenario["domain"], "x_min": -0.05}
    scenario["time"] = {"end": 0.04, "output_interval": 0.02}
    result = multilayer.run(write_scenario(scenario), tmp_path / "out")
    assert np.ptp(result["bed"].values) > 1e-3
    assert check_result(tmp_path / "out") == tmp_path / "out" / "result.nc"


def _tiny(**changes: object) -> dict:
    """TINY_SCENARIO with dotted keys set (list indices as integers)."""
    data = copy.deepcopy(TINY_SCENARIO)
    for key, value in changes.items():
        *parents, last = key.split("__")
        node: typing.Any = data
        for part in parents:
            node = node[int(part)] if isinstance(node, list) else node.setdefault(part, {})
        node[last] = value
    return data


def test_a_front_threshold_no_cell_can_reach_is_said_and_refused_where_expect_needs_the_front(
    tmp_path, cli, write_scenario
):
    """A front threshold above all the initial material held in one cell ran to exit 0
    with the front NaN at every output time and an empty front figure, and a `check` of the
    run-out failed on NaN after the whole run.  Now the run and `validate` say so, the
    figure says so, and an ``expect`` entry on the front is refused before any run."""
    from multilayer.io import plotting

    # the column 0.1 m x 0.05 m in one cell of 0.0125 m is 0.4 m thick
    above = write_scenario(_tiny(numerics={"front_threshold": 0.5}))
    checked = cli("validate", above)
    assert checked.code == 0 and "numerics.front_threshold = 0.5 m is thicker than any cell" in checked.err
    run = cli("run", above, "-o", tmp_path / "out", "-q")
    assert run.code == 0 and "the front is absent (NaN) at every output time" in run.err
    assert "the front is absent" in (tmp_path / "out" / "run.log").read_text()
    with results.open_result(tmp_path / "out") as ds:
        assert np.isnan(ds["front"].values).all()
        figure = plotting.front_figure(ds, "tiny")
    texts = [t.get_text() for ax in figure.axes for t in ax.texts]
    assert "no front (no cell thicker than 0.5 m) at 3 of 3 output times" in texts
    expect = [{"kind": "regression", "quantity": "runout", "value": 0.2, "rtol": 0.1}]
    refused = cli("validate", write_scenario(_tiny(numerics={"front_threshold": 0.5}, expect=expect)))
    assert refused.code == 2 and "Traceback" not in refused.err
    assert "numerics.front_threshold (line" in refused.err and "and expect checks runout" in refused.err
    assert "accepted: a number > 0 (m) up to 0.4 m" in refused.err
    at_the_bound = cli("validate", write_scenario(_tiny(numerics={"front_threshold": 0.4}, expect=expect)))
    assert at_the_bound.code == 0 and "warning" not in at_the_bound.err
    fed = _tiny(numerics={"front_threshold": 0.5}, expect=expect)
    fed["boundaries"] = {
        "left": "inflow",
        "right": "outflow",
        "inflow": {"thickness": 0.01, "velocity": {"profile": "plug", "speed": 1.0}},
    }
    assert multilayer.load(fed).numerics.front_threshold == 0.5  # an inflow brings any thickness


def test_cells_below_the_float_resolution_of_the_domain_are_refused():
    """10^4 cells of 1e-10 m at x = 1e6 m, where floats are 1.16e-10 m apart: cell edges
    coincided, the initial thickness of a cell of no width was 0/0, a numpy warning and a
    run failure (exit 1) at the initial state, naming no key."""
    far = {"domain__x_min": 1e6, "domain__x_max": 1e6 + 1e-6, "material__grain_diameter": 1e-12}
    initial = [{"shape": "rectangle", "x_min": 1e6, "x_max": 1e6 + 1e-7, "height": 0.05}]
    with pytest.raises(
        InputError, match=r"domain\.cells: 10000 cells of 1e-10 m, where floats near x = 1e\+06 m"
    ):
        multilayer.load(_tiny(**far, domain__cells=10**4, initial=initial))
    with pytest.raises(
        InputError, match=r"accepted: cells at least 1024 float spacings wide there: at most 8 cells"
    ):
        multilayer.load(_tiny(**far, domain__cells=9, initial=initial))
    assert multilayer.load(_tiny(**far, domain__cells=8, initial=initial)).domain.cells == 8
    assert multilayer.load(_tiny(domain__cells=10**6)).domain.cells == 10**6  # near x = 0: any count


@pytest.mark.parametrize(
    ("side", "velocity", "refused"),
    [
        ("left", {"profile": "plug", "speed": -5.0}, True),
        ("right", {"profile": "plug", "speed": 5.0}, True),
        ("left", {"profile": "linear", "shear_rate": -1000.0}, False),  # at rest at the bed: it enters
        ("left", {"profile": "plug", "speed": -0.1}, False),  # a reservoir: it enters against the speed
        ("right", {"profile": "plug", "speed": -5.0}, False),
    ],
)
def test_an_inflow_leaving_the_domain_faster_than_its_waves_is_refused(side, velocity, refused):
    """A left inflow at -5 m/s (out of the domain faster than the 0.59 m/s of its dam-break
    front) brought no material in: the run completed with a mass of 0, exit 0."""
    data = _tiny(initial=[])
    data["boundaries"] = {
        side: "inflow",
        "left" if side == "right" else "right": "outflow",
        "inflow": {"thickness": 0.01, "velocity": velocity},
    }
    if not refused:
        assert multilayer.load(data).boundaries.inflow is not None
        return
    with pytest.raises(
        InputError, match=rf"boundaries\.inflow\.velocity: the {side} side's inflow moves out"
    ):
        multilayer.load(data)


def test_expect_entries_no_value_can_pass_together_are_refused(cli, write_scenario):
    """An entry copied and edited beside its old pin (mass 0.005 +- 1e-4 and 0.004 +- 8e-5):
    `check` ran the whole scenario to fail one of them, exit 1."""
    pins = [
        {"kind": "regression", "quantity": "mass_final", "value": 0.005, "rtol": 0.02},
        {"kind": "regression", "quantity": "runout", "value": 0.2, "rtol": 0.5},
        {"kind": "regression", "quantity": "mass_final", "value": 0.004, "rtol": 0.02},
    ]
    for command in ("validate", "check"):
        result = cli(command, write_scenario(_tiny(expect=pins)))
        assert result.code == 2 and "Traceback" not in result.err
        assert "expect.2.value (line" in result.err
        assert (
            "mass_final = 0.004 +- 8e-05, and expect.0 asks 0.005 +- 0.0001: no value passes both"
            in result.err
        )
    pins[2]["value"] = 0.0049  # the intervals meet: a value of 0.00495 passes both
    assert cli("validate", write_scenario(_tiny(expect=pins))).code == 0


@pytest.mark.parametrize(
    ("quantity", "value", "atol", "phrase"),
    [
        (
            "max_speed_final",
            -1.0,
            0.1,
            "max_speed_final = -1.0 +- 0.1: no run passes (its max_speed_final is 0 or more)",
        ),
        ("mass_final", -1.0, 0.5, "mass_final = -1.0 +- 0.5: no run passes (its mass_final is 0 or more)"),
        (
            "static_interface_mean_final",
            -0.2,
            0.1,
            "static_interface_mean_final = -0.2 +- 0.1: no run passes",
        ),
        (
            "phi_mean_final",
            2.0,
            0.1,
            "phi_mean_final = 2.0 +- 0.1: no run passes (its phi_mean_final is in [0, 0.74048] "
            "(pi/sqrt(18), the densest packing of spheres))",
        ),
        ("phi_mean_final", -1.0, 0.1, "phi_mean_final = -1.0 +- 0.1: no run passes"),
    ],
)
def test_an_expect_entry_no_run_can_pass_is_refused(cli, write_scenario, quantity, value, atol, phrase):
    """A speed, mass or static height below 0, a solid fraction outside [0, 0.74048]: `check` ran
    the whole scenario to fail it, exit 1; refused naming the entry's value, exit 2.  A pin of
    0 +- 0 (a deposit at rest) and one whose interval reaches 0 validate."""
    extra = {}
    if quantity == "phi_mean_final":
        extra = {
            "fluid": {"density": 1000.0, "viscosity": 1e-3},
            "mixture": {"phi_critical": 0.58, "dilatancy": 4.0, "critical_shift": 25.0},
            "material": {"density": 1500.0, "grain_diameter": 1e-3, "particle_density": 2500.0},
            "initial": [{**TINY_SCENARIO["initial"][0], "phi": 0.58}],
        }
    pin = {"kind": "regression", "quantity": quantity, "value": value, "atol": atol}
    for command in ("validate", "check"):
        result = cli(command, write_scenario({**_tiny(expect=[pin]), **extra}))
        assert result.code == 2 and "Traceback" not in result.err, result.err
        assert "expect.0.value (line" in result.err and phrase in result.err, result.err
    for reachable in (0.0, -0.5 * atol):  # [-1.5 atol, 0.5 atol] reaches 0
        pin.update(value=reachable, atol=0.0 if reachable == 0.0 else atol)
        assert cli("validate", write_scenario({**_tiny(expect=[pin]), **extra})).code == 0


@pytest.mark.parametrize(
    ("base", "phrase"),
    [
        (  # between the centres 0.09375 and 0.10625 m
            [{"condition": "no_slip"}, {"condition": "coulomb", "mu": 0.5, "x_min": 0.1, "x_max": 0.105}],
            r"base\.1: condition coulomb on \[0\.1, 0\.105\] m holds no cell centre \(cells of 0\.0125 m\)",
        ),
        (  # beyond the domain
            [{"condition": "coulomb", "mu": 0.5, "x_min": 5.0, "x_max": 6.0}, {"condition": "no_slip"}],
            r"base\.0: condition coulomb on \[5\.0, 6\.0\] m holds no cell centre",
        ),
        (  # under a later zone on every cell
            [{"condition": "no_slip", "x_max": 0.2}, {"condition": "free_slip", "x_min": -1.0}],
            r"base\.0: condition no_slip on \[None, 0\.2\] m applies to no column: later entries",
        ),
        (  # under two later zones together
            [
                {"condition": "no_slip"},
                {"condition": "coulomb", "mu": 0.2, "x_min": 0.1, "x_max": 0.2},
                {"condition": "free_slip", "x_max": 0.15},
                {"condition": "free_slip", "x_min": 0.15},
            ],
            r"base\.0: condition no_slip on \[None, None\] m applies to no column",
        ),
    ],
)
def test_a_base_zone_that_applies_to_no_column_is_refused(base, phrase):
    """A zone between two cell centres, beyond the domain or under later zones on all its
    cells was ignored (a column's condition is the last zone holding its centre), exit 0."""
    with pytest.raises(InputError, match=phrase):
        multilayer.load(_tiny(base=base))


def test_base_zones_each_applying_somewhere_are_accepted_as_the_columns_take_them():
    """The check takes the cells as the engine does: a zone holds the centres in
    ``[x_min, x_max)``, the later zone wins on a centre both hold."""
    from multilayer.app import factory
    from multilayer.engine import basal
    from multilayer.engine.mesh import cell_centres

    x = cell_centres(0.0, 0.5, 40)  # x[8] = 0.10625 m, x[9] = 0.11875 m
    base = [
        {"condition": "no_slip"},
        {"condition": "coulomb", "mu": 0.5, "x_min": 0.1, "x_max": 0.10625},  # x[8] at its x_max
        {"condition": "coulomb", "mu": 0.3, "x_min": 0.11, "x_max": 0.12},
    ]
    with pytest.raises(InputError, match=r"base\.1: .* holds no cell centre"):
        multilayer.load(_tiny(base=base))
    base[1]["x_max"] = 0.1063
    friction = basal.columns(factory.basal_regions(multilayer.load(_tiny(base=base)).base), x).friction
    assert friction[8] == 0.5 and friction[9] == 0.3 and np.count_nonzero(friction) == 2
    base[2]["x_min"] = 0.10625  # now x[8] is the later zone's too
    with pytest.raises(InputError, match=r"base\.1: .* applies to no column"):
        multilayer.load(_tiny(base=base))


def test_a_mixture_or_an_inflow_sets_no_bound_on_the_front_threshold():
    """A grain-fluid mixture's thickness grows as it dilates and an inflow brings any
    thickness: no threshold is above what they can hold."""
    immersed = multilayer.load(
        os.path.join(os.path.dirname(__file__), "..", "scenarios", "submarine_collapse_loose.yaml")
    )
    assert immersed.fluid is not None and immersed.thickest_cell() is None
    assert (
        immersed.model_copy(
            update={"numerics": immersed.numerics.model_copy(update={"front_threshold": 1e6})}
        ).front_never_found()
        is None
    )
    assert multilayer.load(_tiny()).thickest_cell() == pytest.approx(0.4)


@pytest.mark.parametrize(
    ("entry", "name"),
    [("bed", RESULT_FILE), ("bed", "run.lock"), ("initial", "run.log"), ("bed", CHECKPOINT_FILE)],
)
def test_a_file_the_scenario_reads_that_is_a_file_of_its_run_is_not_written_over(tmp_path, cli, entry, name):
    """A bed file ``out/result.nc`` was read, then written over by the run it shaped (exit
    0; the scenario then named a netCDF file as its bed)."""
    (tmp_path / "out").mkdir()
    read = tmp_path / "out" / name
    if entry == "bed":
        read.write_text(BED)
        scenario = {**TINY_SCENARIO, "bed": {"file": f"out/{name}"}}
    else:
        read.write_text("x (m), h (m)\n0, 0.05\n0.1, 0.05\n0.1001, 0\n0.5, 0\n")
        scenario = {**TINY_SCENARIO, "initial": [{"shape": "profile", "file": f"out/{name}"}]}
    (tmp_path / "scenario.yaml").write_text(yaml.safe_dump(scenario))
    before = read.read_bytes()
    result = cli("run", tmp_path / "scenario.yaml", "-o", tmp_path / "out", "-q")
    key = "bed.file" if entry == "bed" else "initial.0.file"
    assert result.code == 2 and (
        f"{read}: the file {key} of {tmp_path / 'scenario.yaml'}, which the run would write over"
        in result.err
    ), result.err
    assert read.read_bytes() == before and sorted(os.listdir(tmp_path / "out")) == [name]


def test_a_run_of_no_material_and_no_inflow_is_refused(tmp_path, cli):
    """``initial: []`` and no inflow: the run completed over an empty domain (mass 0, no
    front at any output time), exit 0; a Simulation may still start empty."""
    data = _tiny(initial=[])
    (tmp_path / "scenario.yaml").write_text(yaml.safe_dump(data))
    for command in (["validate"], ["run", "-o", str(tmp_path / "out"), "-q"]):
        result = cli(command[0], tmp_path / "scenario.yaml", *command[1:])
        assert result.code == 2 and "initial: an empty list and no inflow" in result.err, result.err
    assert not (tmp_path / "out").exists()
    with pytest.raises(InputError, match="an empty list and no inflow"):
        multilayer.run(data, tmp_path / "api")
    from engine import simulation

    assert not simulation(**data).h.any()  # the engine builds an empty domain


@pytest.mark.parametrize(
    ("observation", "phrase"),
    [
        ({"quantity": "front", "file": "front.csv", "columns": ["t", "x_f", "sigma"]},
         "observed front 7 m at 0.1 s (sigma 0.01 m), more than 3 standard deviations"),
        ({"quantity": "runout", "value": -60.0, "units": "cm", "sigma": 1.0},
         "a run-out no longer than the domain, 0.5 m"),
        ({"quantity": "duration", "value": 3.0, "sigma": 0.1},
         "a duration within the simulated time, 0 to 0.05 s"),
        ({"quantity": "mass_final", "value": -0.1, "sigma": 0.01}, "(a mass >= 0)"),
    ],
)  # fmt: skip
def test_an_observation_no_run_can_come_near_is_refused(tmp_path, cli, observation, phrase):
    """A front observed at 7 m on a domain of 0.5 m was fitted: the calibration reported
    the parameters at a bound as its best fit."""
    (tmp_path / "front.csv").write_text("t,x_f,sigma\n0.05,0.12,0.01\n0.1,7,0.01\n")
    config = _calibration(tmp_path, observation)
    result = cli("validate", tmp_path / "calibration.yaml")
    assert result.code == 2 and phrase in result.err and "observations.0 (line" in result.err, result.err
    config["parameters"]["domain.x_max"] = {"bounds": [0.5, 8.0]}  # a run whose domain reaches it
    config["parameters"]["time.end"] = {"bounds": [0.2, 4.0]}
    config["set"] = {"domain.cells": 100}  # the column of 0.1 m wider than a cell of 8 m / 100
    (tmp_path / "calibration.yaml").write_text(yaml.safe_dump(config))
    reached = cli("validate", tmp_path / "calibration.yaml")
    assert (reached.code == 0) == (observation["quantity"] != "mass_final"), reached.err


@pytest.mark.parametrize(
    ("size", "phrase"),
    [
        ("1.2.3", "not a size: '1.2.3'; accepted: a finite number of bytes > 0"),
        (".", "not a size: '.'; accepted"),
        ("1e999", "not a size > 0: '1e999' is inf bytes; accepted"),
        ("1e-400k", "not a size > 0: '1e-400k' is 0 bytes; accepted"),
    ],
)
def test_a_size_python_cannot_read_or_infinite_is_named_with_what_is_accepted(tmp_path, cli, size, phrase):
    """``--max-memory 1.2.3`` was Python's "could not convert string to float", naming
    nothing accepted."""
    (tmp_path / "scenario.yaml").write_text(yaml.safe_dump(TINY_SCENARIO))
    result = cli("validate", tmp_path / "scenario.yaml", "--max-memory", size)
    assert result.code == 2 and phrase in result.err and "Traceback" not in result.err, result.err


def _front_netcdf(path, make) -> None:
    """A netCDF observation file of a front, ``make`` writing its variables into it."""
    import netCDF4

    with netCDF4.Dataset(path, "w") as ds:
        make(ds)


def _front_over(ds, coordinate=True, units="s", values=(0.02, 0.03), kind="f8") -> None:
    ds.createDimension("t", len(values))
    if coordinate:
        t = ds.createVariable("t", "f8", ("t",))
        t[:], t.units = [0.02, 0.04][: len(values)], units
    x = ds.createVariable("x_f", kind, ("t",))
    x.units = "m"
    x[:] = np.array(values, dtype=object if kind is str else kind)


def _calibration(tmp_path, observation: dict, end: float | None = None) -> dict:
    """``calibration.yaml`` in ``tmp_path``: ``rheology.mu_s`` of TINY_SCENARIO (to ``end``
    if given) fitted to ``observation``; its mapping."""
    base = (
        TINY_SCENARIO if end is None else {**TINY_SCENARIO, "time": {"end": end, "output_interval": end / 4}}
    )
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(base))
    config: dict = {"base": "base.yaml", "observations": [{"name": "seen", **observation}]}
    config["parameters"] = {"rheology.mu_s": {"bounds": [0.2, 0.4]}}
    config["search"] = {"population": 4, "generations": 1}
    (tmp_path / "calibration.yaml").write_text(yaml.safe_dump(config))
    return config


def _front_calibration(tmp_path, file: str) -> None:
    _calibration(tmp_path, {"quantity": "front", "file": file, "variable": "x_f", "sigma": 0.01}, end=2.0)


@pytest.mark.parametrize(
    ("make", "phrase"),
    [
        (lambda ds: _front_over(ds, coordinate=False),
         "the dimension t of x_f has no coordinate variable (its entries would be read at t = 0, 1, 2, ...)"),
        (lambda ds: _front_over(ds, units="seconds since 2000-01-01"),
         "t has units 'seconds since 2000-01-01', which are read as dates"),
        (lambda ds: _front_over(ds, values=("a", "b"), kind=str), "x_f holds values of type <U1"),
        (lambda ds: _front_over(ds, values=()), "x_f holds no values"),
    ],
)  # fmt: skip
def test_a_netcdf_observation_not_of_numbers_over_their_coordinate_is_named(tmp_path, cli, make, phrase):
    """A front over a dimension without a coordinate variable was read at t = 0, 1 (xarray's
    index); one of text was a traceback of ``float()``; one of no values was an observation
    of nothing, exit 0; times in dates were read as 9.5e17 s."""
    _front_netcdf(tmp_path / "front.nc", make)
    _front_calibration(tmp_path, "front.nc")
    result = cli("validate", tmp_path / "calibration.yaml")
    assert result.code == 2 and phrase in result.err and "observations.0.file (line" in result.err, result.err
    _front_netcdf(tmp_path / "good.nc", _front_over)
    _front_calibration(tmp_path, "good.nc")
    assert cli("validate", tmp_path / "calibration.yaml").code == 0


@pytest.mark.parametrize("command", ["sweep", "calibrate", "sensitivity"])
def test_a_file_a_study_reads_that_is_the_file_it_writes_is_not_written_over(tmp_path, cli, command):
    """A sweep whose base scenario was ``out/summary.csv`` wrote its summary over it (and
    a calibration's observations ``out/calibration.nc``, a sensitivity study's base
    ``out/sensitivity.nc``), exit 0."""
    pytest.importorskip("dask.distributed")
    (tmp_path / "out").mkdir()
    if command == "sweep":
        read = tmp_path / "out" / "summary.csv"
        read.write_text(yaml.safe_dump(TINY_SCENARIO))
        study = {"base": "out/summary.csv", "parameters": {"slope_deg": [20.0, 25.0]}}
        what = "the base scenario of"
    elif command == "calibrate":
        read = tmp_path / "out" / "calibration.nc"
        _front_netcdf(read, _front_over)
        _front_calibration(tmp_path, "out/calibration.nc")
        study = yaml.safe_load((tmp_path / "calibration.yaml").read_text())
        what = "the file observations.0.file of"
    else:
        pytest.importorskip("SALib")
        read = tmp_path / "out" / "sensitivity.nc"
        read.write_text(yaml.safe_dump(TINY_SCENARIO))
        study = {
            "base": "out/sensitivity.nc",
            "parameters": {"rheology.mu_s": {"bounds": [0.2, 0.4]}},
            "outputs": ["runout"],
            "samples": 8,
        }
        what = "the base scenario of"
    config = tmp_path / "study.yaml"
    config.write_text(yaml.safe_dump(study))
    before = read.read_bytes()
    result = cli(command, config, "-o", tmp_path / "out", "-q")
    assert result.code == 2 and f"{read}: {what} {config}, which the " in result.err, result.err
    assert read.read_bytes() == before and os.listdir(tmp_path / "out") == [read.name]


def test_a_sweep_of_the_members_output_directory_is_refused(tmp_path, cli):
    """Every member ran into ``DIR/mNNN`` whatever its ``output.directory`` said, exit 0."""
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(TINY_SCENARIO))
    for key, values in (("output.directory", ["a", "b"]), ("output", [{"directory": "a"}])):
        (tmp_path / "sweep.yaml").write_text(
            yaml.safe_dump({"base": "base.yaml", "parameters": {key: values}})
        )
        result = cli("validate", tmp_path / "sweep.yaml")
        assert (
            result.code == 2 and f"parameters.{key} (line 3): a member's output is not its own" in result.err
        )


def test_a_study_measuring_the_front_where_no_cell_can_reach_its_threshold_is_refused(tmp_path, cli):
    """A calibration of the front over a base whose ``numerics.front_threshold`` (0.5 m)
    no cell can reach (0.4 m at most) validated, then ran every member to fail on a NaN
    front, exit 1; a sensitivity study of the run-out alike.  A study measuring the mass
    only runs."""
    (tmp_path / "front.csv").write_text("t,x_f,sigma\n0.02,0.12,0.01\n")
    config = _calibration(
        tmp_path, {"quantity": "front", "file": "front.csv", "columns": ["t", "x_f", "sigma"]}
    )
    config["set"] = {"numerics.front_threshold": 0.5, "domain.cells": 40}
    (tmp_path / "calibration.yaml").write_text(yaml.safe_dump(config))
    result = cli("validate", tmp_path / "calibration.yaml")
    assert result.code == 2 and "base (line 1): numerics.front_threshold = 0.5 m is thicker" in result.err
    assert "and the study measures front on it" in result.err, result.err
    config["observations"] = [{"name": "mass", "quantity": "mass_final", "value": 0.005, "sigma": 1e-4}]
    (tmp_path / "calibration.yaml").write_text(yaml.safe_dump(config))
    assert cli("validate", tmp_path / "calibration.yaml").code == 0
    study = {
        "base": "base.yaml",
        "set": {"numerics.front_threshold": 0.5, "domain.cells": 40},
        "parameters": {"rheology.mu_s": {"bounds": [0.2, 0.4]}, "slope_deg": {"bounds": [20.0, 30.0]}},
        "outputs": ["mass_final", "runout"],
        "samples": 64,
    }
    (tmp_path / "sensitivity.yaml").write_text(yaml.safe_dump(study))
    result = cli("validate", tmp_path / "sensitivity.yaml")
    assert result.code == 2 and "and the study measures runout on it" in result.err, result.err


@pytest.mark.parametrize("study", ["sensitivity", "calibration"])
def test_a_study_design_beyond_its_memory_bound_is_refused_before_it_is_made(tmp_path, cli, study):
    """65536 base samples of 399 parameters (the elevations of a bed's points) asked numpy
    for 78 GiB in ``validate`` (its MemoryError, a traceback, or the machine's memory); a
    calibration of a population of 10^4 of them, 12 GiB for differential evolution."""
    n = 400
    base = {**TINY_SCENARIO, "bed": {"points": [[0.5 * i / (n - 1), 0.0] for i in range(n)]}}
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(base))
    parameters = {f"bed.points.{i}.1": {"bounds": [0.0, 0.001]} for i in range(1, n)}
    if study == "sensitivity":
        config = {"base": "base.yaml", "parameters": parameters, "outputs": ["mass_final"], "samples": 65536}
        phrase = "samples (line 1601): 65536 x (399 parameters + 2) = 26279936 runs of 399 values: 78.1 GiB"
    else:
        observation = {"name": "m", "quantity": "mass_final", "value": 0.005, "sigma": 1e-4}
        config = {"base": "base.yaml", "parameters": parameters, "observations": [observation]}
        config["search"] = {"population": 10_000}
        phrase = (
            "search.population (line 1605): 10000 x (399 parameters) = 3990000 runs of 399 values: 11.9 GiB"
        )
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(config))
    result = cli("validate", tmp_path / "study.yaml")
    assert result.code == 2 and phrase in result.err and "accepted: at most 134217728 values" in result.err, (
        result.err
    )


def _geotiff(
    path, crs="EPSG:32632", transform=None, bands=1, dtype="float64", scale=None, offset=0.0, units=None
):
    """A GeoTIFF of 40 x 80 pixels of 0.01 m, rising at 5 degrees towards +X from 100 m
    (``transform``: a rotated one of the same terrain), with the ``scale``, ``offset`` and
    the band's ``units`` given."""
    rasterio = pytest.importorskip("rasterio")
    from rasterio.transform import Affine

    x = (np.arange(80) + 0.5) * 0.01
    z = np.tile(100.0 + x * math.tan(math.radians(5.0)), (40, 1))
    if transform == "rotated":  # rows along -X, columns along +Y
        z, transform = z.T[::-1].copy(), Affine(0.0, -0.01, 0.8, 0.01, 0.0, 0.0)
    values = np.round((z - offset) / scale) if scale else z
    with rasterio.open(
        path, "w", driver="GTiff", height=z.shape[0], width=z.shape[1], count=bands, dtype=dtype, crs=crs,
        transform=transform or Affine(0.01, 0.0, 0.0, 0.0, -0.01, 0.4),
    ) as dem:  # fmt: skip
        for band in range(1, bands + 1):
            dem.write(values.astype(dtype), band)
        if scale:
            dem.scales, dem.offsets = (scale,), (offset,)
        if units:
            dem.units = (units,)


def _dem_scenario(tmp_path, tiny_scenario):
    tiny_scenario["bed"] = {"dem": "dem.tif", "polyline": [[0.05, 0.2], [0.75, 0.2]], "extend": "flat"}
    (tmp_path / "scenario.yaml").write_text(yaml.safe_dump(tiny_scenario))
    return tmp_path / "scenario.yaml"


@pytest.mark.parametrize(
    ("kind", "phrase"),
    [
        (
            {"crs": "EPSG:4326"},
            "a geographic coordinate reference system (EPSG:4326), whose coordinates are not",
        ),
        (
            {"crs": None},
            "no coordinate reference system: where its pixels lie, or in what units, is not said",
        ),
        ({"crs": "EPSG:2227"}, "map coordinates in US survey foot (0.304801 m), not metres"),
        ({"units": "ft"}, "elevations in 'ft', not metres"),
        ({"crs": "EPSG:32610+6360"}, "elevations in 'US survey foot', not metres"),
        ({"bands": 2}, "dem.tif: 2 bands, which one is the elevation is not said"),
        ({"dtype": "complex64"}, "values of type complex64, not real numbers"),
        ({"transform": (0.01, 0.01, 0.0, 0.01, 0.01, 1.0)}, "that maps its pixels on no area"),
    ],
)
def test_a_dem_not_of_elevations_in_metres_on_a_metric_map_is_refused(
    tmp_path, tiny_scenario, cli, kind, phrase
):
    """A DEM in degrees was sampled as if its pixels of 0.01 degree were 0.01 m wide, one in
    feet or without a frame as if in metres, the first of two bands or the real part of
    complex values taken as the terrain, all exit 0; a geotransform that maps the pixels on
    a line was a traceback of ``affine``."""
    if "transform" in kind:
        from rasterio.transform import Affine

        kind = {"transform": Affine(*kind["transform"])}
    _geotiff(tmp_path / "dem.tif", **kind)
    result = cli("validate", _dem_scenario(tmp_path, tiny_scenario))
    assert result.code == 2 and "bed.dem (line" in result.err and phrase in result.err, result.err
    assert "accepted: a single-band GeoTIFF of elevations in metres in a projected" in result.err


def test_a_dem_of_scaled_integers_or_a_rotated_geotransform_gives_its_terrain(tmp_path, tiny_scenario):
    """int16 tenths of a millimetre above 100 m (scale 1e-4, offset 100) were read as metres
    (a terrain of 600 m rising at 89 degrees, refused as a fold), and a geotransform rotated
    90 degrees had a pixel size of 0 (a numpy warning and a refusal); both give the terrain
    of the plain DEM."""
    _geotiff(tmp_path / "dem.tif")
    plain = np.asarray(multilayer.load(_dem_scenario(tmp_path, tiny_scenario)).bed.points)
    for kind in ({"scale": 1e-4, "offset": 100.0, "dtype": "int16"}, {"transform": "rotated"}):
        (tmp_path / "dem.tif").unlink()
        _geotiff(tmp_path / "dem.tif", **kind)
        points = np.asarray(multilayer.load(_dem_scenario(tmp_path, tiny_scenario)).bed.points)
        np.testing.assert_allclose(points, plain, atol=2e-4 if "scale" in kind else 1e-12)


@pytest.mark.slow
def test_a_dem_is_read_in_windows_around_its_polyline_never_whole(tmp_path, tiny_scenario, cli):
    """A DEM of 20000 x 20000 pixels was read whole, 3 GiB of float64 (a MemoryError under a
    limit, a traceback); read in windows it takes kilobytes.  A block larger than 2^24
    pixels, which GDAL decodes whole, is refused."""
    import tracemalloc

    rasterio = pytest.importorskip("rasterio")
    from rasterio.transform import Affine
    from rasterio.windows import Window

    for blocks in ({"tiled": True}, {"blockysize": 20000, "compress": "deflate"}):
        with rasterio.open(
            tmp_path / "dem.tif", "w", driver="GTiff", height=20000, width=20000, count=1, dtype="float32",
            crs="EPSG:32632", transform=Affine(0.01, 0.0, 0.0, 0.0, -0.01, 0.4), sparse_ok=True, **blocks,
        ) as dem:  # fmt: skip
            dem.write(np.full((40, 80), 100.0, dtype="float32"), 1, window=Window(0, 0, 80, 40))
        path = _dem_scenario(tmp_path, tiny_scenario)
        tracemalloc.start()
        try:
            result = cli("validate", path)
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        if "tiled" in blocks:
            assert result.code == 0 and peak < 100e6, (result.err, peak)
        else:
            assert result.code == 2 and "blocks of 20000 x 20000 pixels, decoded whole" in result.err


def test_a_polyline_far_outside_the_dem_is_named_without_a_numpy_warning(tmp_path, tiny_scenario, cli):
    """Samples at X = 1e300 m were cast to pixel indices: numpy's warning "invalid value
    encountered in cast" before the message."""
    _geotiff(tmp_path / "dem.tif")
    path = _dem_scenario(tmp_path, tiny_scenario)
    far = "bed.polyline=[[1e300, 0.2], [1.0000000001e300, 0.2]]"
    result = cli("validate", path, "--set", far, "--set", "bed.spacing=1e289")
    assert result.code == 2 and "no elevation at (1e+300, 0.2), 0 m along the polyline" in result.err
    assert "warning" not in result.err, result.err


def test_a_vrt_named_tif_is_not_read_through(tmp_path, tiny_scenario, cli):
    """A VRT file (XML) named ``dem.tif`` read the raster, device or URL it names, exit 0."""
    _geotiff(tmp_path / "inner.tif")
    (tmp_path / "dem.tif").write_text(
        '<VRTDataset rasterXSize="80" rasterYSize="40"><SRS>EPSG:32632</SRS>'
        "<GeoTransform>0, 0.01, 0, 0.4, 0, -0.01</GeoTransform>"
        '<VRTRasterBand dataType="Float64" band="1"><SimpleSource>'
        f'<SourceFilename relativeToVRT="0">{tmp_path / "inner.tif"}</SourceFilename>'
        "<SourceBand>1</SourceBand></SimpleSource></VRTRasterBand></VRTDataset>"
    )
    result = cli("validate", _dem_scenario(tmp_path, tiny_scenario))
    assert result.code == 2 and "not recognized as being in a supported file format" in result.err


@pytest.mark.parametrize("command", ["sweep", "calibrate", "sensitivity", "member"])
def test_a_file_the_base_scenario_of_a_study_reads_is_not_written_over_by_the_study(
    tmp_path, cli, command, tiny_scenario
):
    """A base scenario whose bed was ``out/summary.csv`` (an initial thickness
    ``out/calibration.nc``, a bed ``out/sensitivity.nc``) had it written over by the study
    into ``out``, exit 0; one in a member's directory, ``out/<member>/member.json``, was
    deleted when the member started."""
    pytest.importorskip("dask.distributed")
    out = tmp_path / "out"
    out.mkdir()
    sweep = {"base": "base.yaml", "parameters": {"slope_deg": [20.0, 25.0]}}
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(sweep))
    read = out / {"sweep": "summary.csv", "calibrate": "calibration.nc", "sensitivity": "sensitivity.nc"}.get(
        command, "member.json"
    )
    if command == "member":
        (tmp_path / "base.yaml").write_text(yaml.safe_dump(tiny_scenario))
        read = out / sweeps.load(tmp_path / "study.yaml").members()[0].id / "member.json"
        read.parent.mkdir()
    if command == "calibrate":
        read.write_text("x (m), h (m)\n0, 0.05\n0.1, 0.05\n0.1001, 0\n0.5, 0\n")
        tiny_scenario["initial"] = [{"shape": "profile", "file": "out/calibration.nc"}]
        key = "initial.0.file"
        study = {
            "base": "base.yaml",
            "parameters": {"rheology.mu_s": {"bounds": [0.2, 0.4]}},
            "observations": [{"name": "m", "quantity": "mass_final", "value": 0.005, "sigma": 1e-4}],
            "search": {"population": 4, "generations": 1},
        }
    else:
        read.write_text(BED)
        tiny_scenario["bed"] = {"file": read.relative_to(tmp_path).as_posix()}
        key = "bed.file"
        study = sweep
        if command == "sensitivity":
            pytest.importorskip("SALib")
            study = {
                "base": "base.yaml",
                "parameters": {"rheology.mu_s": {"bounds": [0.2, 0.4]}},
                "outputs": ["mass_final"],
                "samples": 16,
            }
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(tiny_scenario))
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(study))
    before = read.read_bytes()
    result = cli("sweep" if command == "member" else command, tmp_path / "study.yaml", "-o", out, "-q")
    assert result.code == 2 and f"{read}: the file {key} of {tmp_path / 'base.yaml'}" in result.err, (
        result.err
    )
    if command == "member":
        assert (
            f"in the subdirectory {read.parent.name} of {out}, where a member of the sweep runs" in result.err
        )
    assert read.read_bytes() == before


def test_a_calibration_of_more_runs_than_its_bound_is_refused_naming_the_counts(tmp_path, cli):
    """10^4 generations of a population of 10^4 over 2 parameters and 2 experiments asked
    for 4 x 10^8 runs, accepted; the default search of the shipped study is far below."""
    from multilayer.scenario.limits import MAX_STUDY_RUNS

    (tmp_path / "base.yaml").write_text(yaml.safe_dump(TINY_SCENARIO))
    study = {
        "base": "base.yaml",
        "parameters": {"rheology.mu_s": {"bounds": [0.2, 0.4]}, "slope_deg": {"bounds": [20.0, 30.0]}},
        "experiments": {"a": {}, "b": {"time.end": 0.3}},
        "observations": [
            {"name": n, "experiment": n, "quantity": "mass_final", "value": 0.005, "sigma": 1e-4}
            for n in "ab"
        ],
        "search": {"population": 10_000, "generations": 10_000},
    }
    (tmp_path / "calibration.yaml").write_text(yaml.safe_dump(study))
    result = cli("validate", tmp_path / "calibration.yaml")
    runs = 2 * (10_000 * 2 * 10_001 + 10 * 3 + 4)
    assert result.code == 2 and runs > MAX_STUDY_RUNS
    assert (
        "search.generations (line" in result.err
        and f"2 experiment(s) x (10000 x 2 parameters x (10000 generations + 1) + 10 evaluations x (2 + 1) "
        f"+ 2 x 2) = {runs:.3g} runs; accepted: a study of at most 1e+07 runs"
        in result.err
    ), result.err
    study["search"] = {"population": 500, "generations": 4}  # 2 x (500 x 2 x 5 + 34) = 10068
    (tmp_path / "calibration.yaml").write_text(yaml.safe_dump(study))
    assert cli("validate", tmp_path / "calibration.yaml").code == 0


def test_a_file_in_a_subdirectory_of_a_study_that_is_no_members_is_read(tmp_path):
    """Only a member's directory (``m<index>-<hash>``, ``e-<hash>``) is the study's: a base
    scenario ``scenarios/base.yaml`` of a study run with ``-o .`` is read."""
    from multilayer.app.commands import in_a_member

    for name in ("scenarios", "m1", "e-1234567", "m001-1234abcdz"):
        (tmp_path / name).mkdir()
        in_a_member(tmp_path, {"the base scenario": tmp_path / name / "base.yaml"}, "sweep")
    for name in ("m001-1234abcd", "e-0123abcd"):
        with pytest.raises(
            InputError, match=f"in the subdirectory {name} of .*, where a member of the sweep"
        ):
            in_a_member(tmp_path, {"the base scenario": tmp_path / name / "base.yaml"}, "sweep")


@pytest.mark.parametrize("command", ["sweep", "calibrate"])
def test_a_file_a_member_or_an_experiment_reads_is_not_written_over_by_the_study(tmp_path, cli, command):
    """A sweep of ``bed.file: [flat.csv, out/summary.csv]`` and a calibration whose
    experiment reads the bed ``out/calibration.nc`` wrote over that file, exit 0."""
    pytest.importorskip("dask.distributed")
    (tmp_path / "out").mkdir()
    name = "summary.csv" if command == "sweep" else "calibration.nc"
    read = tmp_path / "out" / name
    for path in (read, tmp_path / "flat.csv"):
        path.write_text(BED)
    base = {**TINY_SCENARIO, "bed": {"file": "flat.csv"}}
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(base))
    if command == "sweep":
        study = {"base": "base.yaml", "parameters": {"bed.file": ["flat.csv", f"out/{name}"]}}
        what = f"{read}: the file bed.file of member m001-"
    else:
        study = {
            "base": "base.yaml",
            "parameters": {"rheology.mu_s": {"bounds": [0.2, 0.4]}},
            "experiments": {"a": {}, "b": {"bed.file": f"out/{name}"}},
            "observations": [
                {"name": "m", "experiment": "a", "quantity": "mass_final", "value": 0.005, "sigma": 1e-4}
            ],
            "search": {"population": 4, "generations": 1},
        }
        what = f"{read}: the file bed.file of {tmp_path / 'base.yaml'}"
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(study))
    result = cli(command, tmp_path / "study.yaml", "-o", tmp_path / "out", "-q")
    assert result.code == 2 and what in result.err, result.err
    assert read.read_text() == BED and os.listdir(tmp_path / "out") == [name]


def _rewritten_dem(path, values=None, dtype="float64", nodata=None, **profile):
    """The GeoTIFF ``path`` written again with ``values`` (default its own), of ``dtype``,
    a ``nodata`` value and the creation options ``profile``; ``values`` may be a
    ``(window, array)`` pair, only that window written."""
    rasterio = pytest.importorskip("rasterio")
    from rasterio.windows import Window

    with rasterio.open(path) as dem:
        z, options = dem.read(1), {**dem.profile, "dtype": dtype, "nodata": nodata, **profile}
    window, block = values if isinstance(values, tuple) else (Window(0, 0, 80, 40), z)
    with rasterio.open(path, "w", **options) as dem:
        dem.write(block.astype(dtype), 1, window=window)


def test_a_sparse_dem_without_nodata_is_refused_where_its_polyline_crosses_an_unwritten_block(
    tmp_path, tiny_scenario, cli
):
    """GDAL reads a block never written into a sparse GeoTIFF as zeros: without a nodata
    value the terrain dropped from 100 m to 0 m where the polyline crossed one, exit 0.
    Unwritten blocks elsewhere are no matter."""
    rasterio = pytest.importorskip("rasterio")
    from rasterio.windows import Window

    _geotiff(tmp_path / "dem.tif")
    path = _dem_scenario(tmp_path, tiny_scenario)
    plain = np.asarray(multilayer.load(path).bed.points)
    with rasterio.open(tmp_path / "dem.tif") as dem:
        z = dem.read(1)
    sparse = {"tiled": True, "blockxsize": 32, "blockysize": 32, "sparse_ok": True}
    for window, code in ((Window(0, 0, 32, 32), 2), (Window(0, 0, 80, 32), 0)):
        _rewritten_dem(tmp_path / "dem.tif", (window, z[: window.height, : window.width]), **sparse)
        result = cli("validate", path)
        assert result.code == code, result.err
        if code:
            where = (
                f"{tmp_path / 'dem.tif'}: the block of pixels (0-31, 32-63) (rows, columns) on the polyline"
            )
            assert where in result.err, result.err
            assert "was never written (a sparse GeoTIFF) and the DEM has no nodata value" in result.err
        else:
            np.testing.assert_allclose(np.asarray(multilayer.load(path).bed.points), plain, atol=1e-12)
    _rewritten_dem(tmp_path / "dem.tif", (Window(0, 0, 32, 32), z[:32, :32]), nodata=-9999.0, **sparse)
    result = cli("validate", path)
    assert result.code == 2 and "dem.tif: no elevation at" in result.err, result.err


@pytest.mark.parametrize(("value", "dtype"), [(1e308, "float64"), (-3.4028234663852886e38, "float32")])
def test_an_elevation_farther_than_the_earths_radius_is_named_with_its_pixel(
    tmp_path, tiny_scenario, cli, value, dtype
):
    """A pixel of 1e308 m was refused as terrain rising too steeply, its value and pixel
    unnamed; float32's fill value written undeclared likewise."""
    _geotiff(tmp_path / "dem.tif")
    rasterio = pytest.importorskip("rasterio")
    with rasterio.open(tmp_path / "dem.tif") as dem:
        z = dem.read(1)
    z[20, 40] = value
    _rewritten_dem(tmp_path / "dem.tif", (rasterio.windows.Window(0, 0, 80, 40), z), dtype=dtype)
    result = cli("validate", _dem_scenario(tmp_path, tiny_scenario))
    assert result.code == 2, result.err
    assert (
        f"dem.tif: an elevation of {float(np.array(value, dtype)):g} m at pixel (row 20, column 40)"
        in result.err
    )
    assert "accepted: elevations within 1e+07 m of the datum" in result.err


@pytest.mark.parametrize(
    ("band", "phrase"),
    [
        ("<Scale>0.3048</Scale>", "dem.tif.aux.xml changes its scales from (1.0,) to (0.3048,)"),
        (
            "<NoDataValue>-1</NoDataValue><Offset>-100</Offset>",
            "changes its nodata from None to -1.0, offsets",
        ),
        ('<Metadata><MDI key="STATISTICS_MEAN">100.1</MDI></Metadata>', ""),
    ],
)
def test_a_sidecar_that_changes_what_the_dem_says_is_refused(tmp_path, tiny_scenario, cli, band, phrase):
    """GDAL applies a ``dem.tif.aux.xml`` beside the DEM over what the GeoTIFF says: a scale
    of 0.3048 there read the terrain in feet, exit 0.  One of statistics only changes
    nothing."""
    _geotiff(tmp_path / "dem.tif")
    (tmp_path / "dem.tif.aux.xml").write_text(
        f'<PAMDataset><PAMRasterBand band="1">{band}</PAMRasterBand></PAMDataset>'
    )
    result = cli("validate", _dem_scenario(tmp_path, tiny_scenario))
    assert result.code == (2 if phrase else 0) and phrase in result.err, result.err


@pytest.mark.parametrize("ignore", [None, "YES"])
def test_a_dem_cut_short_gives_gdals_reason(tmp_path, tiny_scenario, cli, monkeypatch, ignore):
    """A tiled, deflated DEM cut to half its bytes was "cannot read the DEM (Read failed. See
    previous exception for details.)": the previous exception is GDAL's reason.  Under
    ``GTIFF_IGNORE_READ_ERRORS=YES`` GDAL read the missing blocks as zeros, exit 0."""
    if ignore:
        monkeypatch.setenv("GTIFF_IGNORE_READ_ERRORS", ignore)
    _geotiff(tmp_path / "dem.tif")
    _rewritten_dem(tmp_path / "dem.tif", tiled=True, blockxsize=32, blockysize=32, compress="deflate")
    data = (tmp_path / "dem.tif").read_bytes()
    (tmp_path / "dem.tif").write_bytes(data[: len(data) // 2])
    result = cli("validate", _dem_scenario(tmp_path, tiny_scenario))
    assert result.code == 2 and "cannot read the DEM (" in result.err, result.err
    assert "IReadBlock failed" in result.err and "See previous exception" not in result.err


def test_a_run_extended_from_an_end_between_output_times_says_what_differs(tmp_path, tiny_scenario, cli):
    """A run to 0.21 s (output every 0.02 s) extended to 0.3 s kept its record at 0.21 s and
    took other steps than a run to 0.3 s (1.9e-6 m apart in h at the end), and said nothing.
    From 0.2 s it is that run, to the bit, and says nothing."""
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(tiny_scenario))
    for end, said in ((0.21, True), (0.2, False)):
        out = tmp_path / f"to_{end}"
        assert cli("run", path, "-o", out, "--set", f"time.end={end}", "-q").code == 0
        result = cli("run", path, "-o", out, "--set", "time.end=0.3", "--resume", "-q")
        assert result.code == 0, result.err
        message = (
            f"extending from t = {end:g} s (the time.end {end:g} s it ran to), not an output time of k x"
        )
        assert (message in result.err) is said, result.err
        times = results.open_result(out)["time"].values
        assert (0.21 in times.round(12)) is said and times[-1] == 0.3


@pytest.mark.parametrize(
    ("key", "value", "phrase"),
    [
        ("initial", lambda: (entry for entry in TINY_SCENARIO["initial"]), "initial: <generator object"),
        ("bed", lambda: {"profile": "file", "file": open(os.devnull)}, "bed.file: <_io.TextIOWrapper"),
        ("domain", lambda: {**TINY_SCENARIO["domain"], "x_max": np.timedelta64(5)}, "domain.x_max: np."),
        ("bed", lambda: {"points": np.array([[0, 0], [5, 0]], dtype="m8")}, "bed.points: array("),
    ],
)
def test_a_python_value_that_is_no_number_or_cannot_be_copied_is_named(key, value, phrase):
    """A generator or an open file in the mapping given to ``multilayer.load`` raised
    ``TypeError: cannot pickle 'generator' object`` from the deep copy of the overrides; a
    numpy duration of no unit was read as the integer it counts (``np.timedelta64(5)``:
    a domain 5 m long)."""
    data = {**TINY_SCENARIO, key: value()}
    with pytest.raises(InputError, match="^<scenario>: ") as raised:
        multilayer.load(data)
    assert phrase in str(raised.value), raised.value
    assert "is a numpy date or duration" in str(raised.value) or "(it cannot be copied)" in str(raised.value)
    with pytest.raises(InputError, match=r"^overrides: time\.end: np\.timedelta64\(1\) is a numpy date"):
        multilayer.load(TINY_SCENARIO, {"time.end": np.timedelta64(1)})
    points = np.array([[0.0, 0.0], [0.5, -0.1]], dtype=object)  # numbers held as objects: read
    assert multilayer.load({**TINY_SCENARIO, "bed": {"points": points}}).bed.points == [[0, 0], [0.5, -0.1]]


@pytest.mark.parametrize(
    ("given", "parameter", "where"),
    [
        ({"set": {"rheology": {"name": "drucker_prager", "mu_s": 0.3, "nu": 0.01}}}, "rheology.mu_s",
         "set.rheology"),
        ({"experiments": {"a": {"rheology": {"name": "drucker_prager", "mu_s": 0.3, "nu": 0.01}}, "b": {}}},
         "rheology.mu_s", "experiments.a.rheology"),
        ({"set": {"initial": copy.deepcopy(TINY_SCENARIO["initial"])}}, "initial.0.height", "set.initial"),
    ],
)  # fmt: skip
def test_a_study_parameter_given_a_value_within_a_key_above_it_is_refused(
    tmp_path, cli, given, parameter, where
):
    """``set: {rheology: {name: drucker_prager, mu_s: 0.3, nu: 0.01}}`` beside the parameter
    ``rheology.mu_s``: validated and run with the calibrated mu_s, set's silently replaced
    (``set: {rheology.mu_s: 0.3}`` was refused).  A key above that does not hold the
    parameter (``set: {initial: [...]}`` beside ``rheology.mu_s``) is read."""
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(TINY_SCENARIO))
    observation = {"name": "m", "quantity": "mass_final", "value": 0.005, "sigma": 0.001}
    config = {
        "base": "base.yaml",
        "parameters": {parameter: {"bounds": [0.2, 0.4] if "mu_s" in parameter else [0.04, 0.06]}},
        "observations": [{**observation, **({"experiment": "a"} if "experiments" in given else {})}],
        "search": {"population": 4, "generations": 1},
        **given,
    }
    (tmp_path / "calibration.yaml").write_text(yaml.safe_dump(config))
    validated = cli("validate", tmp_path / "calibration.yaml")
    assert validated.code == 2, validated.err
    assert re.search(
        rf"parameters\.{re.escape(parameter)} \(line \d+\): also given a value in {where},", validated.err
    )
    if where == "set.initial":
        config["parameters"] = {"rheology.mu_s": {"bounds": [0.2, 0.4]}}
        (tmp_path / "calibration.yaml").write_text(yaml.safe_dump(config))
        assert cli("validate", tmp_path / "calibration.yaml").code == 0


@pytest.mark.parametrize(
    ("directory", "home", "phrase"),
    [
        ("~nosuchuser/x", None, "'~nosuchuser/x': no user 'nosuchuser' on this system"),
        ("~/x", "", "'~/x': HOME is '', not an absolute path"),
        ("~/x", "relative", "'~/x': HOME is 'relative', not an absolute path"),
    ],
)
def test_an_output_directory_under_a_home_that_is_not_known_is_refused(
    tmp_path, cli, monkeypatch, directory, home, phrase
):
    """``output.directory: ~nosuchuser/x`` ran into a directory named ``~nosuchuser`` in the
    working directory (a sweep's stopped with ``RuntimeError: Could not determine home
    directory.`` and a traceback); ``~/x`` under an empty ``HOME`` into ``/x``, in the
    root directory."""
    if home is not None:
        monkeypatch.setenv("HOME", home)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "base.yaml").write_text(yaml.safe_dump({**TINY_SCENARIO, "output": {"directory": directory}}))
    sweep = {"base": "base.yaml", "parameters": {"slope_deg": [20, 25]}, "output": {"directory": directory}}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep))
    (tmp_path / "plain.yaml").write_text(yaml.safe_dump(TINY_SCENARIO))
    for command in (("validate", "base.yaml"), ("run", "base.yaml", "-q"), ("sweep", "sweep.yaml", "-q")):
        result = cli(*command)
        assert result.code == 2 and "output.directory (line " in result.err and phrase in result.err, (
            result.err
        )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["base.yaml", "plain.yaml", "sweep.yaml"]
    monkeypatch.setenv("HOME", str(tmp_path))
    (tmp_path / "base.yaml").write_text(yaml.safe_dump({**TINY_SCENARIO, "output": {"directory": "~/x"}}))
    assert cli("validate", "base.yaml").code == 0


@pytest.mark.parametrize(("given", "missing"), [("fluid", "mixture"), ("mixture", "fluid")])
def test_a_fluid_without_a_mixture_is_said_so(tmp_path, cli, given, missing):
    """``fluid`` given alone was "mixture: fluid and mixture are given together"."""
    keys = {
        "fluid": {"density": 1000.0, "viscosity": 1e-3},
        "mixture": {"phi_critical": 0.58, "dilatancy": 4.0, "critical_shift": 25.0},
    }
    (tmp_path / "s.yaml").write_text(yaml.safe_dump({**TINY_SCENARIO, given: keys[given]}))
    result = cli("validate", tmp_path / "s.yaml")
    assert result.code == 2
    assert re.search(
        rf"s\.yaml: {given} \(line \d+\): {given} is given without {missing}; accepted: both", result.err
    )


@pytest.mark.parametrize(
    ("fractions", "thinnest"), [([5e-324, 0.5, 0.5], "4.94e-324"), ({"geometric": 1e-160}, "1e-320")]
)
def test_a_layer_too_thin_for_a_normal_float_at_the_dry_threshold_is_refused(
    tmp_path, cli, fractions, thinnest
):
    """``domain.layer_fractions: [5e-324, 0.5, 0.5]`` validated, and the run failed at its
    first step (exit 1, a NaN velocity: the layer was 0 m thick in every column thinner than
    1 m); ``[1e-301, 0.5, 0.5]`` (1e-307 m at the dry threshold of 1e-6 m) runs."""
    data = copy.deepcopy(TINY_SCENARIO)
    data["domain"]["layer_fractions"] = fractions
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(data))
    for command in ("validate", "run"):
        result = cli(
            command, tmp_path / "s.yaml", *(["-o", tmp_path / "out", "-q"] if command == "run" else [])
        )
        assert result.code == 2 and not (tmp_path / "out").exists(), result.err
        assert re.search(
            rf"domain\.layer_fractions \(line \d+\): a layer fraction of {thinnest}: in a column", result.err
        )
        assert "accepted: layer fractions >= 2.23e-308 m / numerics.dry_threshold = 2.23e-302" in result.err
    data["domain"]["layer_fractions"] = [1e-301, 0.5, 0.5]
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(data))
    assert cli("validate", tmp_path / "s.yaml").code == 0


@pytest.mark.parametrize(
    ("inflow", "said"),
    [
        (
            {"thickness": 1e308, "velocity": {"profile": "plug", "speed": 1.0}},
            "an inflow 1e+308 m thick at 1 m/s",
        ),
        (
            {"thickness": 0.01, "velocity": {"profile": "plug", "speed": 1e308}},
            "an inflow 0.01 m thick at 1e+308",
        ),
    ],
)
def test_an_inflow_whose_waves_or_momentum_overflow_is_named(tmp_path, cli, inflow, said):
    """An inflow 1e308 m thick was refused for the steps of its waves, naming the time and
    the domain keys, and under ``--force`` stopped the run at its first step blaming the
    state (0.05 m at rest); one at 1e308 m/s, for a step that did not advance the time,
    naming a wave of 0.67 m/s.  An inflow of 0.01 m at 1 m/s runs."""
    data = copy.deepcopy(TINY_SCENARIO)
    data["boundaries"] = {"left": "inflow", "right": "outflow", "inflow": inflow}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(data))
    for command in (("validate",), ("run", "--force", "-q", "-o", tmp_path / "out")):
        result = cli(command[0], tmp_path / "s.yaml", *command[1:])
        assert result.code == 2 and not (tmp_path / "out").exists(), result.err
        assert re.search(rf"boundaries\.inflow \(line \d+\): {re.escape(said)}", result.err), result.err
        assert "is no finite number; accepted: an inflow whose thickness and speed" in result.err
    data["boundaries"]["inflow"] = {"thickness": 0.01, "velocity": {"profile": "plug", "speed": 1.0}}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(data))
    assert cli("validate", tmp_path / "s.yaml").code == 0


@pytest.mark.slow  # a child process as a user (2 s)
@pytest.mark.skipif(os.geteuid() != 0 or not shutil.which("setpriv"), reason="drops root's capabilities")
def test_a_umask_that_takes_the_owners_permissions_is_named(tmp_path, write_scenario):
    """Under ``umask 0177`` the output directory the run makes cannot be entered by its
    owner: the message said "Permission denied" of a directory the command had just made."""
    command = 'umask 0177 && exec "$@"'
    child = subprocess.run(
        ["setpriv", "--bounding-set=-dac_override,-dac_read_search,-fowner", "sh", "-c", command, "sh",
         sys.executable, "-m", "multilayer", "run", str(write_scenario(TINY_SCENARIO)), "-o", "out", "-q"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert child.returncode == 2 and "Traceback" not in child.stderr, child.stderr
    assert (
        "out: cannot be created or written (Permission denied): the umask 0177 leaves the directories made "
        "here without permissions their owner needs (drw-------)"
    ) in child.stderr


def test_the_umask_is_read_without_being_set():
    """``os.umask`` sets the process's umask to read it (for every thread of a host): it is
    read from ``/proc`` and left as it is."""
    from multilayer.app.runner import umask

    before = os.umask(0o027)
    try:
        assert umask() == 0o027 and os.umask(0o027) == 0o027
    finally:
        os.umask(before)


def test_a_removed_working_directory_is_named(tmp_path, cli, write_scenario, monkeypatch):
    """A shell left in a directory another removed: the first relative path resolved
    (``validate``'s default output directory) failed with ``[Errno 2] No such file or
    directory`` naming nothing, a run's with "results/tiny: cannot be created or written";
    commands of absolute paths and ``plugins`` run."""
    scenario = write_scenario(TINY_SCENARIO)
    gone = tmp_path / "gone"
    gone.mkdir()
    monkeypatch.chdir(gone)
    gone.rmdir()
    said = "the working directory no longer exists (removed after this shell entered it)"
    result = cli("validate", scenario)
    assert result.code == 2 and said in result.err and "Errno" not in result.err, result.err
    result = cli("run", scenario, "-q")
    assert result.code == 2 and f"results/tiny: {said}" in result.err, result.err
    assert cli("run", scenario, "-o", tmp_path / "out", "-q").code == 0
    assert cli("plugins").code == 0


def test_a_compilation_in_a_removed_working_directory_is_named(tmp_path, monkeypatch):
    """numba makes the path of a kernel's source relative for its messages while compiling
    (``os.path.relpath``): in a removed working directory that raised ``FileNotFoundError``
    naming no file, from ``multilayer.run`` of absolute paths too."""
    import logging

    from multilayer.app.compilation import compile_notice

    def compiling() -> None:
        numba = __import__("numba")

        @numba.njit
        def fresh(x):  # compiled here, on its first call
            return x + 1

        fresh(1)
        os.rmdir(gone)
        os.path.relpath(__file__)  # what numba's messages of a kernel's source do (numba.core.ir.Loc)

    gone = tmp_path / "gone"
    gone.mkdir()
    monkeypatch.chdir(gone)
    with pytest.raises(InputError, match="^the working directory no longer exists"):
        with compile_notice(logging.getLogger("test"), None):
            compiling()


def test_a_masked_value_or_a_0d_object_array_in_a_mapping_is_read_as_numpy_holds_it():
    """``tolist()`` reads a masked value as None: ``slope_deg: np.ma.masked`` was refused as
    "got None", naming no mask; a 0-d object array (what ``np.array(x, dtype=object)``
    makes of a number) raised ``TypeError: iteration over a 0-d array``."""
    masked = "a masked array of 1 masked value(s) (a netCDF file's fill values, or np.ma.masked)"
    with pytest.raises(InputError, match=re.escape(f"<scenario>: slope_deg: {masked}")):
        multilayer.load({**TINY_SCENARIO, "slope_deg": np.ma.masked})
    with pytest.raises(InputError, match=re.escape(f"overrides: rheology.mu_s: {masked}")):
        multilayer.load(TINY_SCENARIO, {"rheology.mu_s": np.ma.masked})
    points = np.ma.array([[0.0, 0.0], [0.5, 0.1]], mask=[[0, 0], [0, 1]])
    with pytest.raises(InputError, match=re.escape(f"<scenario>: bed.points: {masked}")):
        multilayer.load({**TINY_SCENARIO, "bed": {"points": points}})
    unmasked = np.ma.array([[0.0, 0.0], [0.5, 0.1]])  # nothing under a mask: its numbers
    assert multilayer.load({**TINY_SCENARIO, "bed": {"points": unmasked}}).bed.points == [[0, 0], [0.5, 0.1]]
    assert multilayer.load({**TINY_SCENARIO, "slope_deg": np.array(20.0, dtype=object)}).slope_deg == 20.0


def test_load_state_of_long_doubles_beyond_the_floats_is_refused_naming_the_entry():
    """``t = np.longdouble('1e400')`` is finite as a long double and infinite as the float
    the simulation holds: it was restored as t = inf (the next step said t_max was not
    later than t = inf), and ``h`` of 1e400 m was restored, then named a StateError."""
    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    saved = sim.state_dict()
    huge = np.longdouble("1e400")
    for key, value in (("t", huge), ("h", saved["h"].astype(np.longdouble) * huge)):
        with pytest.raises(InputError, match=rf"^{key} holds values that are not finite as float64"):
            sim.load_state({**saved, key: value})
    assert sim.t == 0.0 and np.array_equal(sim.h, saved["h"])
    sim.load_state({**saved, "t": np.longdouble("0.25")})  # within the floats: read
    assert sim.t == 0.25


def test_load_state_of_a_count_beyond_int64_says_so():
    """``steps = 2**70`` is a Python int numpy holds only as an object: it was refused as
    "object values of shape ()", which names the entry but not why."""
    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    saved = sim.state_dict()
    beyond = r"^steps = 1180591620717411303424, beyond .* at most 9223372036854775807"
    with pytest.raises(InputError, match=beyond):
        sim.load_state({**saved, "steps": 2**70})
    assert sim.steps == 0


@pytest.mark.parametrize(
    ("method", "body"),
    [
        ("yield_stress", lambda self, p, m: (p * 0.3).astype(np.longdouble) * np.longdouble("1e400")),
        ("viscosity_kernel", lambda self, m: ("constant", np.array([np.longdouble("1e400")]))),
    ],
)
def test_a_plugin_value_beyond_the_floats_as_a_long_double_is_named_without_a_warning(
    tmp_path, cli, write_scenario, monkeypatch, method, body
):
    """A long double of 1e400 (a yield stress, a compiled form's parameter) is infinite as a
    float: numpy's "overflow encountered in cast" came before the message naming it."""
    from multilayer.plugins.builtins.drucker_prager import DruckerPrager

    monkeypatch.setattr(DruckerPrager, method, body)
    result = cli("run", write_scenario(TINY_SCENARIO), "-o", tmp_path / "out", "-q")
    assert result.code == 1 and "warning" not in result.err, result.err
    said = "yield_stress" if method == "yield_stress" else "viscosity"
    assert f"{said}() returned inf (must be finite)" in result.err


def test_an_initial_entry_or_a_bed_of_another_type_assigned_after_loading_is_validated_again():
    """The serializers of a bed and an initial entry read the value's attributes: a value of
    another type assigned after loading (``scenario.initial.append(None)``, ``scenario.bed =
    5``, a mapping) raised pydantic's ``PydanticSerializationError`` naming a function of the
    schema (``_as_points``), where the validation again names the key or reads the mapping."""
    scenario = multilayer.load(TINY_SCENARIO)
    scenario.initial.append(None)
    with pytest.raises(InputError, match=r"^<scenario>: initial\.1: expected a mapping \(got None\)"):
        multilayer.Simulation(scenario)
    scenario = multilayer.load(TINY_SCENARIO)
    scenario.bed = 5
    with pytest.raises(InputError, match=r"^<scenario>: bed: expected a mapping \(got 5\)"):
        multilayer.run(scenario)
    scenario = multilayer.load(TINY_SCENARIO)
    scenario.bed = {"points": [[0.0, 0.0], [0.5, -0.1]]}
    assert multilayer.Simulation(scenario).bed[0] == pytest.approx(-0.00125, abs=1e-15)


@pytest.mark.parametrize(
    ("assign", "said"),
    [
        ("scenario.gravity = None", r"gravity: Input should be a valid number \(got None\)"),
        ("scenario.bed = None", r"bed: expected a mapping \(got None\)"),
        ("scenario.numerics.dry_threshold = None", r"numerics\.dry_threshold: Input should be a valid"),
        ("scenario.boundaries.left = None", r"boundaries\.left: Input should be a valid string"),
    ],
)
def test_a_none_assigned_after_loading_where_the_file_refuses_null_is_refused(assign, said):
    """The scenario validated again was written without its None keys (not given), and a
    None assigned where the file refuses null (``bed: null``) gave the default in its place:
    the simulation ran with g = 9.81 after ``scenario.gravity = None``."""
    scenario = multilayer.load(TINY_SCENARIO)
    exec(assign)
    with pytest.raises(InputError, match=rf"^<scenario>: {said}"):
        multilayer.Simulation(scenario)


@pytest.mark.parametrize(
    ("assign", "said"),
    [
        ("scenario.slope_deg = True", r"slope_deg: Input should be a valid number \(got True\)"),
        ("scenario.time.end = True", r"time\.end: Input should be a valid number \(got True\)"),
        ("scenario.domain.cells = True", r"domain\.cells: Input should be a valid integer \(got True\)"),
        (
            "scenario.initial[0].height = True",
            r"initial\.0\.height: Input should be a valid number \(got True\)",
        ),
        (
            "scenario.material.density = np.True_",
            r"material\.density: Input should be a valid number \(got True\)",
        ),
        (
            "scenario.rheology.params['nu'] = np.True_",
            r"rheology\.nu: drucker_prager: Input should be a valid number",
        ),
        ("scenario.domain.cells = 40.0", r"domain\.cells: Input should be a valid integer \(got 40\.0\)"),
        (
            "scenario.domain.x_max = np.array([0.75])",
            r"domain\.x_max: Input should be a valid number \(got \[0\.75\]\)",
        ),
        (
            "scenario.domain.x_max = np.longdouble('1e400')",
            r"domain\.x_max: Input should be a valid number \(got \"np",
        ),
        (
            "scenario.domain.x_max = 10**400",
            r"domain\.x_max: assigned since the scenario was validated, a value the",
        ),
        ("scenario.rheology.params = None", r"rheology\.params: assigned since the scenario was validated"),
    ],
)
def test_a_value_of_another_type_assigned_after_loading_is_named_as_the_file_names_it(assign, said):
    """pydantic writes a boolean assigned to a number as that number (``scenario.slope_deg =
    True`` ran on a slope of 1 degree, ``time.end = True`` to 1 s), took a float equal to the
    validated integer for it (``domain.cells = 40.0`` reached the engine, which named no
    key), and knew no numpy value, an integer past the floats or a law without parameters
    (a ``PydanticSerializationError``, ``OverflowError`` or ``ValueError`` traceback): each
    is named at its key, as the file and ``--set`` name it."""
    scenario = multilayer.load(TINY_SCENARIO)
    exec(assign)
    with pytest.raises(InputError, match=rf"^<scenario>: {said}"):
        multilayer.Simulation(scenario)
    with pytest.raises(InputError, match=rf"^<scenario>: {said}"):
        multilayer.run(scenario)


def test_numpy_numbers_assigned_after_loading_are_their_values():
    """``np.float32``, ``np.int32`` and 0-d arrays assigned after loading are the numbers
    they hold, as ``multilayer.load`` of a mapping reads them (each was a traceback), and
    an integer assigned to a float key its value: the run is the one of that value."""
    scenario = multilayer.load(TINY_SCENARIO)
    scenario.slope_deg, scenario.domain.cells = np.float32(20.0), np.int32(41)
    scenario.domain.x_max = np.array(0.75)
    sim = multilayer.Simulation(scenario)
    assert (sim.scenario.slope_deg, sim.scenario.domain.cells, sim.scenario.domain.x_max) == (20.0, 41, 0.75)
    assert type(sim.scenario.slope_deg) is float and type(sim.scenario.domain.cells) is int
    plain = multilayer.load(
        {
            **TINY_SCENARIO,
            "slope_deg": 20.0,
            "domain": {**TINY_SCENARIO["domain"], "cells": 41, "x_max": 0.75},
        }
    )
    assert np.array_equal(sim.h, multilayer.Simulation(plain).h)
    scenario = multilayer.load(TINY_SCENARIO)
    scenario.slope_deg = int(TINY_SCENARIO["slope_deg"])
    assert multilayer.Simulation(scenario).scenario.slope_deg == TINY_SCENARIO["slope_deg"]


def test_a_none_assigned_after_loading_where_the_file_accepts_null_is_not_given():
    """``walls`` and ``bed.profile`` take null as not given in a file: so after loading."""
    scenario = multilayer.load(TINY_SCENARIO)
    scenario.walls = None
    scenario.bed.profile = None
    scenario.description = None
    assert multilayer.Simulation(scenario).scenario.bed.profile == "flat"


def test_state_dict_waits_for_another_threads_step():
    """``state_dict`` from one thread while another keeps a step took the forces of that
    step with the time before it: it now takes its turn with ``step``, ``advance`` and
    ``load_state`` (the turn held here stands for a step under way)."""
    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    got: list[dict] = []
    with sim._turn("a step"):
        reader = threading.Thread(target=lambda: got.append(sim.state_dict()))
        reader.start()
        reader.join(0.5)
        assert reader.is_alive() and not got
        sim.step()  # the same thread may step while it holds the turn
    reader.join()
    assert got[0]["steps"] == 1 and got[0]["t"] == sim.t


def test_utf8_words_of_a_command_line_read_under_an_ascii_locale(tiny_scenario, write_scenario, capsys):
    """Under ``LC_ALL=C`` with ``PYTHONUTF8=0`` Python keeps each byte of ``é`` as a lone
    surrogate: ``--set description=é`` was refused as bytes that are not UTF-8, and ``-o
    é`` as a name that is not UTF-8 (netCDF cannot be given it in that locale: refused,
    saying why); a byte that is not UTF-8 is still named."""
    from multilayer.app import cli

    path = write_scenario(tiny_scenario)
    assert cli.main(["validate", str(path), "--set", "description=\udcc3\udca9"]) == 0
    assert cli.main(["validate", str(path), "--set", "description=\udcff"]) == 2
    assert "holds the byte 0xFF, which is not UTF-8" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["run", str(path), "-o", "out_\udcc3\udca9"])
    said = capsys.readouterr().err
    assert "b'out_\\xc3\\xa9' is a UTF-8 name, which this process's locale (encoding" in said


def test_a_domain_whose_cells_underflow_to_no_width_is_named(tiny_scenario, write_scenario, cli):
    """A domain 5e-324 m long has cells of 0 m: the message dividing by their width was a
    ``ZeroDivisionError`` traceback."""
    tiny_scenario["domain"]["x_max"] = 5e-324
    result = cli("validate", write_scenario(tiny_scenario))
    assert result.code == 2 and "Traceback" not in result.err
    assert "domain.cells" in result.err and "rounded by more than a cell" in result.err


def test_on_step_may_not_step_the_simulation_advance_steps():
    """An ``on_step`` that stepped the simulation took ``advance(0.05)`` to t = 0.0568 s,
    past the time it stops at, silently: refused, naming the call; reading is allowed and
    the simulation steps again once ``advance`` returns."""
    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    for on_step in (lambda s, dt: s.step(), lambda s, dt: s.advance(s.t + 0.1)):
        with pytest.raises(InputError, match="from the on_step of advance"):
            sim.advance(0.05, on_step=on_step)
        assert sim.t < 0.05
    sim.advance(0.05, on_step=lambda s, dt: s.state_dict())
    assert sim.t == 0.05
    sim.step()


def test_a_third_partys_message_of_several_lines_is_shown_on_one():
    """A law's exception holding a line feed printed its message over two lines, the second
    read as another message."""
    from multilayer.errors import described

    assert described(ValueError("first\nsecond\r\n")) == "ValueError: first\\nsecond\r\\n"


def test_a_result_another_process_holds_open_for_writing_is_not_run_into(tmp_path, cli):
    """The classic netCDF format takes no lock: ``--resume`` into a result another tool
    held open for writing exited 0 (that tool's closing rewrites the record count).
    Refused, naming the file and the process; a reader is no obstacle."""
    scenario = tmp_path / "tiny.yaml"
    scenario.write_text(yaml.safe_dump({**TINY_SCENARIO, "time": {"end": 0.04, "output_interval": 0.02}}))
    assert cli("run", scenario, "-o", tmp_path / "out", "-q").code == 0
    result_file = tmp_path / "out" / RESULT_FILE
    hold = "import sys, time\nf = open(sys.argv[1], sys.argv[2])\nprint(flush=True)\ntime.sleep(60)"
    for mode, code in (("r+b", 2), ("rb", 0)):
        holder = subprocess.Popen(
            [sys.executable, "-c", hold, str(result_file), mode], stdout=subprocess.PIPE
        )
        try:
            holder.stdout.readline()  # type: ignore[union-attr]
            got = cli("run", scenario, "-o", tmp_path / "out", "-q", "--resume", "--set", "time.end=0.06")
        finally:
            holder.kill()
            holder.wait()
        assert got.code == code, got.err
        if code:
            assert f"{result_file}: open for writing by another process (pid {holder.pid}" in got.err


def test_the_compile_notice_says_why_python_oo_compiles_again(monkeypatch):
    """Under ``python -OO`` about twenty kernels are compiled again, once, after ``multilayer
    compile`` (numba keys them on their callees' code, docstrings included): the notice
    says why."""
    import logging
    import types

    import numba

    from multilayer.app import compilation

    said: list[str] = []
    monkeypatch.setattr(compilation, "sys", types.SimpleNamespace(flags=types.SimpleNamespace(optimize=2)))
    with compilation.compile_notice(logging.getLogger("test"), said.append):
        numba.njit(lambda x: x + 1)(1)
    assert said == [compilation.NOTICE + compilation.OPTIMIZED_NOTICE]


@pytest.mark.parametrize(
    "call",
    [lambda s: s.advance(s.t + 0.01), lambda s: s.step(), lambda s: s.load_state(s.state_dict())],
    ids=["advance", "step", "load_state"],
)
def test_an_on_step_waiting_for_a_thread_that_steps_is_refused_not_held(call):
    """An ``on_step`` that started a thread stepping the simulation and waited for it held
    both for ever (the thread waited for ``advance``'s lock, ``advance`` for its on_step):
    the thread's call is refused naming it, and the simulation steps on afterwards.  The
    thread is waited for 30 s at most, so the test cannot hang."""
    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    outcome: list[object] = []

    def other() -> None:
        try:
            outcome.append(call(sim))
        except InputError as exc:
            outcome.append(exc)

    def on_step(s, dt) -> None:
        worker = threading.Thread(target=other, daemon=True)
        worker.start()
        worker.join(30)
        assert not worker.is_alive(), "the other thread still waits"

    sim.advance(0.02, on_step=on_step)
    assert sim.t == 0.02 and outcome
    assert all(isinstance(o, InputError) for o in outcome), outcome
    assert "from another thread while the on_step of advance runs" in str(outcome[0])
    sim.advance(0.04)
    assert sim.t == 0.04


def test_a_thread_reads_the_state_while_on_step_waits_for_it_and_waits_its_turn_otherwise():
    """``state_dict()`` from a thread an ``on_step`` waits for reads the state between the
    steps (it waited for ever for ``advance``'s lock), the state the on_step sees; a thread
    stepping while the simulation steps, outside an on_step, waits its turn: two threads
    advancing to 0.04 s end there, as one call does."""
    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    read: list[tuple[float, float]] = []

    def on_step(s, dt) -> None:
        worker = threading.Thread(target=lambda: read.append((s.state_dict()["t"], s.t)), daemon=True)
        worker.start()
        worker.join(30)
        assert not worker.is_alive(), "the reading thread still waits"

    sim.advance(0.02, on_step=on_step)
    assert read and all(a == b for a, b in read) and read[-1][0] == 0.02
    alone = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    alone.advance(0.04)
    worker = threading.Thread(target=sim.advance, args=(0.04,), daemon=True)
    worker.start()
    sim.advance(0.04)
    worker.join(60)
    assert not worker.is_alive() and sim.t == 0.04 == alone.t


@pytest.mark.parametrize(
    "call",
    [
        lambda s: s.step(),
        lambda s: s.advance(s.t + 0.01),
        lambda s: s.load_state(s.state_dict()),
        lambda s: s.state_dict()["t"],
    ],
    ids=["step", "advance", "load_state", "state_dict"],
)
def test_a_thread_waiting_for_a_step_under_way_is_let_go_when_on_step_starts(call, monkeypatch):
    """A thread that called while ``advance`` was in a step waited for its turn; the
    ``on_step`` after that step, waiting for the thread, held both for ever.  Woken as the
    on_step starts, the thread's step, advance or load_state is refused as from inside it,
    and its state_dict reads the state between the steps.  Waited for 30 s at most."""
    from multilayer.engine import simulation as engine

    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    stepping, outcome = threading.Event(), []
    engine_step = engine.Simulation.step

    def step(self, t_max=np.inf):  # the other thread calls during the first step
        dt = engine_step(self, t_max)
        if not stepping.is_set():
            stepping.set()
            time.sleep(0.3)
        return dt

    monkeypatch.setattr(engine.Simulation, "step", step)

    def other() -> None:
        stepping.wait()
        try:
            outcome.append(call(sim))
        except InputError as exc:
            outcome.append(exc)

    worker = threading.Thread(target=other, daemon=True)
    worker.start()

    def on_step(s, dt) -> None:
        worker.join(30)
        assert not worker.is_alive(), "the other thread still waits"

    sim.advance(0.02, on_step=on_step)
    assert sim.t == 0.02 and len(outcome) == 1
    if isinstance(outcome[0], InputError):
        assert "from another thread while the on_step of advance runs" in str(outcome[0])
    else:
        assert 0 < outcome[0] < 0.02  # the time of the first step, read between the steps


async def _awaited_on_step(sim, dt) -> None:
    raise AssertionError("never run")


def _yielding_on_step(sim, dt):
    yield dt


@pytest.mark.parametrize(
    ("on_step", "said"),
    [
        (_awaited_on_step, "an async function (async def)"),
        (_yielding_on_step, "a generator function (it yields)"),
        (lambda s, dt: _awaited_on_step(s, dt), "returned coroutine"),
        (functools.partial(_yielding_on_step), "a generator function (it yields)"),
    ],
    ids=["async-def", "generator", "lambda-returning-a-coroutine", "partial-of-a-generator"],
)
def test_an_on_step_whose_body_never_runs_is_refused(on_step, said, recwarn):
    """``advance`` calls ``on_step`` and ignored what it returned: an ``async def`` or a
    generator function never ran its body, silently (but for Python's "never awaited"
    warning).  Refused naming it, before the first step where its kind says so, at the
    first call otherwise (the coroutine closed: no warning)."""
    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    with pytest.raises(InputError, match=re.escape(said) + ".*accepted: a function of \\(sim, dt\\)"):
        sim.advance(0.02, on_step=on_step)
    assert sim.steps == (1 if "returned" in said else 0)
    gc.collect()
    assert not [w for w in recwarn if "never awaited" in str(w.message)]


def test_an_integer_of_more_digits_than_python_converts_says_what_is_accepted(tmp_path, cli, write_scenario):
    """An integer of 5000 digits in a scenario passed on Python's advice to call
    ``sys.set_int_max_str_digits()``, which no user of the command line can; the message
    says how many digits an integer may have.  Given to the Python API (a mapping, a time),
    the message quoting it was a ``ValueError`` traceback: it is described."""
    path = write_scenario(TINY_SCENARIO)
    path.write_text(path.read_text().replace("cells: 40", "cells: " + "4" * 5000))
    result = cli("validate", path)
    assert result.code == 2 and "Traceback" not in result.err
    assert "(5000 digits, more than the 4300 an integer may have)" in result.err
    assert "set_int_max_str_digits" not in result.err
    data = copy.deepcopy(TINY_SCENARIO)
    data["domain"]["cells"] = 10**5000
    with pytest.raises(InputError, match=r"domain\.cells: .*got an integer of about 5001 digits"):
        multilayer.load(data)
    sim = multilayer.Simulation(multilayer.load(TINY_SCENARIO))
    with pytest.raises(InputError, match=r"advance\(t_target=an integer of about 5001 digits\)"):
        sim.advance(10**5000)
