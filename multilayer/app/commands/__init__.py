"""CLI subcommands: each module defines ``HELP``, ``add_arguments(parser)`` and ``main(args)``."""

import argparse
import contextlib
import importlib
import os
import stat
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1 in ASCII digits (a bad value is a usage error, exit
    code 2): ``int`` alone read ``--times 1_0`` as 10 and an Arabic-Indic 3 as 3, and a
    value of 5000 digits was quoted whole."""
    from multilayer.errors import MAX_COUNT_DIGITS, ascii_count
    from multilayer.scenario.messages import shown

    value = ascii_count(text)
    if value is None or value < 1:
        raise argparse.ArgumentTypeError(
            f"expected an integer >= 1 (ASCII digits, at most {MAX_COUNT_DIGITS}), got {shown(text)}"
        )
    return value


def decimal(text: str) -> float:
    """argparse type: a number in ASCII decimal notation (``0.25``, ``-1e-3``, ``-inf``), a
    bad one a usage error: ``float`` alone read ``--at 0_1`` as 1 m (and the message quoted
    ``--at 1``) and full-width or Arabic-Indic digits as ours."""
    from multilayer.scenario.messages import shown
    from multilayer.scenario.profiles import csv_number

    try:
        return csv_number(text)
    except ValueError:
        if text.strip().lower().lstrip("+-") in ("inf", "infinity", "nan"):
            return float(text)  # refused by the option's range, which names it
        raise argparse.ArgumentTypeError(
            f"expected a number in ASCII decimal notation (0.25, -1e-3), got {shown(text)}"
        ) from None


STUDIES_EXTRA = "pip install 'multilayer[studies]'"
"""How to install what the study commands need (Dask distributed, SALib)."""


def require(command: str, *modules: str) -> None:
    """Raise :class:`~multilayer.errors.InputError` (exit code 2) naming what ``command``
    needs and how to install it, unless every one of ``modules`` can be imported (the
    packages of the optional ``studies`` extra)."""
    from multilayer.errors import InputError

    missing = []
    for module in modules:
        try:
            importlib.import_module(module)
        except ImportError:
            missing.append(module)
    if missing:
        raise InputError(
            f"multilayer {command} needs {' and '.join(missing)} (not installed); "
            f"accepted: install the studies extra with {STUDIES_EXTRA}"
        )


def add_cluster_arguments(parser: argparse.ArgumentParser) -> None:
    """``--scheduler ADDRESS`` or ``--workers N``: where Dask runs the members."""
    cluster = parser.add_mutually_exclusive_group()
    cluster.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="address of a running Dask scheduler, e.g. tcp://10.0.0.5:8786 (default: start a local cluster)",
    )
    cluster.add_argument(
        "--workers",
        metavar="N",
        type=positive_int,
        help="worker processes of the local cluster (default: one per core)",
    )


def cluster_description(args: argparse.Namespace) -> str:
    """Where the members run, in words, from the options of :func:`add_cluster_arguments`."""
    if args.scheduler is not None:
        return f"the Dask cluster at {args.scheduler}"
    if args.workers is not None:
        return f"a local Dask cluster of {args.workers} single-threaded worker process(es)"
    return "a local Dask cluster (one single-threaded worker process per core)"


@contextmanager
def study_ensemble(
    args: argparse.Namespace, study: Any, outdir: Path, on_progress: Callable[[int, int], None]
) -> Iterator[Any]:
    """The :class:`~multilayer.app.ensemble.Ensemble` of a calibration or sensitivity
    ``study`` (its ``base`` scenario and fixed ``config.set``) on the cluster of
    :func:`add_cluster_arguments`, with Ctrl-C, SIGTERM and SIGHUP stopping it
    (``stopping.signals_stop``); a local cluster starts once the kernels are compiled on
    the base scenario (``sweep.dask_client``)."""
    from multilayer.app import stopping
    from multilayer.app.ensemble import Ensemble
    from multilayer.app.sweep import base_member, dask_client

    fixed = study.config.set
    with (
        stopping.signals_stop(),
        dask_client(args.scheduler, args.workers, warm_up=base_member(study.base, fixed)) as client,
    ):
        yield Ensemble(study.base, outdir, client, fixed=fixed, on_progress=on_progress)


@contextmanager
def study_directory(outdir: Path, reads: dict[str, Path], writes: str, study: str) -> Iterator[None]:
    """Make the output directory of a sweep, calibration or sensitivity study as `multilayer
    run` makes its own (named if it cannot be: ``-o`` a file was "File exists"), and hold its
    lock (:mod:`multilayer.app.lock`) while the study runs: two studies into one directory
    both ran every member, each member's second run refused as another run's, and a stop of
    one stopped the other's members (the directory's stop file).  The directories it made
    go again, if empty, when the study is refused (an :class:`InputError`), and so they do
    when the file it writes, ``writes`` (or its lock or stop request), is a file the
    ``study`` (sweep, calibration, sensitivity study) reads, ``reads`` (what it is, by its
    path; a sweep whose base scenario was ``DIR/summary.csv`` wrote its summary over it), or
    a file it reads lies in a member's directory (:func:`in_a_member`)."""
    from multilayer.app.lock import LOCK_FILE, locked
    from multilayer.app.runner import not_an_input, output_directory
    from multilayer.app.stopping import StopFile
    from multilayer.errors import InputError, warn

    created = output_directory(outdir)
    try:
        written = (writes, LOCK_FILE, StopFile.NAME)
        for name in written:
            not_an_input(outdir / name, reads, written, f"the {study}", f"the {study}")
        in_a_member(outdir, reads, study)
        with locked(outdir, warn):  # a lock taken over: the warning names the directory
            yield
    except InputError:
        for made in created:
            with contextlib.suppress(OSError):  # not empty: the study wrote there
                made.rmdir()
        raise


