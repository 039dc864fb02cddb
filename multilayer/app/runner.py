"""Run a scenario into an output directory: result file, checkpoints, log, Ctrl-C, resume.

``DIR/result.nc`` receives the initial state and every output time
(``k * time.output_interval`` and ``time.end``); after each one the full engine state is
saved to ``DIR/checkpoint.npz`` and a line is added to ``DIR/run.log``.

Ctrl-C (SIGINT), SIGTERM (what batch schedulers send) and SIGHUP are turned into a
request honoured between two kernel calls (well within a second): the step under way is
abandoned, the state at the start of it is checkpointed, ``run_status`` set to
``interrupted``, the resume command written to stderr and ``run.log``, and
:class:`~multilayer.errors.Interrupted` raised (the CLI exits with 128 + the signal number:
130, 143, 129).  A second signal stops at once; the last checkpoint then stands.  A
signal the process was started with ignored stays ignored (:func:`handled_by`).
``resume=True`` restores the checkpoint and continues; the output times are the same as
without the interruption, so the result is identical.

A failure of the engine (a plugin or state guard, docs/reliability.md) ends the run with
:class:`RunError`: ``run_status: failed``, the reason in the ``failure`` attribute, and the
last good state both checkpointed and appended to ``result.nc`` as its last record.

One run at a time writes into ``DIR`` (``DIR/run.lock``, :mod:`multilayer.app.lock`).  A
run without ``resume`` starts afresh: it overwrites ``result.nc``, ``run.log`` and
removes any previous checkpoint in ``DIR``.  Before anything is written the memory and
output size are estimated and checked against the budget (:mod:`multilayer.app.resources`).
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shlex
import signal
import stat
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import Any

import numpy as np
import yaml

from multilayer import scenario as scenarios
from multilayer.app import factory, numba_environment, resources
from multilayer.app.compilation import compile_ahead, compile_notice
from multilayer.app.lock import LOCK_FILE, locked
from multilayer.app.progress import Progress
from multilayer.app.simulation import Simulation
from multilayer.engine.plugin_output import in_plugin_call
from multilayer.errors import (
    REMOVED_WORKING_DIRECTORY,
    InputError,
    Interrupted,
    RunError,
    Stop,
    printable,
    reason,
    to_stderr,
    warn,
    working_directory_removed,
)
from multilayer.io.disk import refuse_other_writers, writable
from multilayer.io.result_check import check_result
from multilayer.io.results import (
    CHECKPOINT_FILE,
    RESULT_FILE,
    Checkpoint,
    DiskFull,
    ResultWriter,
    WriteFailed,
    load_checkpoint,
    made_by,
    record_time,
    recorded,
    save_checkpoint,
    summary,
)
from multilayer.provenance import provenance

LOG_FILE = "run.log"


RECORD_ROUNDING = 1e-9
"""The run's rounding of output times, relative to ``time.end``: an output time within it
of a record kept is that record's (``k * interval`` one rounding unit from the time a
finished run recorded as its end, when the run is extended)."""


def after_record(times: Any, last: float, end: float) -> Any:
    """Whether the output times ``times`` (of a run to ``end``) come after the record at
    ``last``, by more than :data:`RECORD_ROUNDING`."""
    return times > last + RECORD_ROUNDING * end


def output_times(end: float, interval: float | None) -> np.ndarray:
    """Output times ``k * interval`` (k = 1, 2, ...) more than ``1e-9 interval`` before
    ``end``, then ``end`` itself: the last record is at ``end`` exactly, also where
    ``end / interval`` is a whole number to round-off (``k * interval`` one rounding unit
    below ``end`` was the last)."""
    if not interval or interval >= end:
        return np.array([end])
    times = np.arange(1, int(np.ceil(end / interval)) + 1) * interval
    return np.append(times[times < end - 1e-9 * interval], end)


def run(
    scenario: Any,
    outdir: str | os.PathLike,
    *,
    resume: bool = False,
    quiet: bool | None = None,
    budget: resources.Budget | None = None,
    stop_when: Callable[[], bool] | None = None,
) -> dict[str, float]:
    """Run ``scenario`` into ``outdir`` and return :func:`multilayer.results.summary`.

    Raises :class:`InputError` when ``resume`` is asked for but ``outdir`` holds no
    checkpoint of this scenario, when another run holds ``outdir`` or when the run does
    not fit ``budget`` (default: the machine's available memory and the free disk space;
    ``Budget(force=True)`` skips the check), :class:`RunError` when the engine fails (the
    result file then holds every output time completed before the failure and the last
    good state) and :class:`~multilayer.errors.Interrupted` (a :class:`KeyboardInterrupt`)
    after a clean stop on a signal, or when ``stop_when()`` (asked between kernel calls)
    returns True: how a study stops the members running on its workers, where signals
    do not reach (:mod:`multilayer.app.stopping`).  ``quiet=None`` shows the progress
    line only on a terminal.
    """
    numba_environment.check()  # before anything is made (set in Python, no command checked it)
    outdir = Path(outdir)
    if resume and not outdir.is_dir():
        raise InputError(
            f"{outdir}: nothing to resume (no such directory); run without --resume to start afresh"
        )
    budget = budget or resources.Budget()
    scenario.check_material()
    created = output_directory(outdir, scenario.source, scenario.input_files())
    # written once: the estimate of the result, the resume's comparison, the log, the result's
    # header and every checkpoint (a bed of 450 000 points inline is 12 MB of it)
    text = scenario.resolved_yaml()
    try:
        resources.check(scenario, outdir, budget, text)
        resources.check_steps(scenario, budget)
        # as the engine checks them, before the notices on the state (a front never found)
        factory.check_initial(scenario, str(scenario.source or "<scenario>"), on_mesh=not budget.force)
    except InputError:  # refused before anything is written: the directories made go again
        for directory in created:
            directory.rmdir()
        raise
    notices: list[str] = []

    def notice(message: str) -> None:
        notices.append(message)
        warn(message)

    if (absent := scenario.front_never_found()) is not None:  # said, not refused: a film has no front
        notice(f"numerics.front_threshold = {absent}")
    stop = _StopRequest(stop_when)
    with locked(outdir, notice), stop.installed():
        refuse_other_writers(outdir / RESULT_FILE)  # resumed or overwritten: no other tool writes it
        ckpt, end = _checkpoint_to_resume(scenario, text, outdir, notice) if resume else (None, None)
        if end is not None and end != scenario.time.end:  # finished at its last record: it keeps that end
            scenario = scenarios.validated_again(scenario, [f"time.end={end!r}"])
            text = scenario.resolved_yaml()
        log = logging.Logger("multilayer.run")
        handler = _LogFile(outdir / LOG_FILE, mode="a" if resume else "w", encoding="utf-8")
        handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))
        log.addHandler(handler)
        for message in notices:
            log.warning(message)
        # the compile notice is one plain line: also where stderr is not a terminal (a log, a
        # notebook, a batch job), unless quiet; the progress line is for terminals only
        say = (lambda text: to_stderr(f"multilayer: {text}", flush=True)) if not quiet else None
        try:
            with compile_notice(log, say):
                _run(scenario, text, outdir, ckpt, quiet, log, stop, budget.step_limit)
        except InputError as exc:  # found once the log was open: the log says why it ends there
            log.error("%s", exc)
            raise
        except Interrupted as exc:
            if stop.starting:  # before anything was computed: nothing to keep, the lock goes
                log.warning("%s", exc)
                to_stderr(printable(f"multilayer: {exc}"))
                exc.said = True
            raise
        finally:
            handler.close()
        return summary(outdir / RESULT_FILE, checked=False)  # every state passed the state guard


def umask() -> int | None:
    """The process's umask, read without setting it (``os.umask`` sets it, for every thread
    of the host: the library does not change its process), from Linux's ``/proc``; None
    where it cannot be read."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    return None


