"""Provenance (docs/results.md): the version from git and the exact commit in result.nc."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest
import xarray as xr
from packaging.version import Version

import multilayer
from multilayer import scenario as scenarios
from multilayer.app import runner
from multilayer.provenance import SOURCE_ROOT, provenance

needs_git = pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed")


def git(root: Path, *args: str) -> str:
    command = ["git", "-C", str(root), "-c", "user.name=t", "-c", "user.email=t@example.org", *args]
    return subprocess.run(command, capture_output=True, text=True, check=True).stdout.strip()


def test_the_version_is_a_pep_440_version_from_setuptools_scm():
    Version(multilayer.__version__)  # raises if not PEP 440
    assert multilayer.__version__ != "0+unknown"


@needs_git
def test_commit_and_dirty_flag_of_a_git_tree(tmp_path: Path):
    git(tmp_path, "init", "-q")
    (tmp_path / "a.py").write_text("x = 1\n")
    git(tmp_path, "add", "a.py")
    git(tmp_path, "commit", "-q", "-m", "one")
    clean = provenance(tmp_path)
    assert clean.commit == git(tmp_path, "rev-parse", "HEAD") and clean.dirty == "false"
    (tmp_path / "untracked.txt").write_text("results\n")
    assert provenance(tmp_path).dirty == "false"  # untracked files (e.g. results/) do not count
    (tmp_path / "a.py").write_text("x = 2\n")
    assert provenance(tmp_path).dirty == "true"


def test_outside_git_the_commit_comes_from_the_version(tmp_path: Path):
    origin = provenance(tmp_path / "not-a-checkout")
    recorded = re.search(r"\+g([0-9a-f]+)", origin.version)
    assert origin.commit == (recorded.group(1) if recorded else "unknown")
    assert origin.dirty == "unknown"


def test_result_file_names_the_version_and_commit_that_ran(tmp_path: Path, tiny_scenario):
    runner.run(scenarios.from_dict(tiny_scenario), tmp_path, quiet=True)
    with xr.open_dataset(tmp_path / "result.nc") as ds:
        attrs = dict(ds.attrs)
    assert attrs["multilayer_version"] == multilayer.__version__
    expected = provenance()
    assert (attrs["multilayer_commit"], attrs["multilayer_dirty"]) == (expected.commit, expected.dirty)
    if shutil.which("git") and (SOURCE_ROOT / ".git").exists():
        assert attrs["multilayer_commit"] == git(SOURCE_ROOT, "rev-parse", "HEAD")
        assert attrs["multilayer_dirty"] in ("true", "false")
    assert f"commit {attrs['multilayer_commit']}" in attrs["source"]
    assert "FiPy" in attrs["source"] and "numba" in attrs["source"]
