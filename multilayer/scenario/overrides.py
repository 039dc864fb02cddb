"""``--set KEY=VALUE`` overrides of a scenario mapping, and the overrides of a mapping of
dotted keys (how sweeps and studies set their parameters)."""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import Any

import yaml

from multilayer.errors import InputError, shortened
from multilayer.scenario import limits
from multilayer.scenario.messages import KeyPath, dotted, shown
from multilayer.scenario.source import Loader, format_value


def member_output(key: str, study: str) -> str | None:
    """Why a member of a sweep or study (``study``: ``"sweep"`` or ``"study"``) may not set
    the dotted key ``key``, or None: its ``output`` is the study's to choose, which writes
    every run into a directory of its own under its output directory, whatever the run's
    scenario says (the key was ignored, silently)."""
    if key != "output" and not key.startswith("output."):
        return None
    return (
        f"a member's output is not its own: the {study} writes every run into a directory of "
        f"its own under its output directory (-o or the {study} file's output.directory), "
        f"whatever its scenario says; accepted: scenario keys that change the run; the "
        f"{study}'s directory as the {study} file's output.directory"
    )


def as_overrides(values: dict[str, Any]) -> list[str]:
    """``KEY=VALUE`` overrides (as :func:`apply_overrides` reads them) of a mapping of
    dotted keys to values."""
    return [f"{key}={format_value(value)}" for key, value in values.items()]


def apply_overrides(data: dict[str, Any], overrides: Sequence[str]) -> tuple[dict, list[KeyPath]]:
    """``data`` with ``"dotted.key=value"`` overrides applied (value read as YAML).

    List entries are addressed by index (``initial.0.thickness``); missing mappings
    along the path are created, so keys unknown to the schema surface in validation.
    ``"dotted.key+=value"`` appends ``value`` to the list at ``dotted.key`` (created if
    missing): ``initial+={shape: layer, thickness: 0.002}``.
    """
    data = copy.deepcopy(data)
    paths: list[KeyPath] = []
    for item in overrides:
        limits.check_text(item, "--set")  # libyaml's parser encodes it: a byte not UTF-8 was a traceback
        key, sep, text = item.partition("=")
        key = key.strip()  # "domain.cells = 200" names domain.cells
        append = key.endswith("+")
        key = key.removesuffix("+").rstrip()
        if not sep or "" in key.split(".") or not key.isprintable():  # an escape sequence: to the terminal
            raise InputError(
                f"--set {shown(item)}: expected KEY=VALUE or KEY+=VALUE; accepted: a dotted key path (no "
                "part empty, printable text) and a YAML value, e.g. domain.cells=200 or initial+={shape: "
                "layer, thickness: 0.002}"
            )
        limits.check_line_breaks(text, f"--set {shortened(key)}")
        limits.check_yaml(text, f"--set {shortened(key)}", Loader)
        try:
            value = yaml.load(text, Loader=Loader)
        except yaml.YAMLError as exc:
            raise InputError(
                f"--set {shortened(key)}: malformed YAML value {shown(text)}; accepted: a YAML "
                f"scalar, list or mapping ({getattr(exc, 'problem', exc)})"
            ) from None
        node: Any = data
        path: KeyPath = ()
        parts = key.split(".")
        part: str | int
        for depth, part in enumerate(parts):
            if isinstance(node, list):
                # one way to write an index: two keys of a study (initial.0.height and
                # initial.00.height) set one value, the later silently, the earlier not varied
                if not (
                    part.isascii() and part.isdigit() and part == str(int(part)) and int(part) < len(node)
                ):
                    raise InputError(
                        f"--set {shortened(key)}: {dotted(path)} has {len(node)} entries; "
                        f"accepted indices: 0..{len(node) - 1} (without leading zeros)"
                    )
                part = int(part)
            elif not isinstance(node, dict):
                raise InputError(
                    f"--set {shortened(key)}: {dotted(path)} is a value, not a mapping; "
                    f"accepted: a key path ending at {dotted(path)}"
                )
            path = (*path, part)
            if depth < len(parts) - 1:
                if isinstance(node, dict) and node.get(part) is None:
                    node[part] = {}
                node = node[part]
            elif not append:
                node[part] = value
            else:
                target = node[int(part)] if isinstance(node, list) else node.setdefault(part, [])
                if not isinstance(target, list):
                    raise InputError(
                        f"--set {shortened(key)}+=...: {dotted(path)} is not a list; "
                        f"accepted: += on a list key (initial, base, expect), = elsewhere"
                    )
                target.append(value)
                path = (*path, len(target) - 1)
        for earlier in paths:  # domain.cells=20 then domain={...}: 20 was lost, the sweep's table said 20
            if earlier[: len(path)] == path:
                raise InputError(
                    f"--set {shortened(key)}: replaces {dotted(earlier)}, set before it, whose value would "
                    "be lost; accepted: each key set once, a key before the keys within it (domain, then "
                    "domain.cells)"
                )
        paths.append(path)
    return data, paths
