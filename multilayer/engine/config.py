"""The engine's configuration: plain, typed, frozen values (SI units).

A :class:`~multilayer.engine.simulation.Simulation` is built from a
:class:`SimulationConfig` and the rheology plugin instances handed to it; the application
makes both from a validated scenario (:mod:`multilayer.app.factory`), and a script or a
test may make them directly.  Nothing here reads a file or knows the scenario schema:
the names are those of the scenario keys (docs/scenarios.md) so that the factory is a
one-to-one copy.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from multilayer.errors import InputError
from multilayer.plugins.contract import Material

MAX_STEPS = 10_000_000
"""Default bound on the time steps of one ``Simulation.advance`` and of a run
(``multilayer run --max-steps``): a loop that depends on input never runs without one."""


def step_bound(max_steps: object) -> float:
    """``max_steps`` of ``Simulation.advance`` as a bound (inf for None);
    :class:`InputError` unless an integer >= 1 or None."""
    if max_steps is None:
        return math.inf
    if isinstance(max_steps, bool) or not isinstance(max_steps, numbers.Integral) or max_steps < 1:
        raise InputError(f"advance(max_steps={max_steps!r}): accepted: an integer >= 1, or None for no bound")
    return float(max_steps)


def time_value(value: object) -> float:
    """``value`` (``t_max`` of ``Simulation.step``, ``t_target`` of ``advance``) as a time
    (s): a real number or a 0-d array of one; NaN for anything else."""
    item = value.item() if isinstance(value, np.ndarray) and value.ndim == 0 else value
    return float(item) if isinstance(item, numbers.Real) else math.nan


Points = tuple[tuple[float, float], ...] | np.ndarray
"""A piecewise-linear profile ``((x, value), ...)`` with increasing x (m), or its rows as
an ``(n, 2)`` array (a profile file's, read-only and shared: not copied into tuples)."""


FRACTIONS_SUM = 1e-12
"""How far the layer fractions may sum from 1: the round-off of ``mesh.layer_fractions``
(the layers' thicknesses ``l_a h`` add up to the column's ``h``)."""


@dataclass(frozen=True)
class Velocity:
    """A velocity profile over the depth (``zeta`` above the bottom of its entry):
    ``plug`` (``speed``), ``linear`` (``shear_rate`` above ``from_height``) or ``bagnold``
    (``surface_speed``); see :func:`multilayer.engine.initial_state.velocity_profile`."""

    profile: str
    speed: float = 0.0
    shear_rate: float = 0.0
    from_height: float = 0.0
    surface_speed: float = 0.0


@dataclass(frozen=True)
class InitialEntry:
    """One contribution to the initial thickness (entries stack in order): a uniform
    ``layer`` of ``thickness``, a ``rectangle`` (``x_min``, ``x_max``, ``height``) or a
    ``profile`` through ``points``; with its velocity profile (None: at rest)."""

    shape: str
    thickness: float | None = None
    x_min: float | None = None
    x_max: float | None = None
    height: float | None = None
    points: Points | None = None
    velocity: Velocity | None = None
    phi: float | None = None
    """Solid volume fraction of the entry in a grain–fluid mixture (None: a dry run)."""


@dataclass(frozen=True)
class BasalRegion:
    """A basal condition (:mod:`multilayer.engine.basal`) with its parameters on
    ``x_min <= x < x_max`` (unbounded where None); later regions win."""

    condition: str
    parameters: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))
    x_min: float | None = None
    x_max: float | None = None


@dataclass(frozen=True)
class Inflow:
    """The state prescribed at an ``inflow`` boundary: thickness (m) and velocity profile."""

    thickness: float
    velocity: Velocity


@dataclass(frozen=True)
class GateConfig:
    """A gate on the face nearest ``x`` whose lower edge rises at ``lift_speed`` (m/s;
    ``inf``: released at once); :mod:`multilayer.engine.gate`."""

    x: float
    lift_speed: float


@dataclass(frozen=True)
class Numerics:
    """Solver settings (docs/scenarios.md, ``numerics``)."""

    transport_solver: str = "kernel"
    """``kernel`` (compiled) or ``numpy`` (the reference formulation)."""
    threads: int | str = "auto"
    order: int = 2
    tolerance: float = 1e-10
    max_iterations: int = 200
    dry_threshold: float = 1e-6
    front_threshold: float = 1e-3


