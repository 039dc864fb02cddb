"""The ``multilayer`` command line: one module per subcommand in :mod:`multilayer.app.commands`.

Each subcommand module defines ``HELP`` (one line), ``add_arguments(parser)`` and
``main(args) -> int``.  Exit codes (docs/cli.md): 0 success, 1 failure during a run,
2 invalid input, 128 + signal number when stopped by a signal (130 Ctrl-C, 143 SIGTERM,
129 SIGHUP).
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import importlib
import io
import os
import re
import signal
import sys
import threading
import warnings
from collections.abc import Iterator, Sequence
from typing import Any

from multilayer.app import numba_environment
from multilayer.errors import (
    REMOVED_WORKING_DIRECTORY,
    InputError,
    Interrupted,
    RunError,
    printable,
    reason,
    to_stderr,
    warn,
    working_directory_removed,
)
from multilayer.io.disk import address_space_limit

SUBCOMMANDS = (
    "run", "validate", "compile", "plugins", "sweep", "calibrate", "sensitivity", "check", "plot", "export",
)  # fmt: skip


class _Version(argparse.Action):
    """``--version``: the package and FiPy versions (from the package metadata)."""

    def __init__(self, option_strings: Sequence[str], dest: str, **kwargs: object):
        super().__init__(option_strings, dest, nargs=0, help="show version, commit and FiPy version")

    def __call__(self, parser, namespace, values, option_string=None):
        from multilayer.provenance import fipy_version, provenance

        origin = provenance()
        dirty = ", uncommitted changes" if origin.dirty == "true" else ""
        print(f"multilayer {origin.version} (commit {origin.commit}{dirty}; FiPy {fipy_version()})")
        parser.exit()


class _Parser(argparse.ArgumentParser):
    """argparse's parser, reading a word such as ``-1e308``, ``-.5``, ``-2G`` or ``-inf``
    after an option as that option's value, as it reads ``-1`` and ``-0.5``: it took them
    for options (``--at -1e308``: "expected one argument", where ``--at=-1e308`` worked).
    No option of multilayer looks like a negative number (argparse's condition for it)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-(\.?\d|inf(inity)?$|nan$)", re.IGNORECASE)


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The argument parser with every subcommand of :data:`SUBCOMMANDS`; given the
    ``command`` to run, only its module is imported (the others are bare names, which is
    all parsing needs: a run does not import the modules of ``validate`` or ``plot``)."""
    parser = _Parser(
        prog="multilayer",
        description="Multilayer shallow-flow simulator of dense granular flows. "
        "Run 'multilayer COMMAND --help' for the options of a command.",
        epilog="exit codes: 0 success, 1 failure during a run, 2 invalid input, "
        "130/143/129 stopped by Ctrl-C/SIGTERM/SIGHUP",
    )
    parser.add_argument("--version", action=_Version)
    commands = parser.add_subparsers(title="commands", dest="command", metavar="COMMAND", required=True)
    for name in SUBCOMMANDS:
        if command is not None and name != command:
            commands.add_parser(name)
            continue
        module = importlib.import_module(f"multilayer.app.commands.{name}")
        sub = commands.add_parser(
            name,
            help=module.HELP,
            description=module.__doc__,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        module.add_arguments(sub)
        sub.set_defaults(handler=module.main)
    return parser


def _command(argv: Sequence[str]) -> str | None:
    """The subcommand ``argv`` names (its first word that is not an option), None if it
    names none of :data:`SUBCOMMANDS`."""
    words = [word for word in argv if not word.startswith("-")]
    return words[0] if words and words[0] in SUBCOMMANDS else None


def _warning(message, category, filename, lineno, file=None, line=None) -> None:
    text = str(message)
    if "Traceback (most recent call last):" in text:  # numba quotes one for a variable it cannot read
        lines = text.splitlines()
        text = f"{lines[0]} ({lines[-1]})"
    warn(text, file)


@contextlib.contextmanager
def _signals_stop() -> Iterator[None]:
    """SIGTERM and SIGHUP stop the command as Ctrl-C does (a :class:`KeyboardInterrupt`
    with the signal's exit code) where they would end the process without a word; a run
    handles them itself once it holds its directory (:mod:`multilayer.app.runner`)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum: int, frame: object) -> None:
        raise Interrupted(f"stopped by {signal.Signals(signum).name}", signum)

    names = ("SIGTERM", "SIGHUP")
    numbers = [getattr(signal, name) for name in names if hasattr(signal, name)]
    previous = {n: signal.getsignal(n) for n in numbers}
    for number, handler in previous.items():
        if handler is signal.SIG_DFL:
            signal.signal(number, stop)
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


@contextlib.contextmanager
def _encodable_stdout() -> Iterator[None]:
    """stdout writing a character its encoding lacks as Python escapes it (``\\xe9``), as
    Python's stderr always does: a path beyond ASCII printed on success under
    ``PYTHONIOENCODING=ascii`` (or ``PYTHONUTF8=0`` in the C locale) raised
    ``UnicodeEncodeError`` after the work was done, a traceback and exit 1.  Set back after
    the command, for a caller of :func:`main` in the same process."""
    stream = sys.stdout
    errors = getattr(stream, "errors", None)
    if not isinstance(stream, io.TextIOWrapper) or errors != "strict":
        yield
        return
    stream.reconfigure(errors="backslashreplace")
    try:
        yield
    finally:
        if not stream.closed:
            with contextlib.suppress(OSError):  # a flush of what a full stdout kept (said already)
                stream.reconfigure(errors=errors)


class _StdoutFailed(Exception):
    """A write to stdout failed other than by its reader going away (a full device, a
    closed descriptor): not an :class:`OSError`, so that no command takes it for one of its
    own files."""

    def __init__(self, error: OSError) -> None:
        super().__init__(error.strerror or str(error))


class _GuardedStdout:
    """stdout for the command: a write or flush failing with an :class:`OSError` other than
    :class:`BrokenPipeError` raises :class:`_StdoutFailed`, and a closed stdout (``None``,
    ``>&-``) refuses what is written to it where Python's ``print`` dropped it silently
    (``multilayer plugins >&-`` exited 0 with no listing anywhere; ``> /dev/full`` was
    reported as a directory that cannot be written).  Everything else is the stream's."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream

    def _call(self, method: str, *args: Any) -> Any:
        if self._stream is None:
            raise _StdoutFailed(OSError(errno.EBADF, "it is closed"))
        try:
            return getattr(self._stream, method)(*args)
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise _StdoutFailed(exc) from None

    def write(self, text: str) -> int:
        return self._call("write", text)

    def writelines(self, lines: Any) -> None:
        for line in lines:
            self.write(line)

    def flush(self) -> None:
        if self._stream is not None:
            self._call("flush")

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


@contextlib.contextmanager
def _guarded_stdout() -> Iterator[None]:
    """:class:`_GuardedStdout` as ``sys.stdout`` during the command, set back after it for a
    caller of :func:`main` in the same process."""
    stream = sys.stdout
    sys.stdout = _GuardedStdout(stream)
    try:
        yield
    finally:
        sys.stdout = stream


def _tell(message: str) -> None:
    """``message`` on stderr, if stderr takes it: the exit code says the outcome also when
    stderr is closed or full (``2>/dev/full`` turned an invalid input's 2 into 1)."""
    with contextlib.suppress(OSError):
        to_stderr(printable(message), flush=True)


MIN_ADDRESS_SPACE = 2**30
"""The least address space (bytes, ``ulimit -v``) a command starts with: its libraries map
0.4-0.7 GB as they load on two cores (OpenBLAS reserves buffers per core), and under 0.3 GB
the import of SciPy spun for ever, under 0.4 GB an import or a read was a traceback."""


def _address_space() -> str | None:
    """Why this process's address-space limit (``ulimit -v``) is too small for a command
    (checked before the command's modules are imported), or None."""
    soft = address_space_limit()
    if soft >= MIN_ADDRESS_SPACE:
        return None
    return (
        f"the address space of this process is limited to {soft / 2**20:.0f} MiB (ulimit -v), where its "
        f"libraries (NumPy, SciPy, numba) map about half a GiB as they load; accepted: a limit of at least "
        f"{MIN_ADDRESS_SPACE // 2**20} MiB (ulimit -v {MIN_ADDRESS_SPACE // 1024}), or none"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Parse ``argv`` (default ``sys.argv[1:]``), run the subcommand, return the exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    with _encodable_stdout(), _guarded_stdout():
        if (small := _address_space()) is not None:
            _tell(f"multilayer: error: {small}")
            return 2
        try:
            try:
                args = build_parser(_command(argv)).parse_args(argv)
            except SystemExit:  # --help and --version: what they wrote, flushed here
                sys.stdout.flush()
                raise
        except _StdoutFailed as exc:
            return _stdout_failed(exc)
        shown = warnings.showwarning  # restored: a caller in the same process keeps its own
        warnings.showwarning = _warning
        try:
            with _signals_stop():
                return _dispatch(args)
        finally:
            warnings.showwarning = shown


def _dispatch(args: argparse.Namespace) -> int:
    """The exit code of the subcommand of ``args`` (docs/cli.md)."""
    try:
        numba_environment.check()
        code = args.handler(args)
        sys.stdout.flush()  # here, not at exit, where a full stdout's error would be Python's own
        return code
    except InputError as exc:
        _tell(f"multilayer: error: {exc}")
        return 2
    except RunError as exc:
        _tell(f"multilayer: run failed: {exc}")
        return 1
    except BrokenPipeError:  # the reader of stdout went away (multilayer plugins | head -1)
        _quiet_stdout()
        return 128 + 13  # as if SIGPIPE had ended the process
    except _StdoutFailed as exc:
        return _stdout_failed(exc)
    except OSError as exc:  # a path given on the command line cannot be created or written
        what = f"{exc.filename}: {exc.strerror}" if exc.filename is not None and exc.strerror else str(exc)
        if exc.filename is None and working_directory_removed():  # os.getcwd() names no file
            _tell(f"multilayer: error: {REMOVED_WORKING_DIRECTORY}")
            return 2
        _tell(
            f"multilayer: error: {what}; accepted: a directory this user can write and files in it "
            "that are not read-only"
        )
        return 2
    except MemoryError as exc:  # an address-space limit (ulimit -v) the estimates do not know of
        _tell(
            f"multilayer: error: out of memory ({reason(exc) if str(exc) else 'an allocation failed'}); "
            "accepted: more memory for this process (its address-space limit, ulimit -v, and the "
            "machine's), or a smaller problem"
        )
        return 2
    except KeyboardInterrupt as exc:
        if not getattr(exc, "said", False):  # a run or study says itself how it stopped and what it kept
            _tell(f"multilayer: {str(exc) or 'interrupted'}")
        return getattr(exc, "exit_code", 130)


def _stdout_failed(exc: _StdoutFailed) -> int:
    """Exit code 2 and the message for a stdout that cannot be written."""
    _quiet_stdout()
    _tell(
        f"multilayer: error: cannot write to the standard output ({exc}); accepted: a standard output "
        "that takes the command's lines (a terminal, a pipe, a file on a device with room, /dev/null)"
    )
    return 2


def _quiet_stdout() -> None:
    """stdout's descriptor onto the null device: what its buffer holds is flushed there at
    exit, not into an error of Python's own (exit 120)."""
    stream = getattr(sys.stdout, "_stream", sys.stdout)
    with contextlib.suppress(AttributeError, OSError, ValueError):
        os.dup2(os.open(os.devnull, os.O_WRONLY), stream.fileno())


if __name__ == "__main__":
    sys.exit(main())
