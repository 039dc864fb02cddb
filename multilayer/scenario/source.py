"""The YAML text of a scenario (or sweep, calibration, sensitivity) file: parsing with
the line of every key, and writing values back as the loader reads them.

The loader is PyYAML's safe loader on libyaml (its C parser: about ten times faster than
PyYAML's own, a text of 8 Mi characters read in seconds rather than minutes) with the YAML
1.2 number rules (``1e-3`` is a float);
:func:`read_yaml` returns the data and the 1-based line of every key path, which the
messages of :mod:`multilayer.scenario.messages` quote.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any

import yaml

from multilayer.errors import InputError
from multilayer.scenario import limits
from multilayer.scenario.files import read_text
from multilayer.scenario.messages import KeyPath, directory_ending, dotted, shown

_INT, _FLOAT = "tag:yaml.org,2002:int", "tag:yaml.org,2002:float"


try:  # libyaml's parser and emitter, with PyYAML's safe constructors and representers
    from yaml import CSafeDumper as SafeDumper
    from yaml import CSafeLoader as _SafeLoader
except ImportError:  # PyYAML built without libyaml: its own, about ten (four) times slower
    from yaml import SafeDumper  # type: ignore[assignment]
    from yaml import SafeLoader as _SafeLoader  # type: ignore[assignment]


class SafeLoader(_SafeLoader):
    """PyYAML's safe loader (on libyaml) where a value its explicit tag's constructor cannot
    read (``!!float abc``, ``!!int 1e5``, ``!!bool maybe``, ``!!timestamp 2001-13-45``) is
    malformed YAML at its place, a :class:`yaml.constructor.ConstructorError` as an unknown
    tag is: PyYAML's constructors raise ``ValueError`` or ``KeyError`` for them."""

    def construct_object(self, node: yaml.Node, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep)
        except (ValueError, KeyError, TypeError, OverflowError) as exc:
            raise yaml.constructor.ConstructorError(
                None, None, f"{node.tag} cannot read {shown(node.value)} ({exc})", node.start_mark
            ) from None


def safe_load(text: str) -> Any:
    """``yaml.safe_load(text)`` by :class:`SafeLoader`: a malformed text raises a
    :class:`yaml.YAMLError`, whatever its tags, and so does a text beyond the bounds of
    :func:`~multilayer.scenario.limits.check_yaml` (a result's or checkpoint's scenario, numba's
    configuration file): an alias inside its own anchor in the scenarios of a checkpoint and
    its result was a ``RecursionError`` of ``--resume``, which compares them key by key, and
    the billion laughs there held it for minutes."""
    try:
        limits.check_yaml(text, "the YAML text", SafeLoader)
    except InputError as exc:
        raise yaml.YAMLError(str(exc).removeprefix("the YAML text").lstrip(": ")) from None
    return yaml.load(text, Loader=SafeLoader)


class Loader(SafeLoader):
    """SafeLoader reading numbers by the YAML 1.2 core schema: ``1e-3`` and ``2E5`` are
    floats, ``010`` is ten (YAML 1.1, PyYAML's rule, read eight), and ``1:20`` or
    ``0_3`` are text, refused where a number is expected (YAML 1.1 read 80 and 3)."""

    yaml_implicit_resolvers = {
        first: [(tag, rule) for tag, rule in resolvers if tag not in (_INT, _FLOAT)]
        for first, resolvers in _SafeLoader.yaml_implicit_resolvers.items()
    }


def _integer(loader: yaml.SafeLoader, node: yaml.ScalarNode) -> int:
    """An integer of the YAML 1.2 core schema: decimal, ``0o`` octal or ``0x`` hexadecimal.
    A decimal one of more digits than Python converts (``sys.get_int_max_str_digits``,
    4300) is refused saying so (:class:`SafeLoader`): Python's own ``ValueError`` advised a
    call of ``sys.set_int_max_str_digits()``, which no user of the command line can make."""
    text = str(loader.construct_scalar(node))
    sign, digits = (-1, text[1:]) if text[0] == "-" else (1, text.lstrip("+"))
    base = {"0o": 8, "0x": 16}.get(digits[:2], 10)
    limit = sys.get_int_max_str_digits()
    if base == 10 and limit and len(digits.lstrip("0")) > limit:
        raise ValueError(f"{len(digits.lstrip('0'))} digits, more than the {limit} an integer may have")
    return sign * int(digits[2:] if base != 10 else digits, base)


