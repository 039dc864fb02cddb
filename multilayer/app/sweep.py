"""Parameter sweeps (ensembles) of one scenario on Dask distributed.

A sweep file names a base scenario and lists values for dotted scenario keys::

    base: collapse.yaml                  # relative to the sweep file
    parameters:
      rheology.mu_s: [0.40, 0.45, 0.50]
      initial.0.thickness: [0.0, 0.003]
    zip: false                           # true: pair the lists element by element
    output: {directory: results/collapse-sweep}

The members are the Cartesian product of the lists (or, with ``zip: true``, their
element-wise pairing).  Each member is the base scenario with its values applied
exactly as ``multilayer run --set KEY=VALUE`` applies them, and is validated on the
client before anything is submitted.  Valid members run as independent tasks on a Dask
distributed cluster (Rocklin 2015, "Dask: parallel computation with blocked algorithms
and task scheduling", SciPy proceedings); each writes ``DIR/<member-id>/result.nc`` and,
once complete, the marker ``DIR/<member-id>/member.json`` that lets a re-run skip it.
"""

from __future__ import annotations

import contextlib
import csv
import functools
import hashlib
import itertools
import json
import math
import os
import re
import shutil
import tempfile
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from multilayer import scenario
from multilayer.app import resources, runner, stopping
from multilayer.errors import InputError, Interrupted, RunError, ascii_count, described, reason
from multilayer.io.disk import writable, writable_directory, write_whole
from multilayer.io.results import (
    CHECKPOINT_FILE,
    MIXTURE_SUMMARY_KEYS,
    RESULT_FILE,
    SUMMARY_KEYS,
    recorded,
    run_failure,
)
from multilayer.io.results import summary as result_summary
from multilayer.scenario import as_overrides, format_value
from multilayer.scenario.loading import BASE_ACCEPTED, load_base
from multilayer.scenario.messages import HOME_ACCEPTED, dotted, shown, unknown_home
from multilayer.scenario.overrides import member_output

SWEEP_KEYS = ("base", "parameters", "zip", "output", "description")
"""Top-level keys accepted in a sweep file."""

MAX_MEMBERS = 10_000
"""Most members of a sweep (each a run and a directory)."""

MARKER = "member.json"
"""Written into a member's directory once its run has completed."""
MEMBER_DIRECTORY = re.compile(r"(m[0-9]+|e)-[0-9a-f]{8}")
"""The name of a member's directory in a study's: ``m<index>-<hash>`` of a sweep
(:meth:`Sweep.members`), ``e-<hash>`` of a calibration or sensitivity study
(:meth:`~multilayer.app.ensemble.Ensemble.member_id`)."""
MARKER_BYTES = 1 << 20
"""The most of a marker read (one is a few hundred bytes): a larger file is no marker."""

Status = Literal["ok", "invalid", "failed", "interrupted"]


@dataclass(frozen=True)
class Member:
    """One member of a sweep: the base scenario with ``values`` (dotted key -> value)."""

    index: int
    values: dict[str, Any]
    id: str
    overrides: list[str]
    """The member's values as ``KEY=VALUE`` overrides for ``scenario.load``."""


def overrides_digest(overrides: list[str]) -> str:
    """Short hash of a set of overrides, independent of their order."""
    return hashlib.sha1("\n".join(sorted(overrides)).encode()).hexdigest()[:8]


