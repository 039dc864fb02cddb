"""Rheology plugins: the pluggy host of the ``multilayer`` project (docs/plugins.md).

Every distribution (the built-in ``rheologies`` package included) declares an entry
point in the ``multilayer`` group naming a module that implements the hook
``multilayer_register_rheologies(register)``.  Entry points are loaded one at a time,
so a broken plugin is reported (a :class:`PluginWarning`, and ``multilayer plugins``
lists it) without hiding the others.  A rheology's parameters are the keyword
arguments of its constructor; their annotations are the parameter types.
"""

from __future__ import annotations

import _signal  # host_state(): the handlers without signal's enum wrappers
import contextlib
import functools
import importlib.metadata
import inspect
import os
import re
import signal
import sys
import threading
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import pluggy
from pydantic import BaseModel, ConfigDict, create_model

from multilayer.errors import InputError, described, said, shown
from multilayer.plugins.contract import COLUMN_QUANTITIES, Rheology

PROJECT = "multilayer"
"""The pluggy project name, which is also the entry-point group."""

hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)

APPLIES_TO = ("bulk", "walls")
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


class PluginWarning(UserWarning):
    """A plugin could not be loaded, or one of its rheologies was rejected."""


class HookSpecs:
    """Hook specifications of the ``multilayer`` project."""

    @hookspec
    def multilayer_register_rheologies(self, register: Callable[[type[Rheology]], None]) -> None:
        """Register rheology classes by calling ``register(cls)`` once per class."""


class Spec(Protocol):
    """What :func:`instantiate` needs: a rheology name and its keyword arguments."""

    name: str
    params: dict[str, Any]


@dataclass(frozen=True)
class Registered:
    """A rheology class and the entry point that provided it."""

    cls: type[Rheology]
    source: str


@dataclass(frozen=True)
class Broken:
    """An entry point (or one rheology of it) that was skipped, and why."""

    source: str
    error: str


@dataclass(frozen=True)
class Catalogue:
    """Everything the entry points provided: usable rheologies and broken plugins."""

    rheologies: dict[str, Registered]
    broken: tuple[Broken, ...]


def _entry_points() -> list[importlib.metadata.EntryPoint]:
    """Entry points of the group, this distribution's built-ins first, then by name."""

    def key(ep: importlib.metadata.EntryPoint) -> tuple[bool, str, str]:
        dist = ep.dist.name if ep.dist is not None else ""
        return (dist != PROJECT, dist, ep.name)

    return sorted(importlib.metadata.entry_points(group=PROJECT), key=key)


def _source(ep: importlib.metadata.EntryPoint) -> str:
    dist = f"{ep.dist.name} {ep.dist.version}" if ep.dist is not None else "unknown distribution"
    return f"{dist} (entry point {ep.name} = {ep.value})"


def _problem(cls: object) -> str | None:
    """Why ``cls`` cannot be a rheology plugin, or None."""
    if not (isinstance(cls, type) and issubclass(cls, Rheology)):
        return f"{cls!r} is not a subclass of multilayer.Rheology"
    name = getattr(cls, "name", None)
    if not isinstance(name, str) or not _NAME.match(name):
        return f"{cls.__qualname__}.name must be an identifier string, got {name!r}"
    if cls.applies_to not in APPLIES_TO:
        return f"{cls.__qualname__}.applies_to must be 'bulk' or 'walls', got {cls.applies_to!r}"
    uses = cls.uses
    if not (isinstance(uses, tuple) and all(isinstance(q, str) and q in COLUMN_QUANTITIES for q in uses)):
        return (
            f"{cls.__qualname__}.uses must be a tuple of the column quantities the engine gives a law "
            f"({', '.join(COLUMN_QUANTITIES)}), got {shown(uses)}: a quantity it never gives would leave "
            "the law on its own default"
        )
    for method in ("yield_stress", "viscosity"):
        if getattr(cls, method) is getattr(Rheology, method):
            return f"{cls.__qualname__} does not implement {method}()"
    try:
        parameter_model(cls)
    except Exception as exc:  # an unusable constructor signature
        return f"{cls.__qualname__}.__init__ has an unusable signature: {exc}"
    taken = [p.name for p in _parameters(cls) if p.name in RESERVED_PARAMETERS]
    if taken:
        return (
            f"{cls.__qualname__}.__init__ has a parameter {taken[0]!r}, a key a scenario cannot give it: "
            f"in `rheology:` and `walls:` {RESERVED_PARAMETERS[taken[0]]}; accepted: other parameter names"
        )
    return None