def output_directory(
    outdir: Path, source: Path | None = None, inputs: dict[str, Path] | None = None
) -> list[Path]:
    """Make ``outdir`` and check that files can be written there, none of the run's the
    scenario file ``source`` (``multilayer run DIR/run.log -o DIR`` wrote the log over
    it) or a file it reads, ``inputs`` by key (a bed file ``DIR/result.nc`` was written
    over by the run it shaped); the directories made, deepest first.  :class:`InputError`
    naming it (``-o DIR`` or ``output.directory``) otherwise."""
    accepted = "accepted: an output directory (-o DIR or output.directory) that can be created and written"
    try:
        str(outdir).encode("utf-8")
    except UnicodeEncodeError:
        raise InputError(
            f"{outdir}: not a UTF-8 name (netCDF files cannot be named by other bytes); {accepted}"
        ) from None
    if "\0" in str(outdir):  # no system call takes it: Python's ValueError, with a traceback
        raise InputError(f"{str(outdir)!r}: a name holding the NUL character; {accepted}")
    if not outdir.is_absolute() and working_directory_removed():
        raise InputError(f"{outdir}: {REMOVED_WORKING_DIRECTORY}")
    missing = [path for path in (outdir, *outdir.parents) if not path.exists()]
    if outdir.exists() and not outdir.is_dir():  # mkdir says only "File exists"
        raise InputError(f"{outdir}: a file, not a directory; {accepted}")
    if outdir.is_symlink() and not outdir.exists():  # mkdir says "File exists" here too
        raise InputError(
            f"{outdir}: a symbolic link to {os.readlink(outdir)}, which does not exist (or links back to "
            f"itself); {accepted}"
        )
    try:
        outdir.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=outdir):
            pass
    except OSError as exc:
        mask = umask() if missing else None  # directories made here, under it
        owner = "" if not mask or not mask & 0o700 else (
            f": the umask {mask:04o} leaves the directories made here without permissions their owner "
            f"needs ({stat.filemode(0o40777 & ~mask)})"
        )  # fmt: skip
        raise InputError(
            f"{outdir}: cannot be created or written ({reason(exc)}){owner}; {accepted}"
        ) from None
    read = {"the scenario file itself": source} if source is not None else {}
    of = f" of {source}" if source is not None else ""
    read.update({f"the file {key}{of}": path for key, path in (inputs or {}).items()})
    written = (RESULT_FILE, CHECKPOINT_FILE, LOG_FILE)
    for name in written:
        path = writable(outdir / name, in_place=name != CHECKPOINT_FILE)  # the checkpoint is replaced
        not_an_input(path, read, written)
    for name in (LOCK_FILE, CHECKPOINT_FILE + ".tmp"):  # made afresh, but over what is there
        not_an_input(outdir / name, read, (*written, LOCK_FILE))
    return missing


