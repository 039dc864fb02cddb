"""Stopping an ensemble (sweep, calibration, sensitivity study) on Ctrl-C, SIGTERM or SIGHUP.

The commands that run members on Dask wait for them in the main process.  While
:func:`signals_stop` is active there, the first Ctrl-C (SIGINT), SIGTERM or SIGHUP is a stop
request: :func:`check` raises :class:`~multilayer.errors.Interrupted` at the next check
(the waiting loop :func:`as_completed` checks every :data:`POLL` seconds, the loops over
the members of a batch at every member), the members not finished are cancelled, the
command writes what was computed and prints how to resume, and the CLI exits with 128 +
the signal number (130, 143, 129).  A second signal raises at once.

Signals do not reach the members running on the workers (threads of worker processes,
perhaps on other hosts), and a cancelled Dask task runs on.  So the study also creates a
:class:`StopFile` in the directory of its members, which every member asks for between
its kernel calls (at most every :data:`STOP_FILE_POLL` seconds): it checkpoints and stops
within a fraction of a second, on any worker that shares the file system.  Members
completed before the stop are kept (``member.json``); one stopped mid-run continues from
its checkpoint when the study is resumed.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import Any

from multilayer.app import runner
from multilayer.errors import Interrupted

POLL = 0.1
"""Seconds between two checks of the waiting loop."""

STOP_FILE_POLL = 0.2
"""Seconds between two looks of a running member for the :class:`StopFile`."""

_requested: list[int] = []
"""The signal of the pending stop request, if any (set by the handler)."""


def _name(signum: int) -> str:
    return "Ctrl-C (SIGINT)" if signum == signal.SIGINT else signal.Signals(signum).name


def _handle(signum: int, frame: FrameType | None) -> None:
    if _requested:
        raise Interrupted(f"stopped at once by a second signal ({_name(signum)})", signum)
    _requested.append(signum)


@contextmanager
def signals_stop() -> Iterator[None]:
    """Turn the stop signals of a run (:data:`~multilayer.app.runner.STOP_SIGNALS`) into a
    stop request of the study while active (main thread only; those the process ignores
    stay ignored, :func:`~multilayer.app.runner.handled_by`)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _requested.clear()
    try:
        with runner.handled_by(_handle):  # a signal the process ignores stays ignored
            yield
    finally:
        _requested.clear()


def dask_setup(worker: Any) -> None:
    """Dask preload of the local cluster's worker processes: ignore SIGINT and SIGHUP, and
    print to stderr.

    A Ctrl-C at a terminal reaches every process of the foreground group; a worker would
    die mid-write and its nanny start another.  The process running the study alone acts
    on it, and stops its members through the :class:`StopFile`.  The workers share the
    study's stdout, which carries its summary: a law printing as a member runs wrote its
    lines there (the workers are the study's processes; a cluster of ``--scheduler`` is
    left as it is).
    """
    sys.stdout = sys.stderr
    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGINT, getattr(signal, "SIGHUP", None)):
            if signum is not None:
                signal.signal(signum, signal.SIG_IGN)
    logging.getLogger("distributed.worker").addFilter(_heartbeat_without_traceback)


def _heartbeat_without_traceback(record: logging.LogRecord) -> bool:
    """A local cluster's scheduler lives in the study's process: a worker that cannot reach
    it for its heartbeat logs that in one line, not with the connection's traceback, which
    a stopped study's workers printed on the terminal while the scheduler closed first."""
    if record.getMessage().startswith("Failed to communicate with scheduler during heartbeat"):
        record.exc_info = record.exc_text = None
    return True


CLOSE_GRACE = 1.0
"""Seconds a stopped local cluster is given to close before its worker processes are killed."""


