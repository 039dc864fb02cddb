"""Room left for the files of a run: the free space of the disk and the file size limit.

A run appends to ``result.nc`` and replaces ``checkpoint.npz`` as it goes.  Two limits
can stop a write half-way: the free space of the file system (``ENOSPC``, or ``EDQUOT``
past a quota) and the largest file the process may write (``ulimit -f``,
``RLIMIT_FSIZE``: ``EFBIG``).  Writers ask :func:`room` before each write, so that a full
disk stops the run between two records, and name either limit with :func:`full_disk_reason`
when a write fails anyway (another process filled the disk in between).
"""

from __future__ import annotations

import errno
import math
import os
import shutil
from collections.abc import Callable
from pathlib import Path

from multilayer.errors import InputError

FULL_ERRNOS = frozenset({errno.ENOSPC, errno.EFBIG, errno.EDQUOT})
"""The errors of a write that found no room: disk full, file too large, quota exceeded."""
SLACK = 8192
"""Bytes asked for beyond what a write adds: the blocks of the file system it may start."""
FULL_MESSAGES = ("no space left", "file too large", "disk quota exceeded")
"""How netCDF-C and the C library word them (netCDF4 raises RuntimeError with the text)."""


def free_space(directory: str | os.PathLike) -> float:
    """Free space (bytes) of the file system holding ``directory`` (or its nearest
    existing parent)."""
    path = Path(directory).absolute()
    while not path.exists() and path != path.parent:
        path = path.parent
    return float(shutil.disk_usage(path).free)


def _soft_limit(name: str) -> float:
    """This process's soft resource limit ``resource.<name>`` (bytes), inf if unlimited or
    where the platform has none."""
    try:
        import resource
    except ImportError:  # not on this platform
        return math.inf
    soft, _hard = resource.getrlimit(getattr(resource, name))
    return math.inf if soft == resource.RLIM_INFINITY or soft < 0 else float(soft)


def file_size_limit() -> float:
    """The largest file this process may write (bytes; ``ulimit -f``), inf if unlimited."""
    return _soft_limit("RLIMIT_FSIZE")


def address_space_limit() -> float:
    """The address space this process may map (bytes; ``ulimit -v``), inf if unlimited."""
    return _soft_limit("RLIMIT_AS")


def room(path: str | os.PathLike) -> tuple[float, str]:
    """Bytes that can still be added to the file ``path`` (which may not exist yet) and
    what limits them, in words: the free space of its disk or the file size limit."""
    path = Path(path)
    size = path.stat().st_size if path.exists() else 0
    free = free_space(path.parent)
    limit = file_size_limit()
    if limit - size < free:
        return max(limit - size, 0.0), f"file too large: the file size limit (ulimit -f) is {limit:.0f} bytes"
    return free, f"disk full: {free:.0f} bytes free on the disk holding {path.parent}"


def full_disk_reason(exc: BaseException) -> str | None:
    """``"disk full"`` or ``"file too large"`` if ``exc`` is a write that found no room
    (``OSError`` with ``ENOSPC``/``EDQUOT``/``EFBIG``, or netCDF4's ``RuntimeError`` saying
    so), else None."""
    number = getattr(exc, "errno", None)
    text = str(exc).lower()
    if number == errno.EFBIG or "file too large" in text:
        return "file too large"
    if number in FULL_ERRNOS or any(words in text for words in FULL_MESSAGES):
        return "disk full"
    return None


def writable(path: Path, in_place: bool = False) -> Path:
    """``path``, where a file is about to be written: absent or a regular file.  A pipe
    there would take the write for ever and a device swallow it, a directory refuse it,
    and a symbolic link have its target written over (``out/result.nc`` linking to a file
    elsewhere: the run replaced that file with its result, and ``run.log`` with its log);
    a file written ``in_place`` (not replaced by a rename) must have one name: a hard link
    had the file under its other names written over too.  :class:`InputError` naming it
    otherwise."""
    if path.exists() and not path.is_file():
        raise InputError(
            f"{path}: exists and is not a regular file (a directory, a pipe or a device); accepted: "
            "no file there, or a regular file to replace"
        )
    if path.is_symlink():
        raise InputError(
            f"{path}: a symbolic link (to {os.readlink(path)}), whose target the write would replace; "
            "accepted: no file there, or a regular file to replace"
        )
    if in_place and path.exists() and (names := path.stat().st_nlink) > 1:
        raise InputError(
            f"{path}: a file of {names} names (hard links), which the write would change under the others "
            "too; accepted: no file there, or a regular file of one name (a copy: cp without -l)"
        )
    return path