def not_an_input(
    path: Path,
    read: dict[str, Path],
    written: tuple[str, ...],
    writer: str = "the run",
    reader: str = "the scenario",
) -> None:
    """:class:`InputError` if ``path``, a file ``writer`` writes, is one it reads (``read``:
    what it is, by its path), which it would write over."""
    for what, source in read.items():
        try:
            same = path.exists() and source.exists() and path.samefile(source)
        except OSError:  # a link loop or a name too long: not the file read (loading named it)
            same = False
        if same:
            raise InputError(
                f"{path}: {what}, which {writer} would write over; accepted: files {reader} reads "
                f"not named {', '.join(written)} in the output directory"
            )


def _run(
    scenario: Any,
    text: str,
    outdir: Path,
    ckpt: Checkpoint | None,
    quiet: bool | None,
    log: logging.Logger,
    stop: _StopRequest,
    step_limit: float,
) -> None:
    log.info(
        "%s run of scenario %r from %s into %s",
        "resumed" if ckpt else "new",
        scenario.name,
        scenario.source or "a mapping",
        outdir,
    )
    log.info("parameters:\n%s", text.rstrip())
    ahead = compile_ahead(scenario)  # the kernels, on two cores where they are not cached yet
    if ahead is not None:
        log.info("numba compiled the Newton kernel in a child process beside the transport: %.1f s", ahead)
    try:
        sim = Simulation(scenario)
    except MemoryError as exc:  # beyond the estimate, or its check skipped (--force, --max-memory)
        where, domain = scenario.source or "<scenario>", scenario.domain
        raise InputError(
            f"{where}: domain.cells, domain.layers: {domain.cells} cells x {domain.layers} layers do not "
            f"fit in memory ({exc}; the estimate is about "
            f"{resources.size_text(resources.estimate(scenario).memory)}); accepted: fewer cells or layers"
        ) from None
    result_path, ckpt_path = outdir / RESULT_FILE, outdir / CHECKPOINT_FILE
    stop.starting = False  # from here a signal is honoured between kernel calls, the state kept
    if ckpt is None:
        ckpt_path.unlink(missing_ok=True)
        writer = ResultWriter(result_path, scenario, text, sim)
        writer.write(sim)
        wall_before = 0.0
    else:
        try:
            sim.load_state(ckpt.state)
        except InputError as exc:
            raise InputError(
                f"{ckpt_path}: {exc}: not a checkpoint this version of multilayer writes for this scenario; "
                "start again without --resume (the run is then computed afresh)"
            ) from None
        writer = ResultWriter(result_path, scenario, text, sim, records=ckpt.records)
        wall_before = ckpt.wall_time_s
        log.info("restored the checkpoint at t = %.6g s, step %d", sim.t, sim.steps)
    started = time.perf_counter()

    def wall_time() -> float:
        return wall_before + time.perf_counter() - started

    def checkpoint() -> float:
        save_checkpoint(ckpt_path, Checkpoint(sim.state_dict(), writer.records, wall_time(), text))
        return sim.t

    saved_t = checkpoint() if ckpt is None else sim.t
    n_layers, n_cells = sim.read_only("u").shape
    log.info("%d cells x %d layers; output times up to %g s", n_cells, n_layers, scenario.time.end)
    times = output_times(scenario.time.end, scenario.time.output_interval)
    progress = Progress(scenario.time.end, n_cells * n_layers, quiet=quiet)

    def on_step(sim: Any, dt: float) -> None:
        progress(sim, dt)
        stop.poll()
        if sim.steps >= step_limit:
            raise RunError(
                f"the run has taken {sim.steps} time steps, its bound (--max-steps, default "
                f"{resources.MAX_STEPS}); continue with: {_resume_command(scenario, outdir)} --max-steps "
                f"{2 * sim.steps}"
            )

    sim.poll = stop.poll  # also between the kernel calls of a step
    status = "failed"
    try:
        # the output times after the last record kept: a run stopped (a signal, its step bound)
        # just as it reached an output time has checkpointed that state before its record
        for t_out in times[after_record(times, writer.last_time, scenario.time.end)]:
            sim.advance(t_out, on_step=on_step, max_steps=None)  # bounded by on_step, over the run
            sim.check_state()
            diag = writer.write(sim)
            saved_t = checkpoint()
            log.info(
                "output t = %.6g s: step %d, front %.6g m, mass %.6g m2, wall %.1f s",
                sim.t,
                sim.steps,
                diag["front"],
                diag["mass"],
                wall_time(),
            )
        writer.check_file()  # the last record is in the file the run leaves
        status = "completed"
    except (Stop, KeyboardInterrupt) as exc:
        status = "interrupted"
        if isinstance(exc, Stop):  # stopped between two kernel calls or in a plugin: the state is whole
            saved_t = checkpoint()
        message = (
            f"interrupted by {stop.name} at t={saved_t:.6g} s; resume with: "
            f"{_resume_command(scenario, outdir)}"
        )
        log.warning(message)
    except WriteFailed as exc:  # nothing more can be written: the last checkpoint stands
        log.error("the run stopped at t = %.6g s (step %d): %s", sim.t, sim.steps, exc)
        writer.failure = str(exc)
        raise RunError(
            f"scenario {scenario.name!r}: {exc}; the run stopped at t={sim.t:.6g} s (step {sim.steps}); "
            + _what_is_kept(exc, outdir, writer.records, saved_t, _resume_command(scenario, outdir))
        ) from exc
    except Exception as exc:
        log.exception("the simulation failed at t = %.6g s (step %d)", sim.t, sim.steps)
        # the engine never keeps a state it rejects: sim holds the last good one
        kept = _keep_last_good_state(sim, writer, checkpoint, saved_t, log)
        writer.failure = str(exc)
        raise RunError(
            f"scenario {scenario.name!r}: the simulation failed at t={sim.t:.6g} s "
            f"(step {sim.steps}): {exc}; {outdir / RESULT_FILE} holds the output times "
            f"up to t={saved_t:.6g} s{kept}"
        ) from exc
    finally:
        progress.finish()
        writer.close(sim.steps, wall_time(), status, text)
    if status == "interrupted":
        if stop.requested:  # a member stopped by its study leaves the resume command to the study
            to_stderr(printable(f"multilayer: {message}"))
        raise Interrupted(message, stop.signum, said=stop.requested)
    log.info("completed: %d steps, wall time %.1f s", sim.steps, wall_time())


