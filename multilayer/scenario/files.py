"""Reading an input file named by the user: a missing or unreadable file is an InputError."""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path
from typing import BinaryIO

from multilayer.errors import InputError, reason
from multilayer.scenario.limits import MAX_FILE_BYTES


def read_text(path: Path, expected: str, readable: str) -> str:
    """The UTF-8 text of ``path`` (without a byte order mark); :class:`InputError` naming
    it, with ``expected`` as what is accepted if it is missing and ``readable`` if it
    cannot be read or decoded, is not a regular file (a device or a pipe could be read
    for ever) or is longer than :data:`~multilayer.scenario.limits.MAX_FILE_BYTES`."""
    try:  # opened without waiting for a writer (a pipe), then checked as opened
        descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        if not stat.S_ISREG(os.fstat(descriptor).st_mode):
            os.close(descriptor)
            raise InputError(f"{path}: not a regular file; accepted: {readable}")
        with os.fdopen(descriptor, "rb") as stream:
            data = _head(stream, MAX_FILE_BYTES + 1)
        if len(data) > MAX_FILE_BYTES:
            raise InputError(
                f"{path}: longer than {MAX_FILE_BYTES} bytes; accepted: {readable} of at most that size"
            )
        try:
            return data.decode("utf-8-sig")  # a byte order mark (spreadsheets write one) is no text
        except UnicodeDecodeError as exc:
            raise InputError(f"{path}: {_not_utf8(data, exc.start)}; accepted: {readable}") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise _unread(path, exc, expected, readable) from None


def _unread(path: Path, exc: Exception, expected: str, readable: str) -> InputError:
    """The error for ``path`` that could not be opened or read (``exc``): a symbolic link
    to nothing or in a loop is said to be one (:func:`why_not_a_file`), where the OS says
    "No such file" or "Too many levels of symbolic links" of a name ``ls`` lists."""
    if isinstance(exc, OSError) and path.is_symlink() and not path.exists():
        return InputError(f"{path} {why_not_a_file(path)}; accepted: {expected}")
    if isinstance(exc, FileNotFoundError):
        return InputError(f"{path}: file not found; accepted: {expected}")
    return InputError(f"{path}: cannot read the file ({reason(exc)}); accepted: {readable}")


_DESCRIPTORS = re.compile(r"/proc/(self|thread-self|\d+)(/task/\d+)?/fd")
"""The directory whose entries name a process's open files (``/dev/stdin`` and ``/dev/fd``
are links into it)."""


def names_a_stream(path: Path) -> bool:
    """Whether ``path`` names an open file of this process, not a file of a directory:
    ``/dev/stdin``, ``/dev/fd/3``, ``/proc/self/fd/0`` (through links too)."""
    name = os.path.abspath(path)
    for _ in range(40):  # the links the OS follows at most
        directory = os.path.realpath(os.path.dirname(name))
        if _DESCRIPTORS.fullmatch(directory):
            return True
        name = os.path.join(directory, os.path.basename(name))
        if not os.path.islink(name):
            return False
        name = os.path.join(directory, os.readlink(name))
    return False


def files_directory(path: Path) -> Path:
    """The directory the relative paths a file holds are read from: the file's own, or
    the working directory for a stream (:func:`names_a_stream`), which has none:
    ``multilayer sweep /dev/stdin < studies/a.yaml`` read its ``base`` from ``/dev``, and a
    here-document is a file of the shell's temporary directory."""
    return Path.cwd() if names_a_stream(path) else path.parent


def relative_to(path: Path) -> str:
    """Where the relative paths of the file ``path`` are read from, in words
    (:func:`files_directory`)."""
    if names_a_stream(path):
        return f"relative to the working directory ({path} names a stream, of no directory)"
    return f"relative to {path}"


def why_not_a_file(path: Path) -> str:
    """Why ``path``, which is not a regular file, cannot be read as one, in words: a
    symbolic link to nothing or in a loop was said to be "not found", where ``ls`` lists it."""
    if path.exists():
        return "is not a regular file"
    return "is a symbolic link to nothing or in a loop" if path.is_symlink() else "not found"


def _head(stream: BinaryIO, size: int) -> bytes:
    """The first ``size`` bytes of ``stream`` (fewer at its end), read in blocks: one
    ``read(size)`` sets aside ``size`` bytes first, 64 MiB for a file of 1 kB (a
    MemoryError under an address-space limit, ``ulimit -v``)."""
    blocks, count = [], 0
    while count < size:
        block = stream.read(min(_BLOCK, size - count))
        if not block:
            break
        blocks.append(block)
        count += len(block)
    return b"".join(blocks)


_BLOCK = 2**20

_BYTE_ORDER_MARKS = (
    (b"\xff\xfe\x00\x00", "UTF-32"),
    (b"\x00\x00\xfe\xff", "UTF-32"),
    (b"\xff\xfe", "UTF-16"),
    (b"\xfe\xff", "UTF-16"),
)


def _not_utf8(data: bytes, start: int) -> str:
    """What a text that is not UTF-8 is: UTF-16 or UTF-32 by its byte order mark (an editor's
    "Unicode"), else the first byte that is not UTF-8 and its line."""
    for mark, encoding in _BYTE_ORDER_MARKS:
        if data.startswith(mark):
            return f"{encoding} text (it starts with the byte order mark {mark.hex(' ').upper()}), not UTF-8"
    line = data.count(b"\n", 0, start) + 1
    return f"not UTF-8 text: byte 0x{data[start]:02X} at line {line}"


def check_regular(path: Path, expected: str, readable: str) -> None:
    """:class:`InputError` as :func:`read_text` gives it if ``path`` is missing or not a
    regular file, for a file read by another library (a DEM, read by GDAL, would wait
    for ever on a pipe)."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError) as exc:
        raise _unread(Path(path), exc, expected, readable) from None
    if not stat.S_ISREG(mode):
        raise InputError(f"{path}: not a regular file; accepted: {readable}")