RESERVED_PARAMETERS = {"name": "`name` chooses the law"}
"""Constructor parameters a plugin may not have: keys of a scenario's ``rheology`` and
``walls`` mappings with a meaning of their own (``scenario.schema.PluginSpec``).  A
parameter ``name`` could never be set (``name: x`` chooses the law x), so a law having one
is skipped with a warning rather than listed by ``multilayer plugins``."""


@functools.cache
def catalogue() -> Catalogue:
    """Load every entry point of the ``multilayer`` group (once per process)."""
    manager = pluggy.PluginManager(PROJECT)
    manager.add_hookspecs(HookSpecs)
    found: dict[str, Registered] = {}
    broken: list[Broken] = []
    for ep in _entry_points():
        source = _source(ep)
        classes: list[type[Rheology]] = []
        host = host_state()
        try:
            with printing_to_stderr():
                module = ep.load()
                manager.register(module, name=source)
                others = [p for p in manager.get_plugins() if p is not module]
                manager.subset_hook_caller("multilayer_register_rheologies", others)(register=classes.append)
        except KeyboardInterrupt:
            raise
        except BaseException as exc:  # noqa: BLE001 - any failure of third-party code (sys.exit too) is reported
            broken.append(Broken(source, described(exc)))
            continue
        finally:
            changed = set_back(host)
        if changed:  # as a constructor or a step would (construct): a notebook's directory changed
            broken.append(Broken(source, f"importing and registering it changed {changed}; {HOST_CHANGED}"))
            continue
        if not classes:
            broken.append(
                Broken(
                    source,
                    "registers no rheology (is "
                    "multilayer_register_rheologies decorated with @multilayer.hookimpl?)",
                )
            )
        for cls in classes:
            try:
                problem = _problem(cls)
            except Exception as exc:  # noqa: BLE001 - a class whose attributes raise
                problem = f"{cls!r} cannot be inspected: {described(exc)}"
            if problem is None and cls.name in found:
                problem = (
                    f"rheology name '{cls.name}' is already registered by "
                    f"{found[cls.name].source}; this second registration was rejected"
                )
            if problem is None:
                found[cls.name] = Registered(cls, source)
            else:
                broken.append(Broken(source, problem))
    for item in broken:
        warnings.warn(f"rheology plugin {item.source} skipped: {item.error}", PluginWarning, stacklevel=2)
    return Catalogue(found, tuple(broken))


def printing_to_stderr() -> contextlib.AbstractContextManager[object]:
    """What a plugin's own code prints goes to stderr while it runs here, in the main
    thread: a module printing as it is imported (or as it registers) wrote its line into
    the output of ``multilayer plugins``, ``validate`` and ``run``, which scripts read.
    ``sys.stdout`` is the process's: in another thread (a host running laws in a pool) it
    is left alone, since two threads swapping it at once can leave it swapped for good.
    ``multilayer run`` and ``check`` hold it over their runs (a law printing in its
    methods), and set back at their end a ``sys.stdout`` a plugin replaced; a run through
    the Python API leaves the host's stdout to the host."""
    if threading.current_thread() is not threading.main_thread():
        return contextlib.nullcontext()
    return contextlib.redirect_stdout(sys.stderr)


def refresh() -> None:
    """Forget the loaded catalogue, e.g. after installing a plugin in this process."""
    catalogue.cache_clear()


