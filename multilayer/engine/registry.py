"""What the registries of the extension points share (basal conditions, lateral
boundaries, pressure models): an entry added under its name, once, and the entries
listed as the messages of invalid input list them (docs/architecture.md)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, TypeVar


class Named(Protocol):
    """An entry of a registry."""

    @property
    def name(self) -> str: ...


Entry = TypeVar("Entry", bound=Named)


def add(entries: dict[str, Entry], entry: Entry, kind: str) -> Entry:
    """``entry`` added to ``entries`` under its name (a name registered twice is an error)."""
    if entry.name in entries:
        raise ValueError(f"{kind} {entry.name!r} is already registered")
    entries[entry.name] = entry
    return entry


def listing(texts: Sequence[str]) -> str:
    """``a, b or c``."""
    return texts[0] if len(texts) == 1 else f"{', '.join(texts[:-1])} or {texts[-1]}"