def _what_is_kept(exc: WriteFailed, outdir: Path, records: int, saved_t: float, resume: str) -> str:
    """The end of the message of a run stopped by a write that failed: what its files keep
    and how to continue (an output directory gone during the run took them with it)."""
    if not outdir.is_dir():
        return (
            f"the output directory {outdir} is gone (removed or moved during the run), and the files "
            "written there with it; run again into a directory left in place"
        )
    if not (outdir / RESULT_FILE).is_file():
        return f"run again (the state at t={saved_t:.6g} s in {CHECKPOINT_FILE} continues no result file)"
    condition = "there is room" if isinstance(exc, DiskFull) else f"{outdir} can be written again"
    return (
        f"{outdir / RESULT_FILE} keeps the {records} output times written before and {CHECKPOINT_FILE} the "
        f"state at t={saved_t:.6g} s; once {condition}, continue with: {resume}"
    )


class _LogFile(logging.FileHandler):
    """``run.log``: a line that cannot be written (a full disk) is dropped, where logging
    would print a traceback on stderr."""

    def handleError(self, record: logging.LogRecord) -> None:
        """Drop the line (the messages on stderr say what the log would have)."""

    def close(self) -> None:
        """Close the file, the lines still buffered dropped if they cannot be written: the
        error of the flush had replaced the run's own (a full disk: ``[Errno 27] File too
        large``, naming no file, for the result file that did not fit)."""
        with contextlib.suppress(OSError):
            super().close()


