"""Reading an input file named by the user: a missing or unreadable file is an InputError."""

from __future__ import annotations

from pathlib import Path

from multilayer.errors import InputError


def read_text(path: Path, expected: str, readable: str) -> str:
    """The UTF-8 text of ``path``; :class:`InputError` naming it, with ``expected`` as what
    is accepted if it is missing and ``readable`` if it cannot be read or decoded."""
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{path}: file not found; accepted: {expected}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read the file ({exc}); accepted: {readable}") from None
