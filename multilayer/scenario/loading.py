"""Loading a scenario: a YAML file or a mapping, ``--set`` overrides applied, validated
into a :class:`~multilayer.scenario.schema.Scenario`; every problem of the input is
reported at once as one :class:`~multilayer.errors.InputError` (docs/scenarios.md)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError
from pydantic_core import PydanticSerializationError

from multilayer.errors import InputError, shortened
from multilayer.scenario import limits
from multilayer.scenario.files import files_directory, names_a_stream, relative_to, why_not_a_file
from multilayer.scenario.messages import KeyPath, describe, directory_ending, dotted
from multilayer.scenario.overrides import apply_overrides
from multilayer.scenario.schema import Scenario
from multilayer.scenario.source import read_yaml


def from_dict(
    data: Any,
    *,
    source: str | Path | None = None,
    overrides: Sequence[str] = (),
    lines: dict[KeyPath, int] | None = None,
) -> Scenario:
    """Validate a scenario mapping (as read from YAML); :class:`InputError` if invalid."""
    where = str(source) if source is not None else "<scenario>"
    if not isinstance(data, dict):
        raise InputError(
            f"{where}: (top level): got {type(data).__name__}; "
            "accepted: a mapping of scenario keys (name, domain, material, ...)"
        )
    data, set_paths = apply_overrides(data, overrides)
    lines = lines or {}
    try:
        directory = files_directory(Path(source)) if source is not None else None
        scenario = Scenario.model_validate(data, context={"directory": directory})
    except ValidationError as exc:
        messages = []
        for error in exc.errors():
            loc, what, accepted = describe(error, Scenario)
            if any(loc[: len(p)] == p or p[: len(loc)] == loc for p in set_paths):
                place = " (from --set)"
            else:
                known = [loc[:n] for n in range(len(loc), 0, -1) if loc[:n] in lines]
                place = f" (line {lines[known[0]]})" if known else ""
            tail = f"; accepted: {accepted}" if accepted else ""
            messages.append(f"{where}: {dotted(loc)}{place}: {what}{tail}")
        raise InputError("\n".join(messages)) from None
    scenario._source = Path(source) if source is not None else None
    scenario.validated()
    return scenario


def validated_again(scenario: Scenario, overrides: Sequence[str] = ()) -> Scenario:
    """``scenario`` validated again, from its keys as they are now (assigned since its
    validation or not), with ``overrides`` applied: a new :class:`Scenario`.  A text
    assigned that is no Unicode (:func:`~multilayer.scenario.limits.check_text`) is named
    first: YAML cannot write it."""
    where = str(scenario.source or "<scenario>")
    try:
        plain = limits.plain_data(scenario.model_dump(warnings=False), where)
        data = yaml.safe_load(scenario.resolved_yaml())
    except (PydanticSerializationError, ValueError, TypeError, OverflowError) as exc:
        keys = ", ".join(dotted(path) for path in scenario.assigned_keys()) or "(a key)"
        raise InputError(
            f"{where}: {keys}: assigned since the scenario was validated, a value the scenario cannot "
            f"hold ({type(exc).__name__}: {shortened(str(exc))}); accepted: {limits.PLAIN_VALUES}, as "
            "the file takes them"
        ) from None
    for path in scenario.assigned_nulls():  # refused where the file refuses a null
        node = data
        for part in path[:-1]:
            node = node[part]
        node[path[-1]] = None
    return from_dict(_booleans_kept(data, plain), source=scenario.source, overrides=overrides)


def _booleans_kept(data: Any, plain: Any) -> Any:
    """``data`` (the scenario's YAML read back) with a boolean of ``plain`` (its keys as
    assigned, :func:`~multilayer.scenario.limits.plain_data`) put back where the YAML
    holds a number: pydantic writes ``True`` assigned to a number as 1 (``scenario.slope_deg
    = True`` ran on a slope of 1 degree, ``time.end = True`` to 1 s), which the file and
    ``--set`` refuse as a boolean."""
    if isinstance(plain, bool) and isinstance(data, int | float) and not isinstance(data, bool):
        return plain
    if isinstance(data, dict) and isinstance(plain, dict):
        return {key: _booleans_kept(value, plain.get(key)) for key, value in data.items()}
    if isinstance(data, list) and isinstance(plain, list) and len(data) == len(plain):
        return [_booleans_kept(value, other) for value, other in zip(data, plain, strict=True)]
    return data


def load(path: str | Path, overrides: Sequence[str] = ()) -> Scenario:
    """Read, override and validate a scenario file."""
    data, lines = read_yaml(path)
    return from_dict(data, source=Path(path), overrides=overrides, lines=lines)


BASE_ACCEPTED = "the path of a scenario file, relative to this file"
"""What the ``base`` of a sweep or study file accepts."""


def load_base(study: Path, base: str, where: str, what: str, overrides: Sequence[str] = ()) -> Path:
    """The scenario file ``base`` of the sweep or study file ``study`` (relative to it, or
    to the working directory where ``study`` is a stream: :func:`files_directory`), loaded
    with ``overrides``; one :class:`InputError` beginning with ``where`` (the file and the
    key) otherwise.  A ``base`` naming the study file itself, or another sweep or
    study file, is said so in one line: loaded as a scenario, it gave one line per key."""
    accepted = (
        BASE_ACCEPTED if not names_a_stream(study) else f"the path of a scenario file, {relative_to(study)}"
    )
    if why := directory_ending(base):
        raise InputError(f"{where}: {why}; accepted: {accepted}")
    path = files_directory(study) / base
    if not path.is_file():  # a directory or a pipe is no scenario file either
        raise InputError(f"{where}: scenario file {path} {why_not_a_file(path)}; accepted: {accepted}")
    if path.samefile(study):
        raise InputError(f"{where}: {path} is this file itself, not a scenario; accepted: {accepted}")
    try:  # read once: the file may change between two reads
        data, lines = read_yaml(path)
        if not (isinstance(data, dict) and "parameters" in data):  # a key of sweeps and studies only
            from_dict(data, source=path, overrides=overrides, lines=lines)
            return path
    except InputError as exc:
        raise InputError(f"{where}: {what} is invalid:\n{exc}") from None
    raise InputError(
        f"{where}: {path} is a sweep or study file (it has the key parameters), not a scenario; "
        f"accepted: {accepted}"
    )
