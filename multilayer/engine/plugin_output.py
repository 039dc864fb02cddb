"""Checked calls of rheology plugins: every value a plugin returns is verified where it is used.

The plugin contract (docs/plugins.md) asks ``yield_stress(p)`` for ``kappa(p) >= 0`` and
``viscosity(gamma, p)`` for ``eta >= 0``, finite, real, with the shape of the pressure
array.  A plugin that raises (anything: ``sys.exit`` and ``KeyboardInterrupt`` included),
returns another shape, complex or non-numeric values, a non-finite or a negative value
stops the run with a :class:`PluginOutputError` naming the plugin, the method, the
offending value, the inputs it was given and where (x, interface or layer, time): a NaN
never reaches the column kernel, where it could spin or write outside its workspace.

A plugin is given read-only copies of the engine's arrays and its results are copied:
it can change neither the state nor what it returned once returned.  The one exception
it does not own is the user's Ctrl-C: :class:`~multilayer.errors.Stop` (a run's first
signal, which its handler raises in the plugin's code: :func:`in_plugin_call`),
:class:`~multilayer.errors.Interrupted` (a run's second signal), and a
``KeyboardInterrupt`` while SIGINT has Python's default handler (outside ``multilayer
run``, which handles the signal itself), pass through.
"""

from __future__ import annotations

import contextlib
import dataclasses
import reprlib
import signal
import threading
from typing import Any

import numpy as np

from multilayer.engine.state_check import masked_values
from multilayer.errors import Interrupted, RunError, Stop, described


class PluginOutputError(RunError):
    """A rheology plugin raised or returned a value outside its contract (exit code 1)."""


def plugin_label(plugin: Any) -> str:
    """``'name' (module.Class)``: how messages name a plugin instance."""
    cls = type(plugin)
    try:
        name = str(getattr(plugin, "name", cls.__name__))
    except Exception:  # noqa: BLE001 - a name property that raises: the class names it
        name = cls.__name__
    return f"rheology plugin {name!r} ({cls.__module__}.{cls.__qualname__})"


_calls = threading.local()
"""``depth``: the plugin calls the thread is in (:func:`contained`)."""


def in_plugin_call() -> bool:
    """True while the calling thread runs a rheology plugin's code: where a run's signal
    handler raises :class:`~multilayer.errors.Stop` on the first signal (a plugin's own
    Python code may loop for ever; no state is replaced during its calls, the step that
    made them is abandoned).  The engine only counts its calls: it installs no handler."""
    return getattr(_calls, "depth", 0) > 0


def user_interrupt(exc: BaseException) -> bool:
    """True if ``exc``, raised during a plugin call, may be the user's Ctrl-C (module
    docstring) rather than the plugin's own failure."""
    if isinstance(exc, (Interrupted, Stop)):
        return True
    main = threading.current_thread() is threading.main_thread()
    default = signal.getsignal(signal.SIGINT) is signal.default_int_handler
    return isinstance(exc, KeyboardInterrupt) and default and main


class contained:  # noqa: N801 - used as the function it was: ``with contained(plugin, method):``
    """Turn whatever the block (a call of ``plugin``'s ``method``) raises into a
    :class:`PluginOutputError` naming them, except the user's Ctrl-C.  A class rather than
    a generator of ``contextlib``: the laws' compiled forms are read through it at every
    time step, and the generator's machinery cost three times the plugin's call."""

    __slots__ = ("plugin", "method", "t", "depth")

    def __init__(self, plugin: Any, method: str, t: float | None = None):
        self.plugin, self.method, self.t = plugin, method, t

    def __enter__(self) -> None:
        self.depth = getattr(_calls, "depth", 0)
        _calls.depth = self.depth + 1

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, _traceback: Any) -> None:
        # the count set back whatever is raised, a signal's Stop between two statements too
        _calls.depth = self.depth
        if exc is None or isinstance(exc, PluginOutputError) or user_interrupt(exc):
            return
        # sys.exit, KeyboardInterrupt of a plugin are its failures
        when = "" if self.t is None else f" (at t = {self.t:.6g} s)"
        raise PluginOutputError(
            f"{plugin_label(self.plugin)}: {self.method} raised {described(exc)}{when}"
        ) from None


def read_only(value: Any) -> Any:
    """A read-only copy of ``value`` if it is an array (what a plugin is given), a copy of a
    frozen dataclass holding arrays (a mixture's :class:`~multilayer.plugins.contract.MixtureState`)
    with read-only copies of them, else ``value``: the mixture's excess pore pressure is a
    view of the Newton iterate, which a plugin writing into it changed."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        arrays = {
            f.name: read_only(getattr(value, f.name))
            for f in dataclasses.fields(value)
            if isinstance(getattr(value, f.name), np.ndarray)
        }
        return dataclasses.replace(value, **arrays) if arrays else value
    if not isinstance(value, np.ndarray):
        return value
    copy = value.copy()
    copy.flags.writeable = False
    return copy


def real_array(plugin: Any, method: str, value: Any, t: float | None = None) -> np.ndarray:
    """``value`` returned by ``plugin.method`` as a new float array; :class:`PluginOutputError`
    unless it holds real numbers (not complex, text, objects or booleans, nor values under
    the mask of a masked array, which ``np.asarray`` would read as numbers).  A value beyond
    the floats (a ``np.longdouble`` of 1e400) is infinite here, without numpy's warning of
    the cast: the callers' checks name it."""
    with contained(plugin, method, t):
        raw = np.asarray(value)
        masked = masked_values(value)
    if raw.dtype.kind not in "fiu" or masked:
        when = "" if t is None else f" (at t = {t:.6g} s)"
        what = f"a masked array of {masked} masked value(s)" if masked else f"values of type {raw.dtype}"
        raise PluginOutputError(
            f"{plugin_label(plugin)}: {method} returned {what} ({type(value).__name__}); must be real "
            f"numbers{when}"
        )
    # a long double beyond the floats: infinite, named by the checks (a value of 8 bytes or
    # fewer is within the floats: its cast needs no change of numpy's error handling)
    with np.errstate(over="ignore") if raw.dtype.itemsize > 8 else contextlib.nullcontext():
        return np.array(raw, dtype=float)