def registry() -> dict[str, type[Rheology]]:
    """Registered rheology classes by name."""
    return {name: item.cls for name, item in catalogue().rheologies.items()}


def is_builtin(name: str) -> bool:
    """Whether the rheology registered as ``name`` is one of multilayer's own (its
    ``builtins`` entry point); False for a third party's and for an unknown name."""
    item = catalogue().rheologies.get(name)
    return item is not None and item.cls.__module__.startswith(f"{PROJECT}.plugins.builtins.")


def available(applies_to: str) -> list[str]:
    """Sorted names of the rheologies for ``applies_to`` ("bulk" or "walls")."""
    return sorted(n for n, cls in registry().items() if cls.applies_to == applies_to)


def find(name: str, applies_to: str | None = None) -> tuple[type[Rheology] | None, str | None]:
    """The class registered as ``name`` and what is wrong with it for ``applies_to``
    (``None`` when it exists and applies there)."""
    cls = registry().get(name)
    if cls is None:
        return None, f"unknown rheology {shown(name)}"
    if applies_to is not None and cls.applies_to != applies_to:
        return cls, f"{shown(name)} applies to {cls.applies_to}, not {applies_to}"
    return cls, None


def lookup(name: str, applies_to: str | None = None) -> type[Rheology]:
    """The class registered as ``name``; :class:`InputError` if there is none."""
    cls, problem = find(name, applies_to)
    if problem or cls is None:
        names = available(applies_to) if applies_to else sorted(registry())
        raise InputError(f"{problem or name}; accepted: {', '.join(names)}")
    return cls


def _parameters(cls: type[Rheology]) -> list[inspect.Parameter]:
    try:
        signature = inspect.signature(cls, eval_str=True)
    except ValueError:  # no Python-level __init__: no parameters
        return []
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    return [p for p in signature.parameters.values() if p.kind in kinds]


_PARAMETER_MODELS: dict[type, type[BaseModel]] = {}


def parameter_model(cls: type[Rheology]) -> type[BaseModel]:
    """A strict pydantic model of ``cls.__init__``'s keyword arguments (the parameter schema),
    built once per class."""
    if cls not in _PARAMETER_MODELS:
        _PARAMETER_MODELS[cls] = _build_parameter_model(cls)
    return _PARAMETER_MODELS[cls]


def _build_parameter_model(cls: type[Rheology]) -> type[BaseModel]:
    fields: dict[str, Any] = {
        p.name: (Any if p.annotation is p.empty else p.annotation, ... if p.default is p.empty else p.default)
        for p in _parameters(cls)
    }
    return create_model(
        f"{cls.__name__}Parameters",
        __config__=ConfigDict(extra="forbid", strict=True, allow_inf_nan=False),
        **fields,
    )


def signature_text(cls: type[Rheology]) -> str:
    """``name(mu_s: float, nu: float)``: the parameters as written in a scenario."""

    def one(p: inspect.Parameter) -> str:
        text = p.name
        if p.annotation is not p.empty:
            text += f": {getattr(p.annotation, '__name__', p.annotation)}"
        if p.default is not p.empty:
            text += f" = {p.default!r}"
        return text

    return f"{cls.name}({', '.join(one(p) for p in _parameters(cls))})"


def description(cls: type[Rheology]) -> str:
    """The first line of the class docstring; without one (``python -OO`` removes every
    docstring: the catalogue listed each law with an empty description) the class and the
    module that define it."""
    doc = inspect.getdoc(cls) or ""
    if doc.strip():
        return doc.strip().splitlines()[0]
    why = " (docstrings removed by python -OO)" if sys.flags.optimize >= 2 else ""
    return f"no description{why}: class {cls.__qualname__} of module {cls.__module__}"


_STOP_SIGNALS = tuple(
    (f"handler of {name}", getattr(signal, name))
    for name in ("SIGINT", "SIGTERM", "SIGHUP")
    if hasattr(signal, name)
)
"""The stop signals of :func:`host_state`: (its key, the signal)."""