def writable_directory(path: Path, make: bool = True) -> Path:
    """``path``, a directory a command writes its files into (``plots/``, ``vtk/``, a
    study's ``members/`` and member directories), made if absent and ``make``.  A symbolic
    link there had every file written into its target, wherever it points, as
    :func:`writable` says of a file; a file there is named too (:class:`InputError`; a
    directory that cannot be made raises the ``OSError`` naming it)."""
    accepted = "accepted: no file there (the directory is made), or a directory"
    if path.is_symlink():
        raise InputError(
            f"{path}: a symbolic link (to {os.readlink(path)}), into whose target the files would be "
            f"written; {accepted}"
        )
    if path.exists() and not path.is_dir():
        raise InputError(f"{path}: exists and is not a directory; {accepted}")
    if make:
        path.mkdir(parents=True, exist_ok=True)
    return path


def write_whole(path: Path, write: Callable[[Path], object]) -> Path:
    """``path`` written by ``write`` into a temporary file beside it (of the same suffix: the
    writers read the format from it, :func:`writable`) renamed over it: never a file
    written half-way, and no temporary file left when ``write`` fails.  The temporary file
    is the process's own (its pid in the name): two ``multilayer plot`` of one directory at
    once took each other's, and one stopped naming it as missing.  A write that finds no
    room (a full disk, ``ulimit -f``) is an :class:`InputError` naming ``path`` and the
    limit: the C library's words alone ("File too large") named neither."""
    part = writable(path.with_name(f".{path.stem}.partial.{os.getpid()}{path.suffix}"))
    try:
        write(part)
        os.replace(part, path)
    except OSError as exc:
        if full_disk_reason(exc) is None:
            raise
        raise InputError(
            f"{path}: not written ({room(part)[1]}); accepted: room for it on the disk and under the file "
            "size limit"
        ) from None
    finally:
        part.unlink(missing_ok=True)
    return path


def refuse_other_writers(path: Path) -> None:
    """:class:`InputError` if another process holds ``path`` open for writing, as Linux's
    ``/proc`` shows its open files (elsewhere, and for processes of other users, none is
    seen).  A result file of the classic netCDF format takes no lock (HDF5's locks are for
    netCDF-4 files only): a run resumed into a file another tool held open for writing
    appended its records, and that tool's closing rewrote the header's record count."""
    try:
        target = path.stat()
        pids = [entry for entry in os.listdir("/proc") if entry.isdigit() and int(entry) != os.getpid()]
    except OSError:  # no file yet, or no /proc
        return
    for pid in pids:
        try:
            descriptors = os.listdir(f"/proc/{pid}/fd")
        except OSError:  # gone, or another user's
            continue
        for fd in descriptors:
            link = f"/proc/{pid}/fd/{fd}"
            try:
                if os.readlink(link).rpartition("/")[2] != path.name:  # the cheap test first
                    continue
                opened = os.stat(link)
                if (opened.st_dev, opened.st_ino) != (target.st_dev, target.st_ino):
                    continue
                with open(f"/proc/{pid}/fdinfo/{fd}") as info:
                    flags = next(int(line.split()[1], 8) for line in info if line.startswith("flags:"))
                with open(f"/proc/{pid}/comm") as comm:
                    name = comm.read().strip()
            except (OSError, ValueError, IndexError, StopIteration):  # closed meanwhile
                continue
            if flags & os.O_ACCMODE != os.O_RDONLY:
                raise InputError(
                    f"{path}: open for writing by another process (pid {pid}, {name!r}): a run writing "
                    "into it too would damage it; accepted: a run once that process has closed it, or "
                    "another output directory (-o)"
                )