@dataclass(frozen=True)
class PressureConfig:
    """The pressure model (:mod:`multilayer.engine.pressure`) and its options."""

    model: str = "hydrostatic"
    options: Mapping[str, object] = field(default_factory=lambda: MappingProxyType({}))


@dataclass(frozen=True)
class MixtureConfig:
    """A grain–fluid mixture (:mod:`multilayer.engine.mixture`): the pore and ambient
    fluid and the dilatancy closure of Bouchut et al. (2016); ``material.particle_density``
    is the grain density.  The constants are those of docs/mixture.md."""

    fluid_density: float
    """rho_f (kg/m^3), below the grain density."""
    fluid_viscosity: float
    """eta_f (Pa s)."""
    phi_critical: float
    """phi_c, the critical volume fraction at rest."""
    dilatancy: float
    """K of ``tan(psi) = K (phi - phi_eq)``."""
    critical_shift: float
    """K2 of ``phi_eq = phi_c - K2 eta_f gamma / p_s``."""
    kozeny: float = 150.0
    """Carman–Kozeny constant of the permeability ``k = d^2 (1 - phi)^3 / (kozeny phi^2)``."""
    compressibility: float | None = None
    """alpha (1/Pa) of a basal excess pore pressure relaxing to the closure's (one layer;
    docs/mixture.md, "A pore pressure with its own evolution"); ``None``: the closure's at once."""


@dataclass(frozen=True)
class SimulationConfig:
    """Everything the engine reads of a problem, rheologies aside."""

    x_min: float
    x_max: float
    cells: int
    fractions: tuple[float, ...]
    """Layer fractions ``l_a`` from the bed up, summing to 1 (``mesh.layer_fractions``)."""
    material: Material
    gravity: float = 9.81
    slope_deg: float = 0.0
    width: float | None = None
    """Channel width (m) for side walls."""
    base: tuple[BasalRegion, ...] = (BasalRegion("no_slip"),)
    bed: Points | None = None
    """Bed elevation through these points (None: flat)."""
    initial: tuple[InitialEntry, ...] = ()
    left: str = "wall"
    right: str = "wall"
    inflow: Inflow | None = None
    gate: GateConfig | None = None
    cfl: float = 0.45
    numerics: Numerics = Numerics()
    pressure: PressureConfig = PressureConfig()
    normal_stress: bool = False
    """The longitudinal normal stress of the layers (:mod:`multilayer.engine.normal_stress`)."""
    mixture: MixtureConfig | None = None
    """A grain–fluid mixture (None: dry grains)."""
    name: str = "<scenario>"
    """How messages name the problem (the scenario file)."""

    def __post_init__(self) -> None:
        """The mesh the kernels index without checking, checked as a script builds it (the
        scenario's schema checks every key): no layer wrote outside the kernels' arrays
        ("double free or corruption", the process aborted), no cell divided by zero."""
        mesh = {"x_min": self.x_min, "x_max": self.x_max}
        if not all(isinstance(v, numbers.Real) and math.isfinite(v) for v in mesh.values()) or not (
            self.x_max > self.x_min
        ):
            raise InputError(f"{self.name}: SimulationConfig {mesh}; accepted: finite numbers, x_max > x_min")
        if isinstance(self.cells, bool) or not isinstance(self.cells, numbers.Integral) or self.cells < 1:
            raise InputError(f"{self.name}: SimulationConfig cells = {self.cells!r}; accepted: integers > 0")
        fractions = tuple(self.fractions)
        if not (
            fractions
            and all(isinstance(f, numbers.Real) and not isinstance(f, bool) and 0 < f <= 1 for f in fractions)
            and abs(math.fsum(fractions) - 1.0) <= FRACTIONS_SUM
        ):
            raise InputError(
                f"{self.name}: SimulationConfig fractions = {fractions!r:.60}; accepted: one number in "
                "(0, 1] per layer, at least one, summing to 1 (mesh.layer_fractions)"
            )