Loader.add_implicit_resolver(
    _INT, re.compile(r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$"), list("-+0123456789")
)
Loader.add_implicit_resolver(
    _FLOAT,
    re.compile(
        r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"
    ),
    list("-+0123456789."),
)
Loader.add_constructor(_INT, _integer)


def line_map(node: yaml.Node, where: str, path: KeyPath = (), lines=None) -> dict[KeyPath, int]:
    """1-based line of every key path in a composed YAML document; rejects duplicate keys."""
    lines = {} if lines is None else lines
    if isinstance(node, yaml.MappingNode):
        for key_node, value_node in node.value:
            if not isinstance(key_node, yaml.ScalarNode):  # a list or mapping as a key: refused
                continue  # when the data is constructed ("found unhashable key", its line)
            child = (*path, key_node.value)
            line = key_node.start_mark.line + 1
            if child in lines:
                raise InputError(
                    f"{where}: {dotted(child)} (line {line}): duplicate key; "
                    f"accepted: each key once (first at line {lines[child]})"
                )
            lines[child] = line
            line_map(value_node, where, child, lines)
    elif isinstance(node, yaml.SequenceNode):
        for index, item in enumerate(node.value):
            lines[(*path, index)] = item.start_mark.line + 1
            line_map(item, where, (*path, index), lines)
    return lines


def parse_yaml(text: str, where: str) -> tuple[Any, dict[KeyPath, int]]:
    """The data of a YAML text and :func:`line_map`; :class:`InputError` naming ``where``
    and the line if it is malformed."""
    limits.check_line_breaks(text, where)
    limits.check_yaml(text, where, Loader)
    loader = Loader(text)  # one parse: the data is constructed from the node the lines are read from
    try:
        node = loader.get_single_node()
        lines = {} if node is None else line_map(node, where)  # before the merge keys are flattened into it
        data = None if node is None else loader.construct_document(node)
    except yaml.reader.ReaderError as exc:  # a character YAML does not take: its place, one line
        start = text.rfind("\n", 0, exc.position) + 1
        line = f" (line {text.count(chr(10), 0, exc.position) + 1}, column {exc.position - start + 1})"
        code = exc.character if isinstance(exc.character, int) else ord(exc.character)
        problem = f"the character U+{code:04X} ({exc.reason})"
        raise InputError(
            f"{where}{line}: malformed YAML: {problem}; accepted: a YAML mapping of scenario keys"
        ) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise InputError(
            f"{where}{line}: malformed YAML: {problem}; accepted: a YAML mapping of scenario keys"
        ) from None
    finally:
        loader.dispose()
    return data, lines


def read_yaml(path: str | Path, kind: str = "scenario") -> tuple[Any, dict[KeyPath, int]]:
    """The parsed YAML of ``path`` and the line of every key path; ``InputError`` if the
    file is missing, unreadable or malformed (``kind`` names the expected file)."""
    if isinstance(path, str) and (why := directory_ending(path)):  # pathlib drops the ending
        raise InputError(f"{why}; accepted: a path to a {kind} YAML file, without a '/' at its end")
    path = Path(path)
    text = read_text(path, f"a path to a {kind} YAML file", "a readable UTF-8 YAML file")
    return parse_yaml(text, str(path))


def dump(data: Any) -> str:
    """``data`` as ``yaml.safe_dump(data, sort_keys=False)`` writes it, by libyaml's emitter
    where PyYAML has it."""
    return yaml.dump(data, Dumper=SafeDumper, sort_keys=False)


class Dumper(yaml.SafeDumper):
    """SafeDumper that quotes every string the scenario loader would read as another type
    (such as ``1e-5``, a float there)."""

    yaml_implicit_resolvers = Loader.yaml_implicit_resolvers


def format_value(value: Any) -> str:
    """YAML text of ``value`` that reads back to the same value, as ``--set`` parses it."""
    text = yaml.dump(value, Dumper=Dumper, default_flow_style=True, width=2**31)
    return text.removesuffix("...\n").strip()