def declared_form(
    plugin: Any, method: str, material: Any, parameters: dict[str, int]
) -> tuple[str, np.ndarray] | None:
    """The compiled form ``plugin.method(material)`` declares (``viscosity_kernel``,
    ``yield_stress_kernel``; docs/plugins.md, "Compiled forms"): None for none or a form
    the engine does not know (the plugin's own methods then run), else ``(form,
    parameters)``.  :class:`PluginOutputError` naming the plugin if it raises or declares
    a known form with other than ``parameters[form]`` real numbers (the kernels read that
    many)."""
    with contained(plugin, f"{method}()"):
        declared = getattr(plugin, method)(material)
    if declared is None:
        return None
    if not (isinstance(declared, (tuple, list)) and len(declared) == 2 and isinstance(declared[0], str)):
        raise PluginOutputError(
            f"{plugin_label(plugin)}: {method}() returned {reprlib.repr(declared)}; "
            "must be None or (form name, parameters)"
        )
    form = declared[0]
    if form not in parameters:
        return None
    values = real_array(plugin, f"{method}()", declared[1])
    if values.shape != (parameters[form],):
        raise PluginOutputError(
            f"{plugin_label(plugin)}: {method}() declares the form {form!r} with parameters "
            f"{reprlib.repr(declared[1])}; it takes {parameters[form]} numbers (docs/plugins.md)"
        )
    return form, values


def call(
    plugin: Any,
    method: str,
    args: tuple[Any, ...],
    *,
    inputs: dict[str, np.ndarray],
    x: np.ndarray,
    position: str,
    t: float,
    keywords: dict[str, np.ndarray] | None = None,
) -> np.ndarray:
    """``plugin.method(*args, **keywords)`` as a float array of the shape of ``inputs``'
    arrays, finite and >= 0.

    ``inputs`` names the array arguments (reported with a bad value), ``x`` (N,) is the
    position of each column and ``position`` names an entry of the first axis in messages,
    a template with ``{index}`` (0-based) and ``{number}`` (1-based); ``t`` is the time of
    the step being computed.  ``keywords`` are the column quantities the plugin declares in
    ``uses`` (given read-only like the arguments).
    """
    shape = np.shape(next(iter(inputs.values())))
    keywords = {} if keywords is None else {key: read_only(value) for key, value in keywords.items()}
    # a value that overflows is named below: numpy's warning (a friction of 1e308 times a
    # pressure) would come before the message as noise
    with contained(plugin, f"{method}()", t), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        value = getattr(plugin, method)(*map(read_only, args), **keywords)
    array = real_array(plugin, f"{method}()", value, t)
    if array.shape != shape:
        raise PluginOutputError(
            f"{plugin_label(plugin)}: {method}() returned an array of shape {array.shape}; "
            f"expected {shape}, the shape of its pressure argument (at t = {t:.6g} s)"
        )
    if array.size and not (array.min() >= 0.0 and array.max() < np.inf):  # NaN fails both (cheap)
        good = np.isfinite(array) & (array >= 0.0)
        a, j = np.unravel_index(np.argmin(good), shape) if array.ndim == 2 else (0, int(np.argmin(good)))
        bad = float(array[a, j] if array.ndim == 2 else array[j])
        count = int(array.size - np.count_nonzero(good))
        given = {name: float(np.asarray(v)[a, j]) for name, v in inputs.items()}
        raise outside_contract(
            plugin, f"{method}()", bad, x=float(x[j]), where=position.format(index=a, number=a + 1), t=t,
            given=given, note=f"{count} bad value(s) in this call",
        )  # fmt: skip
    return array


def outside_contract(
    plugin: Any,
    method: str,
    bad: float,
    *,
    x: float,
    where: str,
    t: float,
    given: dict[str, float],
    note: str,
) -> PluginOutputError:
    """The error for a value ``bad`` of ``plugin``'s ``method`` that is not finite and >= 0,
    found at ``x`` (m), ``where`` (interface or layer) and time ``t``, for the inputs ``given``."""
    rule = "finite" if not np.isfinite(bad) else ">= 0"
    inputs = ", ".join(f"{name} = {value:.6g}" for name, value in given.items())
    return PluginOutputError(
        f"{plugin_label(plugin)}: {method} returned {bad!r} (must be {rule}) at "
        f"x = {x:.6g} m, {where}, t = {t:.6g} s, for {inputs} ({note})"
    )
