"""A full disk or the file size limit (``ulimit -f``) during a run (docs/reliability.md):
exit 1 naming it, every record written before kept and readable, ``run_status: failed``,
no traceback, no crash; a run that cannot fit is refused before it starts (exit 2)."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import TINY_SCENARIO

from multilayer.errors import InputError
from multilayer.io import disk, results
from multilayer.io.results import load_checkpoint, open_result

MANY_OUTPUTS = {**TINY_SCENARIO, "name": "many", "time": {"end": 0.2, "output_interval": 0.005}}
"""41 records of 1624 bytes: about 84 kB of result.nc."""
LIMIT = 48 * 1024
"""The file size limit of the child (bytes): the header and about 18 records."""

CHILD = """
import sys
from multilayer.io import results
if sys.argv[1] == "unchecked":  # the disk fills between the check and the write
    results.ResultWriter._ensure_room = lambda self: None
from multilayer.app.cli import main
sys.exit(main(sys.argv[2:]))
"""


def _run_limited(tmp_path: Path, mode: str, *options: str) -> tuple[subprocess.CompletedProcess, Path]:
    path = tmp_path / "many.yaml"
    path.write_text(yaml.safe_dump(MANY_OUTPUTS), encoding="utf-8")
    outdir = tmp_path / "out"

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))

    done = subprocess.run(
        [sys.executable, "-c", CHILD, mode, "run", str(path), "-o", str(outdir), "-q", *options],
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=limit,
    )
    return done, outdir


def _assert_kept(outdir: Path, reason: str) -> None:
    """The result holds the records written before the disk filled, readable, ``failed``."""
    kept = open_result(outdir)
    assert kept.attrs["run_status"] == "failed" and reason in kept.attrs["failure"]
    t = kept["time"].values
    assert 5 <= t.size < 41 and np.all(np.diff(t) > 0) and np.isfinite(kept["h"].values).all()
    assert load_checkpoint(outdir / "checkpoint.npz").records >= t.size - 1


@pytest.mark.slow
def test_the_file_size_limit_stops_a_write_half_way_keeping_every_record_written_before(tmp_path):
    """The write itself fails (EFBIG) under a real ``ulimit -f``, as when another process
    fills the disk between the writer's check and its write: netCDF-C's buffers are abandoned
    (closing them again crashed the interpreter) and the header set back to the records
    written whole."""
    done, outdir = _run_limited(tmp_path, "unchecked", "--force")
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    assert "multilayer: run failed: scenario 'many': file too large: writing output time" in done.stderr
    assert "once there is room, continue with: multilayer run" in done.stderr
    _assert_kept(outdir, "file too large")
    assert (outdir / "result.nc").stat().st_size <= LIMIT


@pytest.mark.slow
def test_the_file_size_limit_stops_the_run_before_a_record_that_does_not_fit(tmp_path):
    done, outdir = _run_limited(tmp_path, "checked", "--force")
    assert done.returncode == 1 and "Traceback" not in done.stderr
    assert "file too large: the file size limit (ulimit -f) is 49152 bytes" in done.stderr
    _assert_kept(outdir, "file too large")


def test_a_run_beyond_the_file_size_limit_is_refused_unless_forced(
    tmp_path, cli, write_scenario, monkeypatch
):
    monkeypatch.setattr(disk, "file_size_limit", lambda: float(LIMIT))
    path = write_scenario(MANY_OUTPUTS)
    refused = cli("run", path, "-o", tmp_path / "out", "-q")
    assert refused.code == 2
    assert "more than the file size limit of this process (ulimit -f) (48 kB)" in refused.err
    assert not (tmp_path / "out" / "result.nc").exists()
    forced = cli("run", path, "-o", tmp_path / "out", "-q", "--force")
    assert forced.code == 1 and "file too large: the file size limit (ulimit -f) is 49152 bytes" in forced.err
    _assert_kept(tmp_path / "out", "file too large")


def test_a_full_disk_stops_the_run_naming_it_and_the_run_resumes_once_there_is_room(
    tmp_path, cli, write_scenario, monkeypatch
):
    path = write_scenario(MANY_OUTPUTS)
    outdir = tmp_path / "out"
    real = disk.free_space
    calls = []

    def filling(directory):  # the disk fills after the tenth record
        calls.append(directory)
        return 1000.0 if len(calls) > 10 else real(directory)

    monkeypatch.setattr(disk, "free_space", filling)
    run = cli("run", path, "-o", outdir, "-q", "--force")
    assert run.code == 1 and "Traceback" not in run.err
    assert "disk full: 1000 bytes free on the disk holding" in run.err
    _assert_kept(outdir, "disk full")
    monkeypatch.setattr(disk, "free_space", real)
    resumed = cli("run", path, "-o", outdir, "-q", "--resume")
    assert resumed.code == 0, resumed.err
    done = open_result(outdir)
    assert done.attrs["run_status"] == "completed" and done.sizes["time"] == 41


def test_a_checkpoint_that_does_not_fit_leaves_the_previous_one(tmp_path, monkeypatch):
    path = tmp_path / "checkpoint.npz"
    state = {"t": 0.0, "steps": 0, "h": np.zeros(3), "u": np.zeros((1, 3))}
    ckpt = results.Checkpoint(state, 1, 0.0, "name: x")
    results.save_checkpoint(path, ckpt)

    def full(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(np, "savez", full)
    with pytest.raises(results.DiskFull, match=r"disk full: writing the checkpoint .* failed"):
        results.save_checkpoint(path, ckpt)
    assert not path.with_name(path.name + ".tmp").exists()
    assert load_checkpoint(path).records == 1


def test_a_file_written_whole_keeps_the_old_one_when_the_write_fails(tmp_path):
    """``disk.write_whole`` (study files, sweep markers, figures): a write that fails half-way
    leaves the file as it was and no temporary file; one that completes replaces it."""
    path = tmp_path / "calibration.nc"
    path.write_text("old")

    def half(part: Path) -> None:
        part.write_text("ne")
        raise OSError(28, "No space left on device")

    with pytest.raises(InputError, match=r"calibration.nc: not written \(disk full: "):
        disk.write_whole(path, half)
    assert path.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["calibration.nc"]
    disk.write_whole(path, lambda part: part.write_text("new"))
    assert path.read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["calibration.nc"]


@pytest.mark.slow  # a child process; the fault battery tries it too
@pytest.mark.parametrize(
    ("limit", "code", "said"),
    [
        (0, 2, "run.lock: the lock cannot be written (file too large: the file size limit (ulimit -f) is 0"),
        (5000, 1, "run failed: file too large: creating "),
    ],
)
def test_a_forced_run_whose_lock_or_header_does_not_fit_says_so_and_leaves_neither(
    tmp_path, write_scenario, limit, code, said
):
    """``run --force`` under ``ulimit -f`` below the lock or the result file's header: an
    empty ``run.lock`` was left (the lock's write failed after its creation) with "[Errno
    27] File too large" naming no file, and the header's failure was netCDF's traceback
    ("Operation not allowed in define mode"), or ``run.log``'s flush error in its place.
    Each names its file and the limit; neither file is left, half-written."""
    outdir = tmp_path / "out"

    def limited() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    path = write_scenario(TINY_SCENARIO)
    done = subprocess.run(
        [sys.executable, "-m", "multilayer", "run", str(path), "-o", str(outdir), "-q", "--force"],
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=limited,
    )
    assert done.returncode == code and "Traceback" not in done.stderr, done.stderr
    assert said in done.stderr.splitlines()[-1]
    assert not (outdir / "run.lock").exists() and not (outdir / "result.nc").exists()


@pytest.mark.slow  # a child process; the fault battery tries it too
@pytest.mark.parametrize(
    ("command", "written"), [(("plot",), "plots/section.png"), (("export", "--vtk"), "vtk/result_0000.vts")]
)
def test_a_figure_or_vtk_file_beyond_the_file_size_limit_is_named(
    tmp_path, cli, write_scenario, command, written
):
    """``plot`` and ``export`` under ``ulimit -f``: "error: [Errno 27] File too large;
    accepted: a directory this user can write", naming neither the file nor the limit.  The
    file and the limit are named; nothing is left written half-way."""
    outdir = tmp_path / "out"
    assert cli("run", write_scenario(TINY_SCENARIO), "-o", outdir, "-q").code == 0

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (2000, 2000))

    done = subprocess.run(
        [sys.executable, "-m", "multilayer", command[0], str(outdir), *command[1:]],
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=limit,
    )
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert f"error: {outdir / written}" in done.stderr
    assert "not written (file too large: the file size limit (ulimit -f) is 2000 bytes)" in done.stderr
    assert not [p for p in outdir.rglob("*") if p.is_file() and p.parent != outdir]


def test_a_file_written_whole_by_two_processes_at_once_uses_a_temporary_file_each(tmp_path):
    """Two ``multilayer plot`` of one directory at once wrote into one temporary file: the
    one that renamed it first left the other's rename without a file (exit 2 naming
    ``.section.partial.png`` as missing).  Each process writes into its own; another's, under
    way beside it, is left alone."""
    path = tmp_path / "section.png"
    theirs = tmp_path / f".section.partial.{os.getpid() + 1}.png"
    theirs.write_text("under way")
    written = []
    disk.write_whole(path, lambda part: (written.append(part.name), part.write_text("mine")))
    assert written == [f".section.partial.{os.getpid()}.png"] and path.read_text() == "mine"
    assert theirs.read_text() == "under way"