@dataclass(frozen=True)
class Sweep:
    """A validated sweep file."""

    path: Path
    """The sweep file."""
    base: Path
    """The base scenario file (resolved against the sweep file's directory)."""
    parameters: dict[str, list[Any]]
    """Dotted scenario key -> list of values, in file order."""
    paired: bool = False
    """``zip: true``: pair the lists element by element instead of taking their product."""
    output: Path | None = None
    """``output.directory`` of the sweep file, if given."""

    @functools.cached_property
    def _base_yaml(self) -> tuple[Any, dict]:
        """The base scenario file, parsed once for every member."""
        return scenario.read_yaml(self.base)

    def member_scenario(self, member: Member, extra: Sequence[str] = ()) -> scenario.Scenario:
        """``scenario.load(base, [*member.overrides, *extra])``, the base file read once:
        a member costs its validation only (10^4 members of a small base scenario: about
        2 ms each, where reading the file again made 4)."""
        data, lines = self._base_yaml
        return scenario.from_dict(data, source=self.base, overrides=[*member.overrides, *extra], lines=lines)

    def members(self) -> list[Member]:
        """The members in a stable order, with ids ``m<index>-<hash of the overrides>``."""
        keys = list(self.parameters)
        lists = [self.parameters[key] for key in keys]
        combos = zip(*lists) if self.paired else itertools.product(*lists)
        rows = [dict(zip(keys, combo)) for combo in combos]
        width = max(3, len(str(len(rows) - 1)))
        members = []
        for index, values in enumerate(rows):
            overrides = as_overrides(values)
            members.append(
                Member(index, values, f"m{index:0{width}d}-{overrides_digest(overrides)}", overrides)
            )
        return members


