"""The messages of invalid input: one per problem, ``<file>: <key.path> (line N): <what is
wrong>; accepted: <...>``.

A schema field carries the "accepted" part of its messages as its description
(:func:`field`); a validator reports a problem of a sub-key with :func:`invalid`; and
:func:`describe` turns one pydantic error into the key path, what is wrong and what is
accepted, which the loader prefixes with the file and the line.
"""

from __future__ import annotations

import os
import pwd
import typing
from collections.abc import Mapping, Sequence
from typing import Any

from pydantic import BaseModel, ConfigDict, Field
from pydantic_core import PydanticCustomError

from multilayer.errors import shortened, shown

KeyPath = tuple[str | int, ...]
"""A key path in a YAML document: mapping keys and list indices."""


def dotted(path: Sequence[str | int]) -> str:
    """``domain.cells``: a key path as messages write it; a key that is not printable ASCII
    quoted with its escapes (``'\\x1b[2J'``, ``'mu_\\u0455'``): a key of the file is printed
    as the file wrote it, and an escape sequence of the terminal in it acted on the terminal
    (cleared it, set its title), and a letter of another script that looks like ours (a
    Cyrillic s in ``mu_s``) was "unknown" beside the very name it showed; an empty key
    ``''`` was "(top level)"; a key longer than 60 characters is :func:`shortened`."""
    plain = (str(p) if str(p) and str(p).isascii() and str(p).isprintable() else ascii(p) for p in path)
    return ".".join(map(shortened, plain)) or "(top level)"


def invalid(message: str, accepted: str, key: str = "") -> PydanticCustomError:
    """A validation error at sub-key ``key`` of the model being validated."""
    return PydanticCustomError(
        "scenario", "{message}", {"message": message, "accepted": accepted, "key": key}
    )


def directory_path(value: Any) -> Any:
    """``output.directory`` of a scenario or a study as given, with a leading ``~`` or
    ``~user`` read as that home directory, as a shell reads it (``~/runs`` made a directory
    named ``~`` in the working directory), unless it holds the NUL character (a YAML
    ``"\\0"``), which no system call takes: the run or the study stopped with Python's
    ``ValueError`` and a traceback."""
    if value is not None and "\0" in str(value):
        raise invalid(f"{str(value)!r} holds the NUL character", "a directory path without it")
    if value == "":  # Path('') is '.': the run wrote into the working directory
        raise invalid("an empty path", "a directory path ('.' for the working directory)")
    if value is not None and str(value).startswith("~"):
        problem = unknown_home(str(value))
        if problem is not None:
            raise invalid(problem, HOME_ACCEPTED)
        return type(value)(os.path.expanduser(str(value)))  # a Path stays a Path
    return value


def file_name(value: Any) -> Any:
    """A file's name as given (a YAML key, an argument), refused when it ends in ``/`` or
    ``/.``: such a name is a directory's, never a file's (the system opens no ``s.yaml/``,
    "Not a directory"), and pathlib drops the ending, so that ``Path("s.yaml/")`` read the
    file ``s.yaml``."""
    if isinstance(value, str) and (why := directory_ending(value)):
        raise invalid(why, "the path of a file, without a '/' at its end")
    return value


def directory_ending(name: str) -> str | None:
    """Why ``name`` names no file, in words, when it ends in ``/`` or ``/.`` (which pathlib
    drops); None for any other name."""
    if not name.endswith(("/", "/.")):
        return None
    return f"{name}: a path ending in '{name[name.rindex('/') :]}', which names a directory, never a file"


HOME_ACCEPTED = "a directory path whose leading ~ is a home directory, or no ~"
"""What a directory path accepts where :func:`unknown_home` finds a problem."""


def unknown_home(path: str) -> str | None:
    """What is wrong with the home directory a leading ``~`` or ``~user`` of ``path`` names,
    or None (also for a path without a leading ``~``): a user the system does not know
    (``os.path.expanduser`` leaves ``~nosuchuser/x`` as it is, a directory named
    ``~nosuchuser`` in the working directory, and ``Path``'s raises ``RuntimeError``), or a
    ``HOME`` that is empty (``~/runs`` read as ``/runs``, in the root directory) or relative
    (read from the working directory)."""
    if not path.startswith("~"):
        return None
    head = path.split(os.sep, 1)[0]
    if head == "~":
        if "HOME" not in os.environ:
            try:
                pwd.getpwuid(os.getuid())
            except KeyError:
                user = os.getuid()
                return f"{shown(path)}: the home directory is not known (no HOME, no user of id {user})"
            return None
        home = os.environ["HOME"]
        if not os.path.isabs(home):
            return f"{shown(path)}: HOME is {shown(home)}, not an absolute path"
        return None
    try:
        pwd.getpwnam(head[1:])
    except KeyError:
        return f"{shown(path)}: no user {shown(head[1:])} on this system"
    return None