def base_reads(base: Path, fixed: dict[str, Any] | None = None) -> dict[str, Path]:
    """The files the base scenario of a study reads (``bed.file``, ``bed.dem``,
    ``initial.N.file``) with the study's fixed overrides ``fixed``, by what they are, for
    :func:`study_directory`: a bed file ``DIR/summary.csv`` of the base scenario of a sweep
    into ``DIR`` is a file the sweep writes over.  Empty for a base that does not load (each
    member names its own error)."""
    from multilayer.app.sweep import base_member

    member = base_member(base, fixed or {})
    if member is None:
        return {}
    return {f"the file {key} of {base}": path for key, path in member.input_files().items()}


def in_a_member(outdir: Path, reads: dict[str, Path], study: str) -> None:
    """:class:`InputError` if a file the ``study`` reads lies in a member's directory of its
    output directory ``outdir`` (a subdirectory named as a member's,
    :data:`~multilayer.app.sweep.MEMBER_DIRECTORY`, whatever its members): each member runs
    into its own, which it writes and clears (a bed at ``DIR/<member>/member.json`` was
    deleted when that member started)."""
    from multilayer.app.sweep import MEMBER_DIRECTORY
    from multilayer.errors import InputError

    try:
        root = outdir.resolve()
    except (OSError, RuntimeError):
        return
    for what, path in reads.items():
        try:
            inside = path.resolve().relative_to(root)
        except (OSError, RuntimeError, ValueError):  # elsewhere (or a link loop loading named)
            continue
        if len(inside.parts) > 1 and MEMBER_DIRECTORY.fullmatch(inside.parts[0]):
            raise InputError(
                f"{path}: {what}, in the subdirectory {inside.parts[0]} of {outdir}, where a member of the "
                f"{study} runs; accepted: files the {study} reads outside its members' directories "
                "(m<index>-<hash>, e-<hash>)"
            )


