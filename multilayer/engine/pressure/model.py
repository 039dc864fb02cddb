"""The pressure model of a simulation: the pressure the yield stresses see, and what the
step does to the velocities after the vertical step (docs/nonhydrostatic.md).

A model is a :class:`PressureModel` subclass with a ``name``, in a module of this package of
its own; :func:`models` finds them, and the scenario key ``model.pressure`` accepts their
names.  Its scenario options (``model.<option>``) are declared in :attr:`PressureModel.options`.
Per step (``Simulation.step``) a model gives

- :meth:`~PressureModel.yield_gravity`: the normal gravity ``G_k`` (L, N) of the interface
  pressures ``p_k = rho G_k (h - z_k)`` of the yield stresses (None: ``g cos(theta)``, the
  hydrostatic pressure), from the state at the start of the step and the thickness after
  transport;
- :meth:`~PressureModel.seeds`: the velocities the Newton iteration of the vertical step
  starts from, in the order it tries them;
- :meth:`~PressureModel.project`: the velocities at the end of the step from those of the
  vertical step, and the layer fields of the state it updates (the state's windowed
  commit stores them; :attr:`PressureModel.checked` names those the state guard checks).
"""

from __future__ import annotations

import functools
import importlib
import pkgutil
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from multilayer.engine import registry

if TYPE_CHECKING:
    from multilayer.engine.state import FlowState
    from multilayer.engine.vertical.problem import VerticalSolver
    from multilayer.engine.vertical.stresses import StressModel


@dataclass(frozen=True)
class Option:
    """A scenario option of a pressure model (``model.<name>``)."""

    accepted: str
    """What it accepts, for messages; ``{layers}`` is replaced by ``domain.layers``."""
    valid: Callable[[Any, int], bool]
    """Whether a value is accepted with that many layers."""
    default: Callable[[int], Any]
    """Its value when the scenario does not give it, for that many layers."""


@dataclass(frozen=True)
class PressureSetup:
    """What a pressure model may need of its simulation."""

    fractions: np.ndarray
    """Layer fractions (L,)."""
    bed: np.ndarray
    """Bed elevation at the cell centres (N,), m."""
    dx: float
    gravity: float
    theta: float
    """Slope angle, radians."""
    g_n: float
    """``g cos(theta)``."""
    dry: float
    """Columns not thicker than this (m) are dry."""
    wraps: bool
    """The domain is periodic (its ends connect)."""
    base_bulk: np.ndarray
    """Columns (N,) whose bed is held by the bulk law (no slip; the others slip)."""
    options: Mapping[str, Any]
    """The model's options, defaults filled in (:func:`options`)."""
    stresses: StressModel | None = None
    """The laws of the vertical step (for a model that stresses the layers itself)."""
    solver: VerticalSolver | None = None
    """The exact solver of the column problem (None: the compiled one;
    ``numerics.vertical_solver``), for a model that solves such problems itself."""


class PressureModel:
    """The hydrostatic behaviour; subclasses change what they need (module docstring)."""

    name: ClassVar[str]
    options: ClassVar[Mapping[str, Option]] = {}
    checked: ClassVar[Mapping[str, str]] = {}
    """Layer fields that :meth:`project` returns and the state guard checks: field name, what it is."""

    def __init__(self, setup: PressureSetup, state: FlowState):
        self.setup = setup

    def found_finite(self) -> bool:
        """Whether the last :meth:`project` found every value of its fields :attr:`checked`
        finite in the kernels that wrote them (False: the state guard checks them)."""
        return False

    def yield_gravity(self, state: FlowState, h: np.ndarray) -> np.ndarray | None:
        """Normal gravity (L, N) of the yield pressures with the thickness ``h`` after
        transport; None: ``g cos(theta)``."""
        return None

    def seeds(self, state: FlowState) -> tuple[np.ndarray, ...]:
        """The velocities the Newton iteration starts from, tried in turn: the state's."""
        return (state.u,)

    def project(
        self, state: FlowState, h: np.ndarray, u: np.ndarray, dt: float
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """The velocities at the end of the step from those of the vertical step ``u`` on
        the thickness ``h``, and the layer fields to commit: ``u`` itself, none."""
        return u, {}


@functools.cache  # the package's modules are found once (validating a scenario asks every time)
def models() -> dict[str, type[PressureModel]]:
    """The pressure models of this package by name (a module holds one), the same mapping
    on every call (not to be changed)."""
    package = importlib.import_module(__package__ or "multilayer.engine.pressure")
    found: dict[str, type[PressureModel]] = {}
    for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda i: i.name):
        module = importlib.import_module(f"{package.__name__}.{info.name}")
        for value in vars(module).values():
            if (
                isinstance(value, type)
                and issubclass(value, PressureModel)
                and value is not PressureModel
                and value.__module__ == module.__name__
            ):
                found[value.name] = value
    return found


def accepted() -> str:
    """``bim2016, hydrostatic or non_hydrostatic``: the models as messages list them."""
    return registry.listing(list(models()))


def options(model: type[PressureModel], given: Mapping[str, Any], layers: int) -> dict[str, Any]:
    """The options of ``model`` with their defaults for ``layers`` layers where not ``given``."""
    return {
        key: given[key] if key in given else option.default(layers) for key, option in model.options.items()
    }
