"""What the header of a classic netCDF file declares: its records and the bytes they take.

``result.nc`` is written in the classic 64-bit offset format (CDF-2).  Its header holds
the number of records and, for every variable, its size and the offset of its data
(Unidata, "NetCDF Classic Format Specification", the file format of netCDF-C): from
them follows the length the file must have.  netCDF-C reads the bytes missing from a
truncated file as zeros, without an error, so a reader compares the length of the file
with the length its header declares (:func:`read_layout`, ``Layout.complete_records``).
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from typing import BinaryIO

ABSENT, DIMENSION, VARIABLE, ATTRIBUTE = 0, 0x0A, 0x0B, 0x0C
TYPE_SIZES = {1: 1, 2: 1, 3: 2, 4: 4, 5: 4, 6: 8, 7: 1, 8: 2, 9: 4, 10: 8, 11: 8}
"""Bytes per value of each netCDF type code (byte, char, short, int, float, double and
the CDF-5 unsigned and 64-bit types)."""
STREAMING = 0xFFFFFFFF
"""The record count of a file still being streamed (numrecs not yet written)."""
NUMRECS_OFFSET = 4
"""Offset of the record count in the file (after the four bytes ``CDF`` + version)."""
HEADER_SPACE = 16384
"""Bytes a writer keeps free in the header for the attributes it writes last: netCDF-C
moves every record when the header grows."""
MAX_HEADER = 1 << 30
"""Largest header read (bytes): a longer one is taken as damaged."""


class LayoutError(ValueError):
    """The file is not a classic netCDF file, or its header is damaged."""


@dataclass(frozen=True)
class Layout:
    """Records of a classic netCDF file as its header declares them."""

    version: int
    """1 (classic), 2 (64-bit offset) or 5 (64-bit data)."""
    numrecs: int
    """Records the header counts (``STREAMING`` when unknown)."""
    records_begin: int
    """Offset of the first record (the file length when there is no record variable)."""
    record_size: int
    """Bytes per record (0 without record variables)."""
    fixed_end: int
    """End of the data of the fixed-size variables."""

    def size(self, records: int | None = None) -> int:
        """Bytes a file holding ``records`` records (default: ``numrecs``) takes."""
        count = self.numrecs if records is None else records
        return max(self.fixed_end, self.records_begin + count * self.record_size)

    def complete_records(self, file_size: int) -> int:
        """Records entirely held by a file of ``file_size`` bytes (at most ``numrecs``)."""
        if self.record_size == 0:
            return self.numrecs
        whole = max(file_size - self.records_begin, 0) // self.record_size
        return whole if self.numrecs == STREAMING else min(whole, self.numrecs)


class _Reader:
    """Big-endian reads from the header of ``stream``."""

    def __init__(self, stream: BinaryIO, wide: bool):
        self.stream, self.wide = stream, wide

    def take(self, n: int) -> bytes:
        if n > MAX_HEADER or self.stream.tell() + n > MAX_HEADER:
            raise LayoutError(f"a header longer than {MAX_HEADER} bytes")
        data = self.stream.read(n)
        if len(data) != n:
            raise LayoutError("the header ends before its last entry")
        return data

    def int32(self) -> int:
        return int(struct.unpack(">i", self.take(4))[0])

    def count(self) -> int:
        """A non-negative count (4 bytes, 8 in CDF-5)."""
        value = int(struct.unpack(">q", self.take(8))[0]) if self.wide else self.int32()
        if value < 0:
            raise LayoutError(f"a negative count {value}")
        return value

    def name(self) -> str:
        n = self.count()
        raw = self.take(n)
        self.take(-n % 4)
        return raw.decode("utf-8", "replace")

    def attributes(self) -> None:
        """Skip an attribute list."""
        tag, n = self.int32(), self.count()
        if tag not in (ABSENT, ATTRIBUTE) or (tag == ABSENT and n):
            raise LayoutError(f"an attribute list tagged {tag}")
        for _ in range(n):
            self.name()
            kind = self.int32()
            if kind not in TYPE_SIZES:
                raise LayoutError(f"an attribute of unknown type {kind}")
            length = self.count() * TYPE_SIZES[kind]
            self.take(length + (-length % 4))


def read_layout(path: str | os.PathLike) -> Layout:
    """The layout declared by the header of the classic netCDF file ``path``;
    :class:`LayoutError` if it is not one or its header is damaged."""
    with open(path, "rb") as stream:
        magic = stream.read(4)
        if len(magic) < 4 or magic[:3] != b"CDF" or magic[3] not in (1, 2, 5):
            raise LayoutError("not a classic netCDF file (no CDF signature)")
        version = magic[3]
        read = _Reader(stream, wide=version == 5)
        numrecs = read.count() if version == 5 else int(struct.unpack(">I", read.take(4))[0])
        tag, n = read.int32(), read.count()
        if tag not in (ABSENT, DIMENSION) or (tag == ABSENT and n):
            raise LayoutError(f"a dimension list tagged {tag}")
        lengths = []
        for _ in range(n):
            read.name()
            lengths.append(read.count())
        read.attributes()
        tag, n = read.int32(), read.count()
        if tag not in (ABSENT, VARIABLE) or (tag == ABSENT and n):
            raise LayoutError(f"a variable list tagged {tag}")
        fixed_end, records_begin, record_sizes = 0, None, []
        for _ in range(n):
            read.name()
            dims = [read.count() for _ in range(read.count())]
            if any(d >= len(lengths) for d in dims):
                raise LayoutError("a variable on an undefined dimension")
            read.attributes()
            kind = read.int32()
            if kind not in TYPE_SIZES:
                raise LayoutError(f"a variable of unknown type {kind}")
            read.count()  # vsize: computed below (it saturates for variables beyond 4 GiB)
            begin = int(struct.unpack(">q" if version != 1 else ">i", read.take(8 if version != 1 else 4))[0])
            if begin < 0:
                raise LayoutError(f"a negative data offset {begin}")
            record = bool(dims) and lengths[dims[0]] == 0
            size = TYPE_SIZES[kind]
            for d in dims[1:] if record else dims:
                size *= lengths[d]
            if record:
                records_begin = begin if records_begin is None else min(records_begin, begin)
                record_sizes.append(size)
            else:
                fixed_end = max(fixed_end, begin + size + (-size % 4))
    # each record holds every record variable padded to 4 bytes, but a lone one unpadded
    record_size = sum(s + (-s % 4) for s in record_sizes) if len(record_sizes) > 1 else sum(record_sizes)
    begin = fixed_end if records_begin is None else records_begin
    return Layout(version, numrecs, begin, record_size, fixed_end)


def declared_size(path: str | os.PathLike) -> int | None:
    """The bytes of the classic netCDF file ``path`` its header declares, its records
    included, or None if it is not one or its header does not count its records.  The file
    may hold more: netCDF-C extends it by the rest of its last write's block (zeros), and
    another tool may append to it; netCDF-C reads neither."""
    try:
        layout = read_layout(path)
    except LayoutError:
        return None
    return None if layout.numrecs == STREAMING else layout.size()
