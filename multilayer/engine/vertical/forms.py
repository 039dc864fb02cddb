"""The compiled forms of the laws: one registry of the compiled viscosity forms, their
Newton model one value at a time, and whether the form a plugin declares describes it.

A rheology plugin may declare its viscosity as one of the compiled forms of :data:`FORMS`
(``Rheology.viscosity_kernel``, docs/plugins.md), for ``p = max(p, 0)``: ``constant``,
``eta``; ``inertial``, ``A p / (B sqrt(p) + C |gamma|)`` (the mu(I) law of Jop, Forterre &
Pouliquen 2006, eq. 2, less its yield part); ``inertial_quadratic``, ``(A p + D |gamma|
sqrt(p)) / (B sqrt(p) + C |gamma|)`` (the same with the high-I term ``mu_inf I^2 / (I_0 +
I)`` of Barker & Gray 2017); ``power``, ``A p^e_p max(|gamma|, floor)^e_g``;
``inertial_plateau``, the viscous stress ``max(0, A p |gamma| / (B sqrt(p) + C |gamma|) - D
p / (1 + h / L))`` divided by ``|gamma|`` (the mu(I) of Jop, Forterre & Pouliquen 2005 above
the thickness-dependent stop friction of Forterre & Pouliquen 2003, ``pouliquen_forterre``),
the one form that takes the column thickness ``h`` (a law that declares ``Rheology.uses =
("thickness",)``). The compiled vertical step (``newton_kernel``, ``sheared_columns``)
evaluates them here, with the factors that depend on the pressure only computed once per
layer and step (:func:`_pressure_parts`).

A new form is one :class:`Form` in :data:`FORMS` and its branch in :func:`_pressure_parts`
and :func:`_viscosity_and_slope` (with its exact slope), all in this module, and a test
against the plugin's own ``viscosity`` (tests/test_newton_kernel.py); the side-by-side
sweep of ``sheared_columns`` runs it as it is, and compiles a copy specialised to it only
where a branch there names its code.

A form describes the methods of the class that declares it (:func:`describes`): where a
subclass (or the instance itself) redefines one of them below that class, the form no
longer describes what the plugin computes, and the engine calls the plugin's own methods.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np

from multilayer.engine.compiled import jit
from multilayer.engine.plugin_output import (
    PluginOutputError,
    contained,
    declared_form,
    plugin_label,
    read_only,
    real_array,
)


@dataclass(frozen=True)
class Form:
    """A compiled viscosity form: its name in ``viscosity_kernel``, its code in the kernels
    and how many parameters it takes."""

    name: str
    code: int
    parameters: int
    thickness: bool = False  # takes the column thickness (laws with Rheology.uses = ("thickness",))


CONSTANT, INERTIAL, POWER, INERTIAL_QUADRATIC, INERTIAL_PLATEAU = 0, 1, 2, 3, 4
"""The codes of the built-in forms (the branches of :func:`_viscosity_and_slope`)."""
FORMS = {
    form.name: form
    for form in (
        Form("constant", CONSTANT, 1),
        Form("inertial", INERTIAL, 3),
        Form("power", POWER, 4),
        Form("inertial_quadratic", INERTIAL_QUADRATIC, 4),
        Form("inertial_plateau", INERTIAL_PLATEAU, 5, thickness=True),
    )
}
"""The compiled viscosity forms by name."""


_PARAMETER_COUNTS = {name: form.parameters for name, form in FORMS.items()}
"""The number of parameters of each compiled viscosity form by name (:func:`law_of`)."""

PARAMETERS = max(form.parameters for form in FORMS.values())
"""The number of parameters every form is given (:func:`parameters`)."""


def parameters(values: Any) -> np.ndarray:
    """The parameters of a compiled form, padded with zeros to :data:`PARAMETERS` floats
    (the kernels read them as a tuple, :func:`as_tuple`)."""
    floats = np.zeros(PARAMETERS)
    given = np.ravel(np.asarray(values, dtype=float))
    floats[: given.size] = given
    return floats


NO_PARAMETERS = parameters(())
"""The parameters of an absent law (no side walls)."""


@jit(inline="always")
def as_tuple(params):
    """The :data:`PARAMETERS` parameters of a form as a tuple: numba counts the
    references of an array passed to a function it does not inline, two atomic
    operations per call, which cost five times the evaluation of a law itself; a tuple
    of floats has none.  A kernel converts once and passes the tuple to the forms."""
    return (params[0], params[1], params[2], params[3], params[4])


def law_of(rheology: Any, material: Any) -> tuple[int, np.ndarray] | None:
    """(form code, parameters) of a plugin's compiled viscosity, None if it has none (or
    declares a form unknown here).  A known form with another number of parameters stops
    the run naming the plugin (``plugin_output.declared_form``).

    A compiled form describes the ``viscosity`` of the class that declares it: where a
    subclass (or the instance) redefines ``viscosity`` below that class, the form is not
    used, and the step runs the plugin's own ``viscosity`` (numpy path); so does a law whose
    column quantities (``Rheology.uses``) are not those its form takes (the thickness forms
    for a law that uses the thickness, the others for a law that uses nothing)."""
    if not describes(rheology, "viscosity_kernel", ("viscosity",)):
        return None
    uses = tuple(getattr(rheology, "uses", ()))
    if uses not in ((), ("thickness",)):
        return None
    declared = declared_form(rheology, "viscosity_kernel", material, _PARAMETER_COUNTS)
    if declared is None or FORMS[declared[0]].thickness != bool(uses):
        return None
    form, params = FORMS[declared[0]], parameters(declared[1])
    _check_agreement(rheology, material, form, params)
    return form.code, params


SAMPLES = {
    "pressure": (0.0, 1.0, 1e3, 1e5),
    "shear_rate": (0.0, 1e-3, 1.0, 1e2),
    "thickness": (1e-3, 0.1, 10.0),
}
"""Where a declared form is held equal to the plugin's ``viscosity`` (:func:`_check_agreement`):
pressures (Pa), shear rates (1/s) and, for the forms that take it, column thicknesses (m)."""

AGREEMENT = 1e-9
"""The difference allowed there, relative to the viscosity or, as a stress, to the pressure
(a friction of order 1): round-off, which the difference of two stresses near the plateau
of ``inertial_plateau`` amplifies in the viscosity, not in the stress (the built-in laws'
forms agree to 1e-14 elsewhere, tests/test_newton_kernel.py)."""

_agreed: set[tuple] = set()
"""The (class, form, parameters, material) already held equal to their plugin's ``viscosity``."""