def host_state() -> dict[str, Any]:
    """What a plugin may not change of the process it runs in (docs/plugins.md): the
    working directory (against which the run's relative paths are read: a plugin's
    ``os.chdir`` stopped the run blaming a removed output directory), the handlers of the
    stop signals (a plugin ignoring SIGINT made the run deaf to Ctrl-C, and the process
    after it) and numpy's floating-point error handling.  Taken in the main thread only:
    another thread may change the first two meanwhile, and a plugin in it cannot set a
    signal handler.  Taken twice in every step (``Simulation.step``): the handlers are read
    with ``_signal``'s function, which ``signal.getsignal`` wraps to convert each to an
    enum, by a failed look-up (an exception) for a Python function (``SIG_DFL`` and
    ``SIG_IGN`` stay the integers they are, equal to their enums)."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    try:
        directory: str | None = os.getcwd()
    except OSError:  # removed: nothing to compare with
        directory = None
    handlers = {key: _signal.getsignal(s) for key, s in _STOP_SIGNALS}
    return {"working directory": directory, **handlers, "numpy error handling": np.geterr()}


def _shown(value: Any) -> str:
    if isinstance(value, int) and value in (signal.SIG_DFL, signal.SIG_IGN):
        return signal.Handlers(value).name
    return str(getattr(value, "__qualname__", None) or value)


HOST_CHANGED = "a plugin may not change the process it runs in (set back)"


def set_back(before: dict[str, Any]) -> str:
    """Set back what changed of :func:`host_state` since ``before``; what changed, in words
    ("" if nothing)."""
    after = host_state()
    changed = [key for key, value in before.items() if after[key] != value]
    for key in changed:
        if key == "working directory":
            with contextlib.suppress(OSError):  # removed since
                os.chdir(before[key])
        elif key == "numpy error handling":
            np.seterr(**before[key])
        elif before[key] is not None:  # a handler not set from Python cannot be set back
            signal.signal(getattr(signal, key.split()[-1]), before[key])
    return "; ".join(f"the {key} from {_shown(before[key])} to {_shown(after[key])}" for key in changed)


class ConstructorError(ValueError):
    """A rheology's constructor raised (anything but the user's Ctrl-C) or returned nothing usable."""


def construct(cls: type[Rheology], params: dict[str, Any]) -> Rheology:
    """``cls(**params)``; a :class:`ConstructorError` (a ValueError: bad parameters) if the
    constructor raises anything, ``sys.exit`` included (a ``TypeError`` or ``ValueError``
    keeps its message, which says what is wrong with the parameters), or changes the
    process it runs in (:func:`host_state`, set back)."""
    call = f"{cls.__qualname__}({_arguments(params)})"
    host = host_state()
    try:
        with printing_to_stderr():
            plugin = cls(**params)
    except (TypeError, ValueError) as exc:
        raise ConstructorError(said(exc)) from None
    except KeyboardInterrupt:  # the user's Ctrl-C while the constructor ran
        raise
    except BaseException as exc:  # noqa: BLE001 - a third-party constructor's failure is bad parameters
        raise ConstructorError(f"{call} raised {described(exc)}") from None
    finally:
        changed = set_back(host)
    if changed:
        raise ConstructorError(f"{call} changed {changed}; {HOST_CHANGED}")
    return plugin


def _arguments(params: dict[str, Any]) -> str:
    return ", ".join(f"{key}={value!r}" for key, value in params.items())


def instantiate(spec: Spec) -> Rheology:
    """The plugin instance for a scenario's ``rheology`` or ``walls`` spec."""
    cls = lookup(spec.name)
    try:
        return construct(cls, spec.params)
    except ConstructorError as exc:
        raise InputError(f"rheology {spec.name}: {exc}; accepted: {signature_text(cls)}") from None