def size(text: str) -> float:
    """argparse type: a size in bytes such as ``4G`` or ``500M`` (binary units)."""
    from multilayer.app.resources import parse_size

    try:
        return parse_size(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_budget_arguments(parser: argparse.ArgumentParser) -> None:
    """``--max-memory``, ``--max-output`` and ``--force`` (docs/reliability.md, sizes)."""
    parser.add_argument(
        "--max-memory",
        type=size,
        metavar="SIZE",
        help="refuse a run needing more memory than SIZE, e.g. 4G (default: the memory available now)",
    )
    parser.add_argument(
        "--max-output",
        type=size,
        metavar="SIZE",
        help="refuse a run whose result.nc would exceed SIZE, e.g. 2G (default: the free disk space)",
    )
    parser.add_argument(
        "--max-steps",
        type=positive_int,
        metavar="N",
        help="refuse a run estimated to take more than N time steps, and stop one that gets there "
        "(default 10000000; validate prints the estimate)",
    )
    parser.add_argument(
        "--force", action="store_true", help="run even beyond the memory, output and step budget"
    )


def budget(args: argparse.Namespace):
    """The :class:`~multilayer.app.resources.Budget` of the options of :func:`add_budget_arguments`."""
    from multilayer.app.resources import Budget

    return Budget(args.max_memory, args.max_output, args.force, args.max_steps)


def _utf8_bytes(text: str) -> str | None:
    """``text``, a word of the command line, read as UTF-8 where Python could not: under a
    locale whose encoding is not UTF-8 (``LC_ALL=C`` with ``PYTHONUTF8=0``) each byte
    beyond ASCII is kept as a lone surrogate, and ``é`` typed by the user was refused as
    bytes that are not UTF-8.  None if its bytes are not UTF-8."""
    try:
        return os.fsencode(text).decode("utf-8")
    except UnicodeError:
        return None


def argument_text(text: str) -> str:
    """argparse type: a word of the command line as the user wrote it in UTF-8
    (:func:`_utf8_bytes`); other bytes stay lone surrogates, which the command names."""
    if not any("\udc80" <= c <= "\udcff" for c in text):
        return text  # the locale read every byte
    return _utf8_bytes(text) or text


def directory(text: str) -> Path:
    """argparse type: a directory path whose name netCDF can write (UTF-8; a name holding
    other bytes is a usage error, exit code 2)."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        if _utf8_bytes(text) is not None:  # netCDF is given the name in the locale's encoding
            raise argparse.ArgumentTypeError(
                f"{os.fsencode(text)!r} is a UTF-8 name, which this process's locale (encoding "
                f"{sys.getfilesystemencoding()}) cannot give netCDF; accepted: an ASCII name, or a "
                "UTF-8 locale (LC_ALL=C.UTF-8, or PYTHONUTF8=1)"
            ) from None
        raise argparse.ArgumentTypeError(
            f"{text.encode('utf-8', 'surrogateescape')!r} is not a UTF-8 name (netCDF files cannot be "
            "named by other bytes); accepted: a directory name in UTF-8"
        ) from None
    if not text:  # Path('') is '.': -o "$UNSET" wrote into the working directory
        raise argparse.ArgumentTypeError(
            "an empty path; accepted: a directory path ('.' for the working directory)"
        )
    return Path(text)


RUN_DIRECTORY = "the output directory of `multilayer run`"
"""What ``DIR`` of ``plot`` and ``export`` accepts (a study's directory too for ``plot``)."""


def file_path(text: str) -> str:
    """A YAML file argument, refused when empty: ``Path('')`` is the working directory, and
    ``multilayer run "$UNSET"`` named it (``.: not a regular file``), not the empty path.
    Refused too when it ends in ``/`` or ``/.``: such a path names a directory, never a
    file (the system refuses to open ``s.yaml/``, "Not a directory"), and pathlib drops
    the ending: ``multilayer validate s.yaml/`` read ``s.yaml``."""
    if not text:
        raise argparse.ArgumentTypeError("an empty path; accepted: the path of a YAML file")
    if text.endswith(("/", "/.")):  # the test of directory_ending, without importing pydantic
        from multilayer.scenario.messages import directory_ending

        raise argparse.ArgumentTypeError(
            f"{directory_ending(text)}; accepted: the path of a YAML file, without a '/' at its end"
        )
    return text


def not_a_file(path: Path, accepted: str) -> Path:
    """``path``, the ``DIR`` of ``plot`` or ``export``, unless it is a file: a result file
    given for its directory is refused naming the directory holding it (its figures'
    directory, ``DIR/result.nc/plots``, could not be made, and the error would ask for a
    directory this user can write); nor a directory this user cannot list or enter (its
    permissions, or a umask that leaves them off), named as such: otherwise the first file
    looked for in it (``calibration.nc``) is named, which it may not hold."""
    from multilayer.errors import InputError

    if path.is_file():
        raise InputError(f"{path}: a file, not a directory; accepted: {accepted} (here {path.parent})")
    if path.is_dir() and not os.access(path, os.R_OK | os.X_OK):
        raise InputError(
            f"{path}: a directory this user cannot list or enter (permissions "
            f"{stat.filemode(path.stat().st_mode)}); accepted: {accepted}, readable"
        )
    return path


def add_output_argument(parser: argparse.ArgumentParser, default: str) -> None:
    """``-o DIR``, ``--output DIR``: the output directory (``args.output``, a Path or None);
    ``default`` says where the output goes without it."""
    parser.add_argument(
        "-o", "--output", metavar="DIR", type=directory, help=f"output directory (default: {default})"
    )


def add_set_argument(parser: argparse.ArgumentParser, help: str) -> None:
    """``--set KEY=VALUE`` (repeatable): scenario overrides, the list ``args.overrides``."""
    parser.add_argument(
        "--set",
        dest="overrides",
        metavar="KEY=VALUE",
        type=argument_text,
        action="append",
        default=[],
        help=help,
    )


def add_study_arguments(parser: argparse.ArgumentParser, kind: str) -> None:
    """``CONFIG``, ``-o DIR``, the cluster options and ``-q`` of an ensemble study (``kind``:
    calibration or sensitivity)."""
    parser.add_argument("config", metavar="CONFIG", type=file_path, help=f"{kind} YAML file")
    add_output_argument(parser, "output.directory of the file, else results/<file name>")
    add_cluster_arguments(parser)
    add_resume_argument(parser)
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress lines")


def add_resume_argument(parser: argparse.ArgumentParser) -> None:
    """``--resume`` of an ensemble command (sweep, calibrate, sensitivity)."""
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue the interrupted study in DIR (completed runs are reused, runs stopped "
        "mid-way continue from their checkpoints); DIR must hold its results",
    )


def check_results(
    args: argparse.Namespace, outdir: Path, results: str, copy: tuple[Path, str] | None = None
) -> None:
    """``outdir/results``, the file a study writes at every stop and at its end, must be
    absent or a regular file (a pipe there held the study for ever once its members had run,
    a symbolic link had its target written over, :func:`multilayer.io.disk.writable`), and
    with ``--resume`` it must exist: exit 2 otherwise, before anything runs.  ``copy``:
    the study file and the attribute of ``results`` holding its text as the study ran;
    a resumed study whose file changed since says so (its runs of other parameters were
    run afresh, the earlier ones left beside them, and nothing said why)."""
    from multilayer.errors import InputError, warn
    from multilayer.io.disk import writable

    writable(outdir / results)
    if args.resume and not (outdir / results).is_file():
        raise InputError(
            f"{outdir}: nothing to resume ({results} missing); accepted: the output directory "
            "of an interrupted study of this file, or no --resume to start one"
        )
    if args.resume and copy is not None:
        config, attribute = copy
        earlier = _attribute(outdir / results, attribute)
        if earlier is not None and earlier != config.read_text(encoding="utf-8"):
            warn(
                f"{config} changed since the study in {outdir} ran ({results} holds the file it ran): the "
                "runs the changed file still asks for are reused, the others run afresh"
            )


def _attribute(path: Path, name: str) -> str | None:
    """The text attribute ``name`` of the netCDF file ``path``, or None if it has none or
    cannot be read (the study's own checks of the file then speak)."""
    try:
        import netCDF4

        with netCDF4.Dataset(path) as ds:
            value = ds.getncattr(name) if name in ds.ncattrs() else None
    except (OSError, RuntimeError, ValueError):
        return None
    return value if isinstance(value, str) else None


def resume_command(command: str, config: str, outdir: Path, args: argparse.Namespace) -> str:
    """The command line that continues an interrupted ensemble study into ``outdir``."""
    import shlex

    words = ["multilayer", command, str(config), "-o", str(outdir), "--resume"]
    if args.scheduler is not None:
        words += ["--scheduler", args.scheduler]
    elif args.workers is not None:
        words += ["--workers", str(args.workers)]
    return shlex.join(words)


def report_stop(exc: Any, done: str | None, command: str, config: str, outdir: Path, args: Any) -> None:
    """Say on stderr how the study stopped (``exc``, a :class:`~multilayer.errors.Interrupted`),
    what it kept (``done``, the rest of that line; None if nothing), the members that
    did not stop (``exc.running``: in a plugin's code that never returns, on worker
    threads) and how to resume; the command line then says no more (``exc.said``)."""
    from multilayer.errors import printable, to_stderr, warn

    to_stderr(f"multilayer: {printable(str(exc))}{done or ''}")
    running = getattr(exc, "running", [])
    if running:
        warn(
            f"member(s) {', '.join(running)} did not stop (in a plugin's code that never returns?): the "
            f"worker threads of {args.scheduler} run them on until the workers are restarted (Dask "
            "cannot stop a thread), their directories locked until then"
        )
    resume = resume_command(command, config, outdir, args)
    to_stderr(printable(f"multilayer: resume with: {resume}"))
    exc.said = True