def _check_agreement(rheology: Any, material: Any, form: Form, params: np.ndarray) -> None:
    """:class:`PluginOutputError` naming the plugin where the compiled form it declares is
    not its ``viscosity`` at the points of :data:`SAMPLES` (to :data:`AGREEMENT`): the
    compiled step computed with the form, and a form of another viscosity gave another
    flow, silently (a ``constant`` form of 100 times the plugin's ``eta``).  Held once per
    class, form, parameters and material (the check is not made at every step)."""
    key = (type(rheology), form.code, params.tobytes(), material)  # law_of's every call: cheap
    if key in _agreed:
        return
    thicknesses = SAMPLES["thickness"] if form.thickness else (0.0,)
    pressure, rate, thickness = (
        np.ravel(grid)[np.newaxis, :]
        for grid in np.meshgrid(SAMPLES["pressure"], SAMPLES["shear_rate"], thicknesses, indexing="ij")
    )
    keywords = {"thickness": read_only(thickness)} if form.thickness else {}
    with contained(rheology, "viscosity()"), np.errstate(all="ignore"):
        value = rheology.viscosity(read_only(rate), read_only(pressure), material, **keywords)
    plugin = real_array(rheology, "viscosity()", value)
    by_form = np.empty(pressure.size)
    factor, offset = np.empty(1), np.empty(1)
    # the forms' source, which the kernels compile (held equal: tests/test_newton_kernel.py),
    # run by the interpreter: the check compiles nothing for the run
    with np.errstate(all="ignore"):  # numpy scalars throughout: inf or nan, not an exception
        for i in range(pressure.size):
            column = np.array([pressure[0, i]])
            _pressure_parts.py_func(form.code, params, column, thickness[0, i], factor, offset, 0)
            by_form[i], _ = _viscosity_and_slope.py_func(form.code, params, rate[0, i], factor[0], offset[0])
    if plugin.shape == pressure.shape:
        plugin = plugin[0]
        with np.errstate(all="ignore"):  # a value not finite is the contract's (plugin_output.call)
            gap = np.abs(plugin - by_form)
            differs = (gap > AGREEMENT * np.maximum(np.abs(plugin), np.abs(by_form))) & (
                gap * rate[0] > AGREEMENT * pressure[0]
            )
        if not differs.any():
            if len(_agreed) > 1024:
                _agreed.clear()
            _agreed.add(key)
            return
        i = int(np.argmax(differs))
        at = f"pressure {pressure[0, i]:g} Pa, shear rate {rate[0, i]:g} 1/s" + (
            f", thickness {thickness[0, i]:g} m" if form.thickness else ""
        )
        raise PluginOutputError(
            f"{plugin_label(rheology)}: viscosity_kernel() declares the compiled form {form.name!r} "
            f"{tuple(params[: form.parameters].tolist())}, which is not its viscosity(): at {at} the form "
            f"gives {float(by_form[i])!r} Pa s, viscosity() {float(plugin[i])!r} "
            '(docs/plugins.md, "Compiled forms"); '
            "accepted: a form equal to viscosity() to round-off, or None (the plugin's own methods run)"
        )
    raise PluginOutputError(
        f"{plugin_label(rheology)}: viscosity() returned an array of shape {plugin.shape}; "
        f"expected {pressure.shape}, the shape of its pressure argument"
    )