def close_quickly(cluster: Any) -> None:
    """Close a local Dask cluster after a stop, killing its worker processes if it takes
    longer than :data:`CLOSE_GRACE` seconds.

    The members were asked to stop (:class:`StopFile`) and do within a fraction of a second,
    checkpointed, so the workers are soon idle and close; a worker still busy then (say,
    importing the engine, with no run under way) would hold the close for seconds.  The
    ``distributed`` logger is quiet (errors only) while it closes, then as it was.
    """
    pids = [
        nanny.process.process.pid
        for nanny in cluster.workers.values()
        if getattr(getattr(nanny, "process", None), "process", None) is not None
    ]
    logger = logging.getLogger("distributed")  # the host process's: its level is set back
    level = logger.level
    logger.setLevel(logging.ERROR)  # the workers' goodbyes are not news
    try:
        closing = threading.Thread(target=cluster.close, daemon=True)
        closing.start()
        closing.join(CLOSE_GRACE)
        if closing.is_alive():
            for pid in pids:
                with contextlib.suppress(OSError):
                    os.kill(pid, signal.SIGKILL)
            closing.join(CLOSE_GRACE)
    finally:
        logger.setLevel(level)


def check() -> None:
    """Raise :class:`~multilayer.errors.Interrupted` if a stop was requested."""
    if _requested:
        signum = _requested[0]
        raise Interrupted(f"interrupted by {_name(signum)}", signum)


class StopFile:
    """``DIRECTORY/stop-requested``: while it exists, the members running into the
    subdirectories of ``DIRECTORY`` stop.  Calling it answers whether to stop (looking
    at the file at most every :data:`STOP_FILE_POLL` seconds)."""

    NAME = "stop-requested"

    def __init__(self, directory: str | Path) -> None:
        self.path = Path(directory) / self.NAME
        self._next_look = 0.0

    def request(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.path.touch()

    def clear(self) -> None:
        self.path.unlink(missing_ok=True)

    def __call__(self) -> bool:
        now = time.monotonic()
        if now < self._next_look:
            return False
        self._next_look = now + STOP_FILE_POLL
        return self.path.exists()


def as_completed(client: Any, futures: list[Any], members: str | Path) -> Iterator[Any]:
    """The ``futures`` in the order they finish, checking for a stop request every
    :data:`POLL` seconds.  On a stop (or any other exception) the members running into
    the directory ``members`` are asked to stop (:class:`StopFile`) and the unfinished
    futures cancelled before the exception goes on."""
    from dask.distributed import as_completed as completed

    since = time.time() - 1.0  # a second before the futures were submitted, just before
    waiting = completed(futures)
    try:
        while not waiting.is_empty():
            check()
            ready = waiting.next_batch(block=False)
            if not ready:
                time.sleep(POLL)
            yield from ready
    except BaseException as exc:
        unfinished = [f for f in futures if not f.done()]
        if unfinished:
            StopFile(members).request()
            client.cancel(unfinished)
            if isinstance(exc, Interrupted) and getattr(client, "cluster", None) is None:
                exc.running = still_running(Path(members), since)  # type: ignore[attr-defined]
        raise


STOP_GRACE = 2.0
"""Seconds a member of a cluster of ``--scheduler`` is given to stop (it looks for the
:class:`StopFile` every :data:`STOP_FILE_POLL` seconds between its kernel calls)."""


def still_running(members: Path, since: float) -> list[str]:
    """The members (subdirectories of ``members``) whose run, begun after ``since`` (a
    time of ``time.time()``), still holds its lock :data:`STOP_GRACE` seconds from now.

    A cluster of ``--scheduler`` may run members in threads, which Dask cannot stop: one in
    a plugin's code that never returns does not see the :class:`StopFile` and runs on (the
    local cluster's worker processes are killed instead, :func:`close_quickly`)."""
    from multilayer.app.lock import LOCK_FILE

    def held() -> list[str]:
        names = []
        for path in members.glob(f"*/{LOCK_FILE}"):
            with contextlib.suppress(OSError):  # removed meanwhile: that member stopped
                if path.stat().st_mtime >= since:
                    names.append(path.parent.name)
        return sorted(names)

    end = time.monotonic() + STOP_GRACE
    while (running := held()) and time.monotonic() < end:
        time.sleep(POLL)
    return running