def _keep_last_good_state(sim: Any, writer: ResultWriter, checkpoint: Any, saved_t: float, log: Any) -> str:
    """Checkpoint the state ``sim`` holds after a failure and append it to the result file
    (after the checkpoint's record count, so a resume overwrites it); the message tail."""
    if not sim.t > saved_t:
        return ""
    try:
        sim.check_state()
        checkpoint()
        writer.write(sim)
    except Exception:  # noqa: BLE001 - the failure being reported matters more than this extra record
        log.exception("could not keep the last good state at t = %.6g s", sim.t)
        return ""
    return f" and the last good state at t={sim.t:.6g} s (also in the checkpoint)"


def _checkpoint_to_resume(
    scenario: Any, text: str, outdir: Path, notice: Callable[[str], None]
) -> tuple[Checkpoint, float]:
    """The checkpoint in ``outdir``, checked to belong to ``scenario``: every key but
    :data:`_FREE_KEYS` the same, ``time.end`` not before the checkpoint; and the
    ``time.end`` the resumed run ends at.  A change of another free key (a new name) is
    allowed and said through ``notice``.

    A ``time.end`` no later than the result's last record by more than the rounding of
    output times (:data:`RECORD_ROUNDING`) is that record's time: the run is finished
    there, which ``notice`` says, and ends at that record, whose time it keeps as its
    ``time.end`` (one unit of round-off later, no output time came after the record, and
    the result claimed an end it does not reach: every reader refused it)."""
    ckpt_path = outdir / CHECKPOINT_FILE
    if not (ckpt_path.is_file() and (outdir / RESULT_FILE).is_file()):
        raise InputError(
            f"{outdir}: nothing to resume ({CHECKPOINT_FILE} or "
            f"{RESULT_FILE} missing); run without --resume to start afresh"
        )
    ckpt = load_checkpoint(ckpt_path)
    try:  # the records before the checkpoint must be whole: the run appends after them
        check_result(outdir, "resume", records=ckpt.records)
    except InputError as exc:
        raise InputError(f"{exc}, or run without --resume to start afresh") from None
    saved, resolved = yaml.safe_load(ckpt.scenario), yaml.safe_load(text)
    # the records go on after the checkpoint's: another run's result.nc put there (copied, or
    # another scenario run into the directory and stopped) was continued and relabelled
    other = _changed_keys(yaml.safe_load(recorded(outdir, "scenario")), saved)
    if other:
        raise InputError(
            f"{outdir / RESULT_FILE}: holds the output times of another scenario than its checkpoint "
            f"(changed: {', '.join(other)}); run without --resume to start afresh"
        )
    changed = _changed_keys(saved, resolved)
    if changed:
        raise InputError(
            f"{ckpt_path}: the checkpoint belongs to a different scenario (changed: "
            f"{', '.join(changed)}); resume with the same scenario file and --set "
            f"options (only {', '.join(sorted(_FREE_KEYS))} may change), or run without --resume"
        )
    origin, before = provenance(), recorded(outdir, "made_by")
    if before != made_by(origin.version, origin.commit):  # the file's attributes name the first only
        notice(
            f"{outdir / RESULT_FILE}: its output times so far were computed by {before}, the ones to come "
            f"by {made_by(origin.version, origin.commit)} (its history says which run wrote which)"
        )
    relabelled = [key for key in _changed_keys(saved, resolved, free=frozenset()) if key != "time.end"]
    if relabelled:
        notice(
            f"{ckpt_path}: resuming with {', '.join(relabelled)} changed (no part of the computed "
            f"solution; the result and the checkpoint take the new values)"
        )
    t_saved, end = float(ckpt.state["t"]), scenario.time.end
    if t_saved > end:  # every digit: one unit of round-off earlier is earlier
        raise InputError(
            f"{ckpt_path}: the checkpoint is at t = {t_saved!r} s, beyond time.end = {end!r} s; accepted: "
            f"a time.end at or after {t_saved!r} s (a run can be extended, not shortened), or run without "
            "--resume"
        )
    last = record_time(outdir, ckpt.records - 1)
    if not after_record(end, last, end):
        if t_saved > last:  # stopped after its last record, within the rounding of the end
            raise InputError(
                f"{ckpt_path}: time.end = {end!r} s is the time of the result's last record, t = {last!r} s, "
                f"to within the rounding of output times ({RECORD_ROUNDING:g} of time.end), and the "
                f"checkpoint is after it, at t = {t_saved!r} s; accepted: a time.end later than {last!r} s "
                f"by more than {RECORD_ROUNDING:g} of itself, or run without --resume"
            )
        said = (
            f"the result's last record is at time.end = {end!r} s: the run is finished there"
            if end == last
            else f"time.end = {end!r} s is the time of the result's last record, t = {last!r} s, to within "
            f"the rounding of output times ({RECORD_ROUNDING:g} of time.end): the run is finished there and "
            f"keeps time.end = {last!r} s"
        )
        notice(f"{ckpt_path}: {said}; nothing to compute (a later time.end extends it)")
        return ckpt, last
    interval, old_end = scenario.time.output_interval, float(saved["time"]["end"])
    schedule = output_times(scenario.time.end, interval)
    finished = abs(t_saved - old_end) <= 1e-12 * old_end
    on_schedule = np.any(np.abs(schedule - t_saved) <= 1e-9 * (interval or t_saved))
    if finished and t_saved < scenario.time.end and not on_schedule:
        # a finished run's last record at its old time.end, between two output times of the new
        # schedule: the run goes on from there, its steps cut to land on it
        notice(
            f"{ckpt_path}: extending from t = {t_saved:g} s (the time.end {old_end:g} s it ran to), not an "
            f"output time of k x {interval or scenario.time.end:g} s: its record at {t_saved:g} s stays, "
            f"one more than an uninterrupted run to {scenario.time.end:g} s writes, and the steps after "
            "it differ from that run's (the same to the accuracy of the scheme, not to the bit); for the "
            "uninterrupted run's result, run without --resume, or end runs to be extended on an output time"
        )
    return ckpt, end


