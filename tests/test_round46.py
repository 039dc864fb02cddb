"""The fixes of the fault battery's forty-sixth round (docs/reliability.md): a result
followed by bytes its header does not declare (a terabyte of zeros), empty file paths on
the command line, and Dask settings the local cluster cannot read."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import dask
import pytest
import yaml
from conftest import TINY_SCENARIO

from multilayer import scenario as scenarios
from multilayer.app import runner
from multilayer.app import sweep as sweeps
from multilayer.errors import InputError
from multilayer.io.netcdf_layout import declared_size
from multilayer.io.plotting import drawn_from
from multilayer.io.result_check import check_result
from multilayer.io.results import open_result


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    directory = tmp_path_factory.mktemp("finished")
    (directory / "tiny.yaml").write_text(yaml.safe_dump(TINY_SCENARIO), encoding="utf-8")
    runner.run(scenarios.load(directory / "tiny.yaml"), directory / "out", quiet=True)
    return directory


def test_a_result_followed_by_a_terabyte_of_zeros_is_drawn_from_its_declared_bytes_and_resume_cuts_them(
    finished, tmp_path, cli
):
    shutil.copytree(finished, tmp_path, dirs_exist_ok=True)
    result = tmp_path / "out" / "result.nc"
    declared, source = declared_size(result), drawn_from(result)
    assert declared is not None and declared <= result.stat().st_size
    os.truncate(result, 2**40)  # sparse: `plot` hashed the terabyte for hours
    assert drawn_from(result) == source  # the bytes netCDF-C reads, and nothing after them
    assert check_result(result) == result  # the records are whole: the file is read as it is
    longer = {**TINY_SCENARIO, "time": {"end": 0.1, "output_interval": 0.025}}
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump(longer), encoding="utf-8")
    assert cli("run", path, "-o", tmp_path / "out", "-q", "--resume").code == 0
    assert result.stat().st_size < 2**20  # the zeros cut before the records were appended
    assert check_result(result) == result and open_result(tmp_path / "out").sizes["time"] == 5


@pytest.mark.parametrize("command", ["run", "validate", "check", "sweep", "calibrate", "sensitivity"])
def test_an_empty_file_path_is_named_as_empty(command, cli):
    result = cli(command, "")
    assert result.code == 2 and "Traceback" not in result.err
    assert "an empty path; accepted: the path of a YAML file" in result.err
    assert ".: not a regular file" not in result.err


def test_a_missing_dask_temporary_directory_is_named(tmp_path):
    with dask.config.set({"temporary-directory": str(tmp_path / "nothing")}):
        with pytest.raises(
            InputError, match="Dask's temporary-directory .*nothing .*DASK_TEMPORARY_DIRECTORY"
        ):
            with sweeps.dask_client(None, 1):
                pass


def test_a_dask_setting_the_cluster_cannot_read_is_an_input_error_naming_the_variables(monkeypatch):
    monkeypatch.setenv("DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT", "abc")
    with dask.config.set({"distributed.comm.timeouts.connect": "abc"}):
        with pytest.raises(
            InputError, match="could not read its settings .*set in the environment: DASK_DISTRIBUTED__COMM"
        ):
            with sweeps.dask_client(None, 1):
                pass
