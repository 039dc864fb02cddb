"""The output-directory lock: one run at a time writes into a directory.

``DIR/run.lock`` is created exclusively (``O_CREAT | O_EXCL``) and holds the pid, host
and start time of the run that owns the directory; it is removed when the run ends,
however it ends.  A second run into the directory is refused with an
:class:`InputError` naming the holder.  A lock whose holder is gone (a process of this
host that no longer exists, e.g. after ``kill -9``) is stale: it is taken over and the
take-over is reported through ``notice``.  A lock from another host cannot be checked
and is honoured; the message says how to remove it.

Runs started at once look at the lock and take it one after the other, under an advisory
lock (``flock``) of the directory itself: without it, one read the lock another had just
created, still empty, as unreadable, or two took over one stale lock, the second deleting
the first's new lock, and both wrote into the directory.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import os
import socket
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from multilayer.errors import InputError, reason
from multilayer.io import disk

try:
    import fcntl
except ImportError:  # not on POSIX: no guard (runs started at once may both take the lock)
    fcntl = None  # type: ignore[assignment]

LOCK_FILE = "run.lock"
GUARD_WAIT_S = 10.0
"""How long a run waits for another to finish looking at the lock before it gives up."""


def _alive(pid: int) -> bool:
    """True if a process ``pid`` exists on this host."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    return True


def _holder(path: Path) -> dict | None:
    """The holder written in the lock ``path``; None if it cannot be read or is not a
    lock (a mapping whose ``pid`` is a process id: an integer from 1 to 2^31 - 1, as
    ``os.kill`` would read 0, -1 or a larger number as another process group or fail).
    Only a regular file is read: a named pipe there held the command for ever, waiting
    for a writer."""
    if not path.is_file():
        return None
    try:
        with open(path, "rb") as stream:
            data = json.loads(stream.read(4096).decode("utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    pid = data.get("pid") if isinstance(data, dict) else None
    return data if type(pid) is int and 0 < pid < 2**31 else None


def _describe(holder: dict | None) -> str:
    if holder is None:
        return "an unreadable lock"
    return f"pid {holder.get('pid')} on host {holder.get('host')}, started {holder.get('started')}"


@contextmanager
def _guarded(directory: Path) -> Iterator[None]:
    """Hold the advisory lock of ``directory`` itself while the block looks at and takes its
    lock file (module docstring); a directory that cannot be opened (no read permission)
    or locked (a file system without ``flock``) is used without it."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        fd = -1
    try:
        deadline = time.monotonic() + GUARD_WAIT_S
        while fd >= 0 and fcntl is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() > deadline:
                    raise InputError(
                        f"{directory}: another process has been taking this directory's lock for "
                        f"{GUARD_WAIT_S:g} s; accepted: a directory no other run is using"
                    ) from None
                time.sleep(0.01)
            except OSError:
                break
        yield
    finally:
        if fd >= 0:
            os.close(fd)  # releases the flock


@contextmanager
def locked(directory: Path, notice: Callable[[str], None] = lambda message: None) -> Iterator[None]:
    """Hold the lock of ``directory`` (which must exist) for the duration of the block."""
    with _guarded(directory):
        me = _take(directory, notice)
    path = directory / LOCK_FILE
    try:
        yield
    finally:
        # a directory made read-only during the run keeps its lock, stale once this
        # process ends (the next run takes it over): how the run ended is the message
        if _holder(path) == me:
            with contextlib.suppress(OSError):
                path.unlink(missing_ok=True)


def _take(directory: Path, notice: Callable[[str], None]) -> dict:
    """Create the lock file of ``directory`` for this process (under :func:`_guarded`);
    returns what it holds."""
    path = directory / LOCK_FILE
    me = {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "started": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
    }
    for _attempt in range(3):
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            holder = _holder(path)
            here = holder is not None and holder.get("host") == me["host"]
            if holder is not None and here and holder.get("pid") == me["pid"]:
                raise InputError(
                    f"{directory}: this process already runs into this directory; "
                    "accepted: a different output directory per run"
                ) from None
            if holder is None or (here and not _alive(holder["pid"])):
                notice(f"{path}: taking over a stale lock ({_describe(holder)}: no such process)")
                try:
                    path.unlink(missing_ok=True)
                except OSError as exc:  # a directory, or a directory we may not change
                    raise InputError(
                        f"{path}: a stale lock that cannot be removed ({reason(exc)}); accepted: remove it"
                    ) from None
                continue
            raise InputError(
                f"{directory}: another run is writing into this directory ({_describe(holder)}); "
                f"accepted: a different output directory (-o DIR), or wait for that run to end "
                f"(if it no longer exists, delete {path})"
            ) from None
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as stream:
                json.dump(me, stream)
        except OSError as exc:  # no room for it: no lock left behind, empty, for the next run to blame
            path.unlink(missing_ok=True)
            why = disk.room(path)[1] if disk.full_disk_reason(exc) else reason(exc)
            raise InputError(f"{path}: the lock cannot be written ({why}); accepted: room for it") from None
        return me
    raise InputError(f"{path}: could not take the lock; accepted: a directory no other run is using")