#: Keys that do not change the computed solution, the only ones a resumed run may change
#: (docs/cli.md, ``--resume``); ``time.end`` may grow to extend a run.
_FREE_KEYS = frozenset({"name", "description", "output", "expect", "time.end"})


def _changed_keys(old: Any, new: Any, free: frozenset[str] = _FREE_KEYS, prefix: str = "") -> list[str]:
    """Dotted keys (``--set`` style) whose values differ between two parsed scenarios."""
    if prefix.rstrip(".") in free:
        return []
    if isinstance(old, dict) and isinstance(new, dict):
        return [
            key
            for k in sorted(old.keys() | new.keys(), key=str)
            for key in _changed_keys(old.get(k), new.get(k), free, f"{prefix}{k}.")
        ]
    if isinstance(old, list) and isinstance(new, list) and len(old) == len(new):
        return [
            key
            for i, (a, b) in enumerate(zip(old, new))
            for key in _changed_keys(a, b, free, f"{prefix}{i}.")
        ]
    return [] if old == new else [prefix.rstrip(".")]


def _resume_command(scenario: Any, outdir: Path) -> str:
    """The command line continuing this run, with ``--set`` for what differs from the file."""
    if scenario.source is None:
        return f"multilayer run SCENARIO.yaml -o {shlex.quote(str(outdir))} --resume"
    words = ["multilayer", "run", str(scenario.source), "-o", str(outdir), "--resume"]
    resolved = yaml.safe_load(scenario.resolved_yaml())
    try:
        on_file = yaml.safe_load(scenarios.load(scenario.source).resolved_yaml())
    except InputError:  # the file changed or went away since the start
        on_file = {}
    settings: dict[str, Any] = {}
    for key in _changed_keys(on_file, resolved, free=frozenset()):
        # a key only in the file cannot be unset by --set: its nearest mapping or list in the
        # run is set whole (a --set rheology={...} replacing the file's law had left the
        # file's other parameters in the command, which then failed)
        parts = key.split(".")
        while (value := _at_path(resolved, parts)) is _MISSING and len(parts) > 1:
            parts = parts[:-1]
        if value is not _MISSING:
            settings[".".join(parts)] = value
    for key, value in settings.items():
        if not any(key.startswith(f"{other}.") for other in settings):  # not inside one set whole
            words += ["--set", f"{key}={json.dumps(value)}"]  # JSON is YAML
    return shlex.join(words)