def _as_read(value: Any) -> Any:
    """``value`` with its numbers as floats (mappings and lists through): numbers equal as
    the schema reads them compare equal (an integer beyond 2^53 stays itself)."""
    if isinstance(value, dict):
        return {key: _as_read(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_as_read(item) for item in value]
    if isinstance(value, int | float) and not isinstance(value, bool) and abs(value) <= 2**53:
        return float(value)
    return value


def _non_finite(value: Any) -> bool:
    """True if ``value`` holds an infinity or a NaN (mappings and lists through)."""
    if isinstance(value, dict):
        return any(_non_finite(item) for item in value.values())
    if isinstance(value, list):
        return any(_non_finite(item) for item in value)
    return isinstance(value, float) and not math.isfinite(value)


UNRUN = ("name", "description")
"""The scenario keys a run does not read: members differing only there are one run."""


def load(path: str | Path) -> Sweep:
    """Read and strictly validate a sweep file; raise :class:`InputError` on bad input.

    Messages follow the scenario files': ``<file>: <key.path> (line N): <what>; accepted: <...>``.
    """
    path = Path(path)
    data, lines = scenario.read_yaml(path, "sweep")

    def at(key: tuple[str, ...]) -> str:
        line = f" (line {lines[key]})" if key in lines else ""
        return f"{path}: {dotted(key)}{line}"

    def bad(key: tuple[str, ...], what: str, accepted: str) -> InputError:
        return InputError(f"{at(key)}: {what}; accepted: {accepted}")

    if not isinstance(data, dict):
        raise InputError(
            f"{path}: (top level): got {type(data).__name__}; accepted: a "
            f"mapping with the keys {', '.join(SWEEP_KEYS)}"
        )
    for key in data:
        if key not in SWEEP_KEYS:
            raise bad((str(key),), "unknown key", ", ".join(SWEEP_KEYS))

    if "base" not in data:
        raise bad(("base",), "required key is missing", BASE_ACCEPTED)
    if not isinstance(data["base"], str) or not data["base"]:
        raise bad(("base",), f"got {shown(data['base'])}", BASE_ACCEPTED)
    base = load_base(path, data["base"], at(("base",)), "the base scenario")

    parameters = data.get("parameters")
    if not isinstance(parameters, dict) or not parameters:
        raise bad(
            ("parameters",),
            f"got {shown(parameters)}",
            "a non-empty mapping of dotted scenario keys to lists of values, "
            "e.g. {rheology.mu_s: [0.4, 0.5]}",
        )
    for key, values in parameters.items():
        if not isinstance(key, str) or not key.isprintable() or any(c.isspace() or c == "=" for c in key):
            raise bad(
                ("parameters", str(key)),
                "not a scenario key",
                "a dotted scenario key such as domain.cells or initial.0.thickness",
            )
        if "" in key.split("."):  # was reported as a member's --set, a key the file does not hold
            raise bad(
                ("parameters", key),
                f"the key {shown(key)} has an empty part",
                "a dotted scenario key, no part empty, such as domain.cells or initial.0.thickness",
            )
        if key in UNRUN:  # each member ran the one simulation, under another name
            raise bad(
                ("parameters", key),
                f"{key} does not change the run: every member would run the same simulation",
                "scenario keys that change the run",
            )
        if not isinstance(values, list) or not values:
            raise bad(("parameters", key), f"got {shown(values)}", "a non-empty list of values")
        refused = member_output(key, "sweep")
        if refused:
            raise InputError(f"{at(('parameters', key))}: {refused}")

    paired = data.get("zip", False)
    if not isinstance(paired, bool):
        raise bad(("zip",), f"got {shown(paired)}", "true or false")
    lengths = {key: len(values) for key, values in parameters.items()}
    if paired and len(set(lengths.values())) > 1:
        raise bad(
            ("zip",),
            "the lists under parameters have different lengths ("
            + ", ".join(f"{key}: {n}" for key, n in lengths.items())
            + ")",
            "lists of equal length with zip: true",
        )

    count = len(next(iter(parameters.values()))) if paired else math.prod(lengths.values())
    if count > MAX_MEMBERS:
        raise bad(
            ("parameters",),
            f"{count} members ({' x '.join(str(n) for n in lengths.values())})",
            f"at most {MAX_MEMBERS} members: fewer values, or several sweeps",
        )
    for key, values in parameters.items():  # NaN is no value twice: NaN != NaN
        for index, value in enumerate(values):
            if _non_finite(value):
                raise bad(
                    ("parameters", key),
                    f"entry {index} ({format_value(value)}) "
                    + (
                        "holds a number that is not finite"
                        if isinstance(value, list | dict)
                        else "is not a finite number"
                    ),
                    "finite numbers (no number in a scenario may be infinite or NaN)",
                )
    # the members' overrides as they will read (0.4 and 0.40 are one value, and so are 20
    # and 20.0, the same number to the schema): a product of lists has two equal members
    # when one list holds a value twice; paired lists, when a tuple of values comes twice.
    # Compared by repr (a float's round-trips); YAML text, 0.7 ms a value, only for the message
    read = {key: [repr(_as_read(value)) for value in values] for key, values in parameters.items()}
    for key, texts in {"zip": list(zip(*read.values()))}.items() if paired else read.items():
        seen: dict[Any, int] = {}
        for index, text in enumerate(texts):
            if text in seen:
                values = [v[index] for v in parameters.values()] if paired else [parameters[key][index]]
                raise bad(
                    ("zip",) if paired else ("parameters", key),
                    f"entries {seen[text]} and {index} give the same member "
                    f"({', '.join(format_value(_as_read(value)) for value in values)}): it would run twice",
                    "distinct members",
                )
            seen[text] = index

    output = data.get("output", {})
    if not isinstance(output, dict):
        raise bad(("output",), f"got {shown(output)}", "a mapping with the key directory")
    for key in output:
        if key != "directory":
            raise bad(("output", str(key)), "unknown key", "directory")
    directory = output.get("directory")
    if directory is not None and (not isinstance(directory, str) or not directory or "\0" in directory):
        raise bad(("output", "directory"), f"got {shown(directory)}", "a directory path (no NUL character)")
    if directory is not None and (home := unknown_home(directory)) is not None:
        raise bad(("output", "directory"), home, HOME_ACCEPTED)

    return Sweep(
        path=path,
        base=base,
        parameters=parameters,
        paired=paired,
        output=Path(directory).expanduser() if directory else None,  # ~ as a shell reads it
    )


@dataclass
class Outcome:
    """What became of one member."""

    member: Member
    status: Status
    error: str = ""
    summary: dict[str, float] = field(default_factory=dict)
    skipped: bool = False
    """True if an earlier run of the sweep had already completed this member."""


def scenario_fingerprint(member_scenario: scenario.Scenario) -> str:
    """Hash of the fully resolved member scenario: a completed member is reused only if
    neither the base scenario nor the member's values changed since it ran."""
    return _fingerprint(member_scenario.resolved_yaml())


def _fingerprint(resolved: str) -> str:
    return hashlib.sha256(resolved.encode()).hexdigest()


def completed(member_dir: Path, fingerprint: str) -> dict[str, float] | None:
    """The summary of the member's ``result.nc`` if ``member_dir`` holds a completed, finite
    run of this exact scenario: the marker's fingerprint and the scenario ``result.nc``
    records both this one's (a run of another scenario into the member's directory,
    ``multilayer run -o``, leaves the marker: its summary was reported and its result
    measured as the member's).  The summary is read from the result, which passed its
    checks, not from the marker: a marker edited or damaged (a runout of 99, NaN, text)
    was reported as the member's.  Only a regular file's first :data:`MARKER_BYTES` are
    read: a named pipe there held the study for ever, waiting for a writer."""
    path = member_dir / MARKER
    if not path.is_file():
        return None
    try:
        with path.open("rb") as stream:
            marker = json.loads(stream.read(MARKER_BYTES).decode("utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    summary = marker.get("summary") if isinstance(marker, dict) else None
    if not (isinstance(summary, dict) and set(summary) - set(MIXTURE_SUMMARY_KEYS) == set(SUMMARY_KEYS)):
        return None  # not a marker this module wrote: the member runs again
    if marker.get("fingerprint") != fingerprint or not (member_dir / RESULT_FILE).is_file():
        return None
    if run_failure(member_dir) is not None or _fingerprint(recorded(member_dir, "scenario")) != fingerprint:
        return None
    return result_summary(member_dir / RESULT_FILE, checked=False)  # checked by run_failure


def run_member(
    member_scenario: scenario.Scenario, member_dir: str, fingerprint: str, overrides: list[str]
) -> dict[str, float]:
    """Run one member into ``member_dir`` (on a Dask worker) and mark it complete.

    A run interrupted earlier (its checkpoint belongs to this scenario) is continued,
    anything else starts afresh.  The run stops (checkpointed) when its study is stopped
    (:class:`~multilayer.app.stopping.StopFile` in the parent directory).  The marker is
    written atomically after the run, next
    to ``result.nc``, so that a member counts as complete exactly when its result is.
    """
    directory = Path(member_dir)
    (directory / MARKER).unlink(missing_ok=True)
    resumable = (directory / CHECKPOINT_FILE).is_file()
    stop = stopping.StopFile(directory.parent)
    try:
        try:
            summary = runner.run(member_scenario, directory, resume=resumable, quiet=True, stop_when=stop)
        except InputError:
            if not resumable:
                raise
            # the checkpoint belongs to another scenario: start afresh
            summary = runner.run(member_scenario, directory, resume=False, quiet=True, stop_when=stop)
    except Interrupted as exc:  # the study stopped: a plain failure for Dask (nobody waits for it)
        raise RunError(f"{directory}: {exc}") from None
    failure = run_failure(directory)
    if failure is not None:  # never label a run "ok" that is not complete and finite
        raise RunError(f"{directory / RESULT_FILE}: {failure}")
    marker = {"fingerprint": fingerprint, "overrides": overrides, "summary": summary}
    write_whole(directory / MARKER, lambda part: part.write_text(json.dumps(marker, indent=2) + "\n"))
    return summary


@dataclass(frozen=True)
class Failed:
    """What a member's task returns when it fails.  Raised on a worker process, the failure
    was logged by Dask there ("Compute Failed") with its traceback, on the user's terminal,
    once per failed member; the study reports it itself."""

    error: str


def contained(task: Callable[..., Any], *args: Any) -> Any:
    """``task(*args)`` on a worker, a failure returned as :class:`Failed` (its type and
    message)."""
    try:
        return task(*args)
    except Exception as exc:  # noqa: BLE001 - reported by the study, not in Dask's log
        return Failed(described(exc))


def result_of(future: Any) -> Any:
    """The value of a member's ``future``, or :class:`Failed` (a worker lost, say)."""
    try:
        return future.result()
    except Exception as exc:  # noqa: BLE001 - a failed member must not stop the study
        return Failed(described(exc))


def compile_kernels(member: scenario.Scenario) -> None:
    """Compile the engine's kernels in this process, or load them from numba's cache, by
    one single-threaded step of ``member``, before worker processes start.

    numba's on-disk cache is not safe when several processes compile the same function
    at once (numba issues 4807 and 10128): worker processes that all begin by compiling
    can corrupt it.  Once this process has written the cache, the workers only read it.
    A member that does not construct or step is left to report its own error when it runs.
    Nothing is done for a member under a third-party law: its code would run in the study's
    own process, where a law ending its process (``os._exit``, a crash of its C code) ended
    the study, silently, before any member ran; on a worker the member fails alone.  The
    workers then compile the engine's kernels themselves, each load and save of numba's
    cache under its directory's lock (:func:`multilayer.engine.kernel_cache.current`).
    """
    from multilayer.app.simulation import Simulation
    from multilayer.plugins import host

    laws = [spec.name for spec in (member.rheology, member.walls) if spec is not None]
    if not all(host.is_builtin(name) for name in laws):
        return
    numerics = member.numerics.model_copy(update={"threads": 1})
    try:
        Simulation(member.model_copy(update={"numerics": numerics})).step()
    except (InputError, RunError):
        return


def member_reads(plan: Sweep) -> dict[str, Path]:
    """The files the members of a sweep of a bed or initial-thickness key read (``bed.file``
    of ``bed.file: [a.csv, out/summary.csv]``), by what they are: each such member loaded
    (the others read the base scenario's files).  Members that do not load are left out:
    each names its own error."""
    if not any(key.split(".")[0] in ("bed", "initial") for key in plan.parameters):
        return {}
    reads = {}
    for member in plan.members():
        try:
            files = plan.member_scenario(member).input_files()
        except InputError:
            continue
        reads.update(
            {f"the file {key} of member {member.id} of {plan.path}": path for key, path in files.items()}
        )
    return reads


def base_member(base: Path, fixed: dict[str, Any]) -> scenario.Scenario | None:
    """The scenario ``base`` with the overrides ``fixed`` of a study (None if invalid:
    each member reports its own error)."""
    try:
        return scenario.load(base, as_overrides(fixed))
    except InputError:
        return None


@contextmanager
def dask_client(
    scheduler: str | None, workers: int | None, warm_up: scenario.Scenario | None = None
) -> Iterator[Any]:
    """A Dask client on the cluster at ``scheduler``, or on a new local cluster with
    ``workers`` single-threaded worker processes (default: one per core), started after
    :func:`compile_kernels` of ``warm_up`` (a member scenario)."""
    import dask
    from dask.distributed import Client
    from dask.system import CPU_COUNT

    if scheduler is not None:
        try:
            _answers(scheduler)
            client = Client(scheduler)
        except Exception as exc:  # noqa: BLE001 - a server that is no scheduler: numpy's MemoryError too
            raise InputError(
                f"--scheduler {scheduler}: cannot connect ({type(exc).__name__}: {reason(exc)}); accepted: "
                "the address of a running scheduler, as printed by `dask scheduler`, e.g. tcp://10.0.0.5:8786"
            ) from None
        with client:
            yield client
        return
    resources.check_workers(workers or CPU_COUNT)
    if warm_up is not None:
        compile_kernels(warm_up)
    # the workers' scratch space in a directory of its own, removed after: Dask left its
    # dask-scratch-space with two lock files in TMPDIR after every study
    temporary = dask.config.get("temporary-directory", None)
    try:
        scratch = tempfile.mkdtemp(prefix="multilayer-dask-", dir=temporary)
    except OSError as exc:
        if temporary is None:  # the system's temporary directory: the OSError names it
            raise
        raise InputError(
            f"Dask's temporary-directory {temporary} (DASK_TEMPORARY_DIRECTORY, or a Dask configuration "
            f"file): {exc.strerror}; accepted: a directory this user can write, or the setting unset"
        ) from None
    try:
        with dask.config.set({"temporary-directory": scratch}):  # the nannies' too
            try:
                cluster = _local_cluster(
                    n_workers=workers or CPU_COUNT,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=":0",
                    local_directory=scratch,
                    preload=[stopping.__name__],  # the workers ignore Ctrl-C: this process stops them
                )
            except (KeyError, ValueError, TypeError) as exc:  # a Dask setting it cannot read
                variables = ", ".join(_dask_variables()) or "none"
                raise InputError(
                    f"the local Dask cluster could not read its settings ({type(exc).__name__}: "
                    f"{reason(exc)}; set in the environment: {variables}); accepted: Dask settings (DASK_* "
                    "variables, Dask configuration files) of the forms Dask's documentation gives"
                ) from None
            except RuntimeError as exc:  # "Nanny failed to start.": the worker's own error is on stderr
                raise RunError(
                    f"the local Dask cluster could not start its {workers or CPU_COUNT} worker process(es) "
                    f"({reason(exc).rstrip('.')}; the worker's own error is above), so nothing was run; a "
                    "script read from standard input gives this (a new process cannot import its __main__ "
                    "again): run it from a file or as `multilayer`, or give --scheduler a running cluster"
                ) from None
        try:
            with Client(cluster) as client:
                yield client
        except BaseException:  # a stop (stopping.Interrupted) or a failure: do not wait for the workers
            stopping.close_quickly(cluster)
            raise
        cluster.close()
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _local_cluster(**options: Any) -> Any:
    """A started ``LocalCluster(**options)``; one whose start fails is closed before the
    error goes on.  Dask closes a cluster whose start failed, but that close can fail in
    its turn (a setting it cannot read fails its connection to its own scheduler too,
    distributed 2026.8): the scheduler then ran on, its work directory in the scratch
    space, until the process ended, the cluster "closing" for ever.  The scratch space,
    removed after the error, was gone when the scheduler's directory went at the exit
    ("Failed to remove ... scheduler-..." in Dask's log), and the exit waited 10 s for
    the cluster to close."""
    from dask.distributed import LocalCluster, Status

    made: list[Any] = []

    class Recorded(LocalCluster):  # the cluster, kept where its constructor raises
        def __init__(self, **options: Any) -> None:
            made.append(self)
            super().__init__(**options)

    try:
        return Recorded(**options)
    except BaseException:
        for cluster in made:
            if getattr(cluster, "status", Status.closed) == Status.closed:
                continue  # closed by Dask, or not started
            if getattr(cluster, "scheduler", None) is not None:
                with contextlib.suppress(Exception):  # the error being raised says why it failed
                    cluster.sync(cluster.scheduler.close)
            cluster.status = Status.closed  # its scheduler closed: its own close now stops its event loop
            cluster.close()
        raise


def _dask_variables() -> list[str]:
    """The names of the Dask settings of the environment (``DASK_*``), sorted."""
    return sorted(name for name in os.environ if name.startswith("DASK_"))


def _check_port(address: str) -> None:
    """``ValueError`` unless the port of a TCP or TLS ``address`` (Dask's ``tcp://`` the
    default scheme) written in digits is one, 1 to 65535: Dask retries a connection to
    port 99999 until its connection timeout (30 s), then names the timeout, not the port."""
    scheme, _, location = address.rpartition("://")
    port = location.rpartition(":")[2]
    if (scheme or "tcp") in ("tcp", "tls") and port.isascii() and port.isdigit():
        count = ascii_count(port)  # None past 18 digits: int() of 5000 raised its own ValueError
        if count is None or not 1 <= count <= 65535:
            raise ValueError(f"port {shown(port) if count is None else count} is no TCP port (1 to 65535)")


def _answers(address: str) -> None:
    """Connect to ``address`` as Dask's client does, its answer to the handshake awaited no
    longer than Dask's connection timeout: ``Client(address)`` awaits it without a bound
    (distributed 2026.8), and a server that accepts and says nothing (an HTTP server
    awaiting its request line) held the command for ever.  In a thread of its own: the
    caller's may run an event loop (a notebook)."""
    import asyncio
    from concurrent.futures import ThreadPoolExecutor

    import dask
    from dask.distributed import connect
    from dask.utils import parse_timedelta

    timeout = parse_timedelta(dask.config.get("distributed.comm.timeouts.connect"), default="seconds")
    _check_port(address)

    async def handshake() -> None:
        comm = await asyncio.wait_for(connect(address, timeout=timeout), 2 * timeout)
        await comm.close()

    with ThreadPoolExecutor(1) as thread:
        try:
            thread.submit(asyncio.run, handshake()).result()
        except TimeoutError:  # asyncio's
            raise TimeoutError(f"no answer to the handshake within {2 * timeout:g} s") from None


def run(
    sweep: Sweep,
    outdir: str | Path,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    on_start: Callable[[int, int, int, int], None] | None = None,
    on_progress: Callable[[int, int], None] | None = None,
) -> list[Outcome]:
    """Validate every member, skip completed ones, run the rest on Dask.

    ``on_start(total, skipped, invalid, to_run)`` is called once the members are
    validated, ``on_progress(done, to_run)`` after each member that ran.  A member that is
    invalid or fails does not stop the others.  Returns one :class:`Outcome` per member,
    in member order.
    """
    outdir = Path(outdir).resolve()
    members = sweep.members()
    outcomes: dict[int, Outcome] = {}
    try:
        _run(sweep, outdir, scheduler, workers, on_start, on_progress, members, outcomes)
    except Interrupted as exc:
        exc.outcomes = [  # type: ignore[attr-defined]
            outcomes.get(m.index) or Outcome(m, "interrupted", "not completed: the sweep was interrupted")
            for m in members
        ]
        raise
    return [outcomes[member.index] for member in members]


def _run(
    sweep: Sweep,
    outdir: Path,
    scheduler: str | None,
    workers: int | None,
    on_start: Callable[[int, int, int, int], None] | None,
    on_progress: Callable[[int, int], None] | None,
    members: list[Member],
    outcomes: dict[int, Outcome],
) -> None:
    """:func:`run`, filling ``outcomes`` (member index -> outcome) as members finish."""
    stopping.StopFile(outdir).clear()
    pending: list[tuple[Member, scenario.Scenario, str]] = []
    for member in members:
        stopping.check()
        try:
            member_scenario = sweep.member_scenario(member)
        except InputError as exc:
            outcomes[member.index] = Outcome(member, "invalid", str(exc))
            continue
        fingerprint = scenario_fingerprint(member_scenario)
        # refused before anything runs; its run makes it (a study refused later leaves none)
        summary = completed(writable_directory(outdir / member.id, make=False), fingerprint)
        if summary is not None:
            outcomes[member.index] = Outcome(member, "ok", summary=summary, skipped=True)
        else:
            pending.append((member, member_scenario, fingerprint))

    if on_start is not None:
        skipped = sum(outcome.skipped for outcome in outcomes.values())
        on_start(len(members), skipped, len(outcomes) - skipped, len(pending))
    if pending:
        with dask_client(scheduler, workers, warm_up=pending[0][1]) as client:
            futures = {
                client.submit(
                    contained,
                    run_member,
                    member_scenario,
                    str(outdir / member.id),
                    fingerprint,
                    member.overrides,
                    key=f"multilayer-{member.id}-{os.urandom(4).hex()}",
                    pure=False,
                ): member
                for member, member_scenario, fingerprint in pending
            }
            for done, future in enumerate(stopping.as_completed(client, list(futures), outdir), start=1):
                member, result = futures[future], result_of(future)
                outcomes[member.index] = (
                    Outcome(member, "failed", result.error)
                    if isinstance(result, Failed)
                    else Outcome(member, "ok", summary=result)
                )
                if on_progress is not None:
                    on_progress(done, len(pending))


def write_summary(sweep: Sweep, outcomes: list[Outcome], path: str | Path) -> None:
    """Write ``summary.csv``: one row per member with its values, status, error and the
    scalar diagnostics of its result; whole (a temporary file renamed over it: a stop or a
    full disk never leaves half of one)."""
    columns = ["member", *sweep.parameters, "status", "error", *SUMMARY_KEYS]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)

    def write(part: Path) -> None:
        with part.open("w", newline="") as stream:
            writer = csv.DictWriter(stream, fieldnames=columns)
            writer.writeheader()
            for outcome in outcomes:
                member, summary = outcome.member, outcome.summary
                row = {"member": member.id, "status": outcome.status, "error": outcome.error}
                row.update({key: format_value(value) for key, value in member.values.items()})
                row.update({key: repr(summary[key]) for key in SUMMARY_KEYS if key in summary})
                writer.writerow(row)

    write_whole(writable(path), write)
