"""The compiled viscosity forms of the laws and their Newton model, one value at a time.

A rheology plugin may declare its viscosity as one of three compiled forms
(``Rheology.viscosity_kernel``, docs/plugins.md), for ``p = max(p, 0)``: ``constant``,
``eta``; ``inertial``, ``A p / (B sqrt(p) + C |gamma|)`` (the mu(I) law of Jop, Forterre
& Pouliquen 2006, eq. 2, less its yield part); ``power``, ``A p^e_p max(|gamma|,
floor)^e_g``.  The compiled vertical step (``newton_kernel``, ``sheared_columns``)
evaluates them here, with the factors that depend on the pressure only computed once per
layer and step (:func:`_pressure_part`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from multilayer.engine.compiled_forms import describes
from multilayer.engine.plugin_output import declared_form

FORMS = {"constant": 0, "inertial": 1, "power": 2}
PARAMETERS = {"constant": 1, "inertial": 3, "power": 4}
"""The parameters of each form: (eta,), (A, B, C), (A, e_p, e_g, floor)."""


def law_of(rheology, material) -> tuple[int, np.ndarray] | None:
    """(form code, parameters) of a plugin's compiled viscosity, None if it has none.

    A compiled form describes the ``viscosity`` of the class that declares it: where a
    subclass (or the instance) redefines ``viscosity`` below that class, the form is not
    used, and the step runs the plugin's own ``viscosity`` (numpy path)."""
    if not describes(rheology, "viscosity_kernel", ("viscosity",)):
        return None
    declared = declared_form(rheology, "viscosity_kernel", material, PARAMETERS)
    if declared is None:
        return None
    return FORMS[declared[0]], declared[1]


@njit(cache=True)
def _pressure_part(form, params, p):
    """The factor of eta that depends on the pressure only, and the one added to the
    rate term (computed once per column and step, not per Newton iteration)."""
    p = max(p, 0.0)
    if form == 0:
        return params[0], 0.0
    if form == 1:
        return params[0] * p, params[1] * np.sqrt(p)
    return params[0] * p ** params[1], 0.0


@njit(cache=True)
def _viscosity_and_slope(form, params, rate, factor, offset):
    """eta(rate, p) of the compiled forms (``Rheology.viscosity_kernel``) and the slope
    d(eta rate)/d rate of the viscous stress, for ``rate >= 0``, from the pressure parts
    ``factor, offset = _pressure_part(form, params, p)``.

    The slope is exact: ``eta`` for the constant form; ``eta B sqrt(p) / (B sqrt(p) +
    C rate)`` for the inertial form (``eta`` at rest); ``(1 + e_g) eta`` above the
    floor of the power form, ``eta`` below it.
    """
    if form == 0:
        return factor, factor
    if form == 1:
        denominator = offset + params[2] * rate
        if denominator > 0.0:
            inverse = 1.0 / denominator
            eta = factor * inverse
            return eta, eta * offset * inverse
        return 0.0, 0.0
    if rate > params[3]:
        eta = factor * rate ** params[2]
        return eta, (1.0 + params[2]) * eta
    eta = factor * params[3] ** params[2]
    return eta, eta


@njit(cache=True)
def _viscosity(form, params, rate, factor, offset):
    """eta(|gamma|, p) of the compiled forms (``Rheology.viscosity_kernel``) from the
    pressure parts ``factor, offset = _pressure_part(form, params, p)``."""
    return _viscosity_and_slope(form, params, abs(rate), factor, offset)[0]


@njit(cache=True)
def _newton_model(kappa, rate, eta, slope, secant):
    """``stress._newton_model`` for one value from ``eta`` and the stress slope at
    ``rate``: (yield stress, conductance) of the odd Bingham law through the stress at
    ``rate``, tangent where its yield stress is >= 0, secant otherwise (and always with
    ``secant``: the Kacanov model of ``newton_control``)."""
    slope = max(slope, 0.0)
    offset_yield = kappa + eta * rate - slope * rate
    if offset_yield >= 0.0 and not secant:
        return offset_yield, slope
    return kappa, eta