_MISSING = object()


def _at_path(data: Any, parts: list[str]) -> Any:
    """The value of ``data`` at the dotted key ``parts``, or :data:`_MISSING`."""
    for part in parts:
        if isinstance(data, list) and part.isdigit() and int(part) < len(data):
            data = data[int(part)]
        elif isinstance(data, dict) and part in data:
            data = data[part]
        else:
            return _MISSING
    return data


#: Signals handled like Ctrl-C (those that exist on this platform).
STOP_SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)


@contextmanager
def handled_by(handler: Callable[[int, FrameType | None], None]) -> Iterator[None]:
    """:data:`STOP_SIGNALS` handled by ``handler`` while active (in the main thread, which
    alone receives signals), their handlers set back after.  A signal the process ignores
    stays ignored: a job started with ``&`` by a non-interactive shell inherits SIGINT
    ignored, one under ``nohup`` SIGHUP, and Python itself then leaves SIGINT alone (no
    ``KeyboardInterrupt``); a run that took it had stopped on a Ctrl-C meant for the shell's
    foreground job."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {
        signum: signal.signal(signum, handler)
        for signum in STOP_SIGNALS
        if signal.getsignal(signum) != signal.SIG_IGN
    }
    try:
        yield
    finally:
        for signum, before in previous.items():
            signal.signal(signum, before)


class _StopRequest:
    """Handler of :data:`STOP_SIGNALS` turning the first signal into a stop request."""

    signum: int = signal.SIGINT
    requested = False
    starting = True
    """Until the result file is opened a signal stops at once: nothing is computed yet."""

    def __init__(self, stop_when: Callable[[], bool] | None = None) -> None:
        self.stop_when = stop_when
        """Asked between kernel calls too: True requests a stop (of a study's member)."""

    @property
    def name(self) -> str:
        if not self.requested:
            return "a stop of its study"
        return "Ctrl-C (SIGINT)" if self.signum == signal.SIGINT else signal.Signals(self.signum).name

    def poll(self) -> None:
        """Raise :class:`Stop` if a stop was requested (called between kernel calls)."""
        if self.requested or (self.stop_when is not None and self.stop_when()):
            raise Stop

    def installed(self) -> contextlib.AbstractContextManager[None]:
        return handled_by(self._handle)

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self.starting:
            name = "Ctrl-C (SIGINT)" if signum == signal.SIGINT else signal.Signals(signum).name
            raise Interrupted(
                f"stopped by {name} during start-up, before the first step: nothing was computed "
                "or written; run the command again to start the run",
                signum,
            )
        if self.requested:
            raise Interrupted(f"stopped at once by a second signal ({signal.Signals(signum).name})", signum)
        self.signum = signum
        self.requested = True
        if in_plugin_call():  # its own Python code, which may never return: the step is abandoned
            raise Stop
