"""Checked calls of rheology plugins: every value a plugin returns is verified where it is used.

The plugin contract (docs/plugins.md) asks ``yield_stress(p)`` for ``kappa(p) >= 0`` and
``viscosity(gamma, p)`` for ``eta >= 0``, finite, with the shape of the pressure array.
A plugin that raises, returns another shape, a non-finite or a negative value stops the
run with a :class:`PluginOutputError` naming the plugin, the method, the offending value,
the inputs it was given and where (x, interface or layer, time): a NaN never reaches the
column kernel, where it could spin or write outside its workspace.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from multilayer.errors import RunError


class PluginOutputError(RunError):
    """A rheology plugin raised or returned a value outside its contract (exit code 1)."""


def plugin_label(plugin: Any) -> str:
    """``'name' (module.Class)``: how messages name a plugin instance."""
    cls = type(plugin)
    return f"rheology plugin {getattr(plugin, 'name', cls.__name__)!r} ({cls.__module__}.{cls.__qualname__})"


def call(
    plugin: Any,
    method: str,
    args: tuple[Any, ...],
    *,
    inputs: dict[str, np.ndarray],
    x: np.ndarray,
    position: str,
    t: float,
) -> np.ndarray:
    """``plugin.method(*args)`` as a float array of the shape of ``inputs``' arrays, finite and >= 0.

    ``inputs`` names the array arguments (reported with a bad value), ``x`` (N,) is the
    position of each column and ``position`` names an entry of the first axis in messages,
    a template with ``{index}`` (0-based) and ``{number}`` (1-based); ``t`` is the time of
    the step being computed.
    """
    shape = np.shape(next(iter(inputs.values())))
    try:
        value = getattr(plugin, method)(*args)
        array = np.asarray(value, dtype=float)
    except Exception as exc:  # noqa: BLE001 - any failure inside a plugin is reported as the plugin's
        raise PluginOutputError(
            f"{plugin_label(plugin)}: {method}() raised {type(exc).__name__}: {exc} (at t = {t:.6g} s)"
        ) from exc
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