@jit
def concave(form, params):
    """True when the viscous stress ``eta(rate) rate`` of a compiled form is concave in the
    rate (the tangent and chord bounds of ``newton_control.energy_rise`` hold): constant
    and inertial forms, the power form with ``e_g <= 0``, the inertial_quadratic form with
    ``A C >= B D`` (its stress is ``D/C`` times the rate plus an inertial one of
    coefficient ``A - B D / C``); never the inertial_plateau form (its stress is 0 up to
    the rate where the inertial stress reaches the plateau: convex there)."""
    if form == INERTIAL_QUADRATIC:
        return params[0] * params[2] >= params[1] * params[3]
    return form == CONSTANT or form == INERTIAL or (form == POWER and params[2] <= 0.0)


def concave_laws(laws: tuple[Any, ...], material: Any) -> bool:
    """True when every law of ``laws`` (None: absent) has a compiled form that describes it
    and is :func:`concave`; False for a law known only by its Python methods."""
    for law in laws:
        if law is None:
            continue
        form = law_of(law, material)
        if form is None or not concave(*form):
            return False
    return True


@jit(borrowing=True)
def _pressure_parts(form, params, pressure, h, factor, offset, start):
    """The factors of eta that depend on the pressure (and the column thickness ``h``)
    only, and the ones added to the rate term, of the layers of ``pressure`` (computed once
    per column and step, not per Newton iteration): into ``factor`` and ``offset`` from
    ``start`` on.  For the inertial_plateau form, the plateau stress ``D p / (1 + h / L)``
    and the pressure.  The form's switch is taken once per column, outside the layers."""
    n = pressure.shape[0]  # (the cells unsigned: no test for negative indices)
    if form == CONSTANT:
        for a in range(n):
            x = np.uint64(start + a)
            factor[x], offset[x] = params[0], 0.0
    elif form == INERTIAL or form == INERTIAL_QUADRATIC:
        for a in range(n):
            p = max(pressure[a], 0.0)
            x = np.uint64(start + a)
            factor[x], offset[x] = params[0] * p, params[1] * np.sqrt(p)
    elif form == INERTIAL_PLATEAU:
        plateau = params[3] / (1.0 + h / params[4])
        for a in range(n):
            p = max(pressure[a], 0.0)
            x = np.uint64(start + a)
            factor[x], offset[x] = plateau * p, p
    else:  # POWER
        for a in range(n):
            p = max(pressure[a], 0.0)
            x = np.uint64(start + a)
            factor[x], offset[x] = params[0] * p ** params[1], 0.0


