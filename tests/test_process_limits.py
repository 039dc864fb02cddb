"""The process's limits (``ulimit -v``) and a lack of memory: one message, never a
traceback or a hang (docs/reliability.md)."""

from __future__ import annotations

import io
import resource
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from conftest import TINY_SCENARIO

from multilayer.app import cli, resources
from multilayer.errors import InputError
from multilayer.io import disk
from multilayer.scenario import files


def test_a_small_address_space_is_refused_before_the_libraries_load(tmp_path: Path) -> None:
    """Under ``ulimit -v`` of 300 MB SciPy's import spun for ever (``validate``); under
    400 MB reading a scenario was a MemoryError traceback: the command says the limit
    and what it needs, in one message, before its modules are imported."""
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(TINY_SCENARIO))
    limit = 400 * 10**6
    done = subprocess.run(
        [sys.executable, "-m", "multilayer", "validate", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
        preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (limit, limit)),
    )
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        f"multilayer: error: the address space of this process is limited to {limit / 2**20:.0f} MiB "
        "(ulimit -v), where its libraries (NumPy, SciPy, numba) map about half a GiB as they load; "
        "accepted: a limit of at least 1024 MiB (ulimit -v 1048576), or none"
    ]


def test_a_memory_error_of_a_command_is_one_message(monkeypatch, cli, tmp_path: Path) -> None:
    """A MemoryError in a command (an allocation past ``ulimit -v`` or the machine's
    memory) was a traceback: exit 2 and one message."""
    from multilayer.app.commands import validate

    def exhausted(args):
        raise MemoryError("Unable to allocate 15.3 MiB")

    monkeypatch.setattr(validate, "main", exhausted)
    result = cli("validate", tmp_path / "scenario.yaml")
    assert result.code == 2
    assert result.err.splitlines() == [
        "multilayer: error: out of memory (Unable to allocate 15.3 MiB); accepted: more memory for this "
        "process (its address-space limit, ulimit -v, and the machine's), or a smaller problem"
    ]


def test_a_mesh_beyond_the_address_space_is_refused_naming_it(monkeypatch, write_scenario) -> None:
    """A run whose estimate fits the machine's memory but not the address space of the
    process (``ulimit -v``) is refused with the estimate and the limit: it failed in a
    numpy allocation on the way."""
    from multilayer import scenario as scenarios

    monkeypatch.setattr(resources, "available_memory", lambda: 64.0 * 2**30)
    monkeypatch.setattr(disk, "address_space_limit", lambda: 1.0 * 2**30)
    data = {**TINY_SCENARIO, "domain": {**TINY_SCENARIO["domain"], "cells": 2_000_000}}
    loaded = scenarios.load(write_scenario(data))
    with pytest.raises(
        InputError, match=r"more than the address space of this process \(ulimit -v\) \(1 GB\)"
    ):
        resources.check(loaded, None, resources.Budget())


def test_an_input_file_is_read_in_blocks() -> None:
    """A file is read a block at a time: one ``read(MAX_FILE_BYTES + 1)`` set aside 64 MiB
    for a file of 1 kB (a MemoryError under ``ulimit -v``); its bytes and the bound are kept."""
    asked = []

    class Stream(io.BytesIO):
        def read(self, size=-1):
            asked.append(size)
            return super().read(size)

    text = b"x" * (3 * files._BLOCK + 5)
    assert files._head(Stream(text), 10**9) == text
    assert max(asked) == files._BLOCK
    assert files._head(Stream(text), 7) == text[:7]


def test_the_address_space_check_passes_without_a_limit(monkeypatch) -> None:
    monkeypatch.setattr(resource, "getrlimit", lambda which: (resource.RLIM_INFINITY, resource.RLIM_INFINITY))
    assert cli._address_space() is None
    monkeypatch.setattr(resource, "getrlimit", lambda which: (2**31, resource.RLIM_INFINITY))
    assert cli._address_space() is None


def test_a_film_below_the_dry_threshold_is_one_message_and_leaves_no_directory(cli, write_scenario, tmp_path):
    """A run of a film thinner than ``numerics.dry_threshold`` said first that its front is
    never found (a warning), then refused the film, and left its output directory: now the
    refusal alone, before anything is made."""
    data = {**TINY_SCENARIO, "initial": [{"shape": "layer", "thickness": 1e-9}]}
    result = cli("run", write_scenario(data), "-o", tmp_path / "out", "-q")
    assert result.code == 2
    assert len(result.err.splitlines()) == 1
    assert "not above numerics.dry_threshold = 1e-06 m" in result.err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("same", [True, False])
def test_a_study_resumed_after_its_file_changed_says_so(tmp_path: Path, capsys, same: bool) -> None:
    """``sensitivity`` and ``calibrate --resume`` whose file changed since the study ran
    (the text its results file records) say so: the runs of other parameters ran afresh,
    the earlier ones beside them, silently."""
    import argparse

    import netCDF4

    from multilayer.app.commands import check_results

    config = tmp_path / "study.yaml"
    config.write_text("base: scenario.yaml\nsamples: 32\n")
    with netCDF4.Dataset(tmp_path / "sensitivity.nc", "w") as ds:
        ds.setncattr("sensitivity", config.read_text() if same else "base: scenario.yaml\nsamples: 16\n")
    check_results(argparse.Namespace(resume=True), tmp_path, "sensitivity.nc", (config, "sensitivity"))
    err = capsys.readouterr().err
    assert err == (
        ""
        if same
        else (
            f"multilayer: warning: {config} changed since the study in {tmp_path} ran (sensitivity.nc holds "
            "the file it ran): the runs the changed file still asks for are reused, the others run afresh\n"
        )
    )


def test_the_address_space_limit_is_read_from_the_process() -> None:
    soft = resource.getrlimit(resource.RLIMIT_AS)[0]
    expected = float("inf") if soft == resource.RLIM_INFINITY else float(soft)
    assert disk.address_space_limit() == expected