def check_kind(model: BaseModel, kind: str, table: dict[str, tuple[tuple[str, ...], ...]]) -> None:
    """Per-kind keys: ``table[value] = (required, optional)`` for ``model.<kind> == value``."""
    value = getattr(model, kind)
    required, optional = table[value]
    accepted = ", ".join((kind, *required, *optional))
    for key in required:
        if getattr(model, key) is None:
            raise invalid(f"{kind} {value} requires {key}", accepted, key)
    extra = sorted(model.model_fields_set - {kind, *required, *optional})
    if extra:
        raise invalid(f"not a key of {kind} {value}", accepted, extra[0])


def ordered(x_min: float, x_max: float) -> None:
    """An interval [x_min, x_max] must have x_max > x_min."""
    if not x_min < x_max:
        raise invalid(f"x_max = {x_max} is not > x_min = {x_min}", f"a number > x_min = {x_min}", "x_max")


def increasing(points: list[list[float]], key: str, what: str) -> None:
    """A profile ``[[x, what], ...]`` (sub-key ``key``) needs 2 points or more with increasing x."""
    xs = [x for x, _ in points]
    if len(points) < 2 or any(b <= a for a, b in zip(xs, xs[1:])):
        raise invalid(
            f"{what} needs at least 2 points with strictly increasing x",
            f"a list [[x, {what}], ...] with increasing x",
            key,
        )


class StrictModel(BaseModel):
    """A mapping of an input file: no unknown key, no type coercion, no inf or nan.

    An infinite or NaN value assigned after validation is written as it is (``.nan`` in
    YAML), not as null: a scenario is validated again from what it writes, and a law's
    parameter or a base zone's (typed ``Any``) written as null would be read as not given:
    ``rheology.mu_start = nan`` assigned from Python would run without ``mu_start``."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, ser_json_inf_nan="constants")


def field(default: Any = ..., accepted: str = "", **constraints: Any) -> Any:
    """A field whose ``description`` is the 'accepted' part of error messages."""
    return Field(default, description=accepted, **constraints)


def accepted(loc: Sequence[str | int], last_is_key: bool, root: type[BaseModel]) -> str:
    """The 'accepted' text of the field at ``loc`` (or the keys of the model holding it)
    in the model ``root``."""
    model: type[BaseModel] | None = root
    info = None
    mapping = False
    for part in loc:
        if isinstance(part, int) or mapping:  # a list index or a key of a mapping field
            mapping = False
            continue
        if model is None or part not in model.model_fields:
            return ""
        info = model.model_fields[part]
        mapping = typing.get_origin(info.annotation) is dict
        model = model_in(info.annotation)
    if last_is_key:
        return ", ".join(model.model_fields) if model else ""
    return info.description or "" if info else ""


def model_in(annotation: Any) -> type[BaseModel] | None:
    """The pydantic model inside ``annotation`` (through Optional, list, Annotated)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = model_in(arg)
        if found is not None:
            return found
    return None


def describe(error: Mapping[str, Any], root: type[BaseModel]) -> tuple[KeyPath, str, str]:
    """(key path, what is wrong, what is accepted) of one pydantic error in the model ``root``."""
    loc, kind, ctx = tuple(error["loc"]), error["type"], error.get("ctx") or {}
    if kind == "scenario":
        key = tuple(int(k) if k.isdigit() else k for k in ctx["key"].split(".") if k)
        return loc + key, ctx["message"], ctx["accepted"]
    if kind == "extra_forbidden":
        return loc, "unknown key", accepted(loc[:-1], last_is_key=True, root=root)
    if kind == "invalid_key":  # a key YAML reads as a number, a boolean or null (pydantic shows True as 1)
        where = loc[:-1]
        return (
            where,
            f"key {shown(error.get('input'))} is not text",
            accepted(where, last_is_key=True, root=root),
        )
    if loc[-1:] == ("[key]",):  # a key of a mapping of parameters (a law's) that is not text
        where = loc[:-3] if loc[-3:-2] == ("params",) else loc[:-2]
        return (
            where,
            f"key {shown(error.get('input'))} is not text",
            "name and the parameters of the law, as text (see `multilayer plugins`)"
            if loc[-3:-2] == ("params",)
            else "keys that are text",
        )
    if kind == "missing":
        return loc, "required key is missing", accepted(loc, last_is_key=False, root=root)
    got = shown(error.get("input"))
    what = (
        f"got {got}"
        if kind == "literal_error"
        else f"expected a mapping (got {got})"
        if kind in ("model_type", "model_attributes_type")
        else f"{error['msg']} (got {got})"
    )
    return loc, what, accepted(loc, last_is_key=False, root=root)