@jit
def _viscosity_and_slope(form, params, rate, factor, offset):
    """eta(rate, p) of the compiled forms (``Rheology.viscosity_kernel``) and the slope
    d(eta rate)/d rate of the viscous stress, for ``rate >= 0``, from the pressure parts
    ``factor, offset`` of :func:`_pressure_parts`.

    The slope is exact: ``eta`` for the constant form; ``eta B sqrt(p) / (B sqrt(p) +
    C rate)`` for the inertial form (``eta`` at rest); for the inertial_quadratic one, with
    ``o = B sqrt(p)``, ``E = D / B``: ``eta = (A p + E o rate) / (o + C rate)`` and the slope
    ``(A p o + E o rate (2 o + C rate)) / (o + C rate)^2``; ``(1 + e_g) eta`` above the
    floor of the power form, ``eta`` below it; for the inertial_plateau form (``factor``
    the plateau stress ``s``, ``offset`` the pressure ``p``, ``o = B sqrt(p)``), ``eta =
    (A p rate / (o + C rate) - s) / rate`` and the slope ``A p o / (o + C rate)^2`` where
    the inertial stress exceeds the plateau, 0 and 0 elsewhere (0 at rest, as the law).
    """
    if form == CONSTANT:
        return factor, factor
    if form == INERTIAL:
        denominator = offset + params[2] * rate
        if denominator > 0.0:
            inverse = 1.0 / denominator
            eta = factor * inverse
            return eta, eta * offset * inverse
        return 0.0, 0.0
    if form == INERTIAL_QUADRATIC:
        denominator = offset + params[2] * rate
        if denominator > 0.0:
            inverse = 1.0 / denominator
            e = params[3] / params[1] * offset * rate
            return (factor + e) * inverse, (
                factor * offset + e * (2.0 * offset + params[2] * rate)
            ) * inverse * inverse
        return 0.0, 0.0
    if form == INERTIAL_PLATEAU:
        o = params[1] * np.sqrt(offset)
        denominator = o + params[2] * rate
        if denominator > 0.0 and rate > 0.0:
            inverse = 1.0 / denominator
            inertial = params[0] * offset * inverse
            tau = inertial * rate - factor
            if tau > 0.0:
                return tau / rate, inertial * o * inverse
        return 0.0, 0.0
    if rate > params[3]:  # POWER
        eta = factor * rate ** params[2]
        return eta, (1.0 + params[2]) * eta
    eta = factor * params[3] ** params[2]
    return eta, eta


@jit
def _newton_model(kappa, rate, eta, slope):
    """``stresses.StressModel._newton_model`` for one value from ``eta`` and the stress slope at
    ``rate``: (yield stress, conductance) of the odd Bingham law through the stress at
    ``rate``, tangent where its yield stress is >= 0, secant otherwise."""
    slope = max(slope, 0.0)
    offset_yield = kappa + eta * rate - slope * rate
    if offset_yield >= 0.0:
        return offset_yield, slope
    return kappa, eta


def describes(rheology: object, kernel: str, methods: tuple[str, ...]) -> bool:
    """True when the definition of ``kernel`` that ``rheology`` uses comes from a class at
    or below every class whose definition of ``methods`` it uses (never when the instance
    itself defines one of them)."""
    instance = getattr(rheology, "__dict__", {})  # none with __slots__
    if kernel in instance or not instance.keys().isdisjoint(methods):
        return False
    cls: Any = type(rheology)
    # the definitions the class resolves now: a method patched on a class is a new key
    return _class_describes(
        cls, kernel, methods, tuple([getattr(cls, name, None) for name in (kernel, *methods)])
    )


@functools.lru_cache(maxsize=256)
def _class_describes(cls: Any, kernel: str, methods: tuple[str, ...], definitions: tuple) -> bool:
    """``describes`` for the class ``cls`` whose attributes ``kernel, *methods`` resolve to
    ``definitions`` (part of the key of the cache)."""
    kernel_owner = _owner(cls, kernel)
    if kernel_owner is None:
        return False
    for method in methods:
        method_owner = _owner(cls, method)
        if method_owner is None or not issubclass(kernel_owner, method_owner):
            return False
    return True


def _owner(cls: Any, name: str) -> type | None:
    """The class of ``cls.__mro__`` whose definition of ``name`` ``cls`` uses (None: none)."""
    return next((base for base in cls.__mro__ if name in vars(base)), None)
