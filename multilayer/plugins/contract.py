"""The rheology plugin contract: a stress law split into a yield part and a viscous part.

Every law is written as (Bouchut, Ionescu & Mangeney 2016, eq. 1.3-1.8)::

    tau = kappa(p) sgn(gamma) + eta(|gamma|, p) gamma    if gamma != 0
    |tau| <= kappa(p)                                    if gamma == 0

``kappa`` is returned by :meth:`Rheology.yield_stress`, ``eta`` by
:meth:`Rheology.viscosity`.  The engine treats the yield part exactly (never by
regularising ``sgn``) and iterates on the viscous part.

A law may also declare a larger yield stress for material at rest, the start/stop
(hysteretic) friction of Pouliquen & Forterre (2002): :meth:`Rheology.static_yield_stress`
applies at an interface whose two adjacent layers were both at rest at the start of the
step, :meth:`Rheology.yield_stress` everywhere else.  It is optional: by default it is the
flowing yield stress, so laws written without it behave as before.

A law that needs a quantity of its column declares it in :attr:`Rheology.uses`; the engine
then passes it to :meth:`~Rheology.yield_stress`, :meth:`~Rheology.static_yield_stress` and
:meth:`~Rheology.viscosity` as a keyword argument of the shape of the pressure array.
``"thickness"``: the thickness ``h`` of the column (m), the same at every interface and
layer of a column (for a law with a thickness below which flow stops, Pouliquen & Forterre
2002).  Laws that declare nothing are called exactly as before.

In a grain–fluid mixture (docs/mixture.md) the engine passes the effective (grain-contact)
pressure ``p_s`` as ``pressure`` (Terzaghi's principle) and calls
:meth:`Rheology.mixture_yield_stress` and :meth:`Rheology.mixture_viscosity`, which also
receive the :class:`MixtureState`; by default they ignore it and call
:meth:`~Rheology.yield_stress` and :meth:`~Rheology.viscosity`, so every law runs in a
mixture as a law of the effective pressure.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np


@dataclass(frozen=True)
class Material:
    """Material constants handed to every rheology call (SI units)."""

    density: float
    """Bulk density rho of the granular layer, kg/m^3."""
    grain_diameter: float
    """Grain diameter d, m."""
    particle_density: float
    """Density rho_p of the grains, kg/m^3 (enters the inertial number)."""


@dataclass(frozen=True)
class MixtureState:
    """What a law may read of a grain–fluid mixture at the interfaces of a call (arrays of
    the shape of ``pressure``): the solid volume fraction ``phi`` of the layer above each
    interface and the excess pore pressure (Pa) there, with the constants of the
    dilatancy closure (Bouchut, Fernández-Nieto, Mangeney & Narbona-Reina 2016)."""

    phi: np.ndarray
    pore_pressure: np.ndarray
    fluid_viscosity: float
    """eta_f, Pa s."""
    phi_critical: float
    dilatancy: float
    """K of ``tan(psi) = K (phi - phi_eq)``."""
    critical_shift: float
    """K2 of ``phi_eq = phi_c - K2 eta_f gamma / p_s``."""


COLUMN_QUANTITIES = ("thickness",)
"""The column quantities the engine gives a law that declares them in :attr:`Rheology.uses`."""


class Rheology:
    """Base class of rheology plugins.

    Subclasses set ``name`` (the YAML ``name``), ``applies_to`` (``"bulk"`` for the
    stress between layers and at a no-slip bed, ``"walls"`` for side-wall friction) and
    take their parameters as keyword arguments of ``__init__`` (these keyword
    arguments are the parameter schema of the scenario file).
    """

    name: ClassVar[str]
    applies_to: ClassVar[Literal["bulk", "walls"]] = "bulk"
    uses: ClassVar[tuple[Literal["thickness"], ...]] = ()
    """The column quantities the law is given as keyword arguments (module docstring), a
    tuple of names of :data:`COLUMN_QUANTITIES`."""

    def yield_stress(self, pressure: np.ndarray, material: Material) -> np.ndarray:
        """Rate-independent yield stress kappa(p) >= 0, in Pa."""
        raise NotImplementedError

    def static_yield_stress(self, pressure: np.ndarray, material: Material) -> np.ndarray:
        """Yield stress of material at rest, in Pa (>= the flowing one for a start/stop law).

        Default: :meth:`yield_stress` (no hysteresis).
        """
        return self.yield_stress(pressure, material)

    def viscosity(self, shear_rate: np.ndarray, pressure: np.ndarray, material: Material) -> np.ndarray:
        """Rate-dependent part eta(|gamma|, p) >= 0, in Pa s, finite at gamma = 0."""
        raise NotImplementedError

    def mixture_yield_stress(
        self, pressure: np.ndarray, mixture: MixtureState, material: Material
    ) -> np.ndarray:
        """Yield stress (Pa) at the effective pressure ``pressure`` in a grain–fluid mixture.

        Default: :meth:`yield_stress` (the law ignores the solid fraction)."""
        return self.yield_stress(pressure, material)

    def mixture_viscosity(
        self, shear_rate: np.ndarray, pressure: np.ndarray, mixture: MixtureState, material: Material
    ) -> np.ndarray:
        """Viscous part (Pa s) at the effective pressure in a grain–fluid mixture.

        Default: :meth:`viscosity`."""
        return self.viscosity(shear_rate, pressure, material)

    def mixture_kernel(self, material: Material) -> tuple[str, tuple[float, ...]] | None:
        """Optional: ``mixture_yield_stress`` and ``mixture_viscosity`` as a compiled form of
        the engine, so that the local step of a mixture of one layer runs compiled
        (docs/plugins.md, "Compiled forms").

        Returns ``(form, parameters)``; the one form: ``("dilatant", (tan_delta, K1))``,
        ``max(tan_delta + K (phi - phi_c), 0) max(p_s, 0)`` and ``(K1 + K K2) eta_f`` with the
        mixture's constants (``dilatant_coulomb``).  The default, None, keeps the law's own
        methods (numpy path).
        """
        return None

    def viscosity_kernel(self, material: Material) -> tuple[str, tuple[float, ...]] | None:
        """Optional: the viscous part as one of the compiled forms of the engine, so that
        the vertical step runs entirely compiled (docs/plugins.md, "Compiled forms").

        Returns ``(form, parameters)`` with ``viscosity`` equal to, for ``p = max(p, 0)``:

        * ``("constant", (eta,))``: ``eta``;
        * ``("inertial", (A, B, C))``: ``A p / (B sqrt(p) + C |gamma|)``, 0 where the
          denominator is 0 (Jop et al. 2006 mu(I));
        * ``("inertial_quadratic", (A, B, C, D))``: ``(A p + D |gamma| sqrt(p)) / (B sqrt(p)
          + C |gamma|)``, 0 where the denominator is 0 (mu(I) with Barker & Gray's 2017
          high-I term), ``B > 0``;
        * ``("power", (A, e_p, e_g, floor))``: ``A p^e_p max(|gamma|, floor)^e_g``;
        * for a law with ``uses = ("thickness",)`` only, ``("inertial_plateau", (A, B, C,
          D, L))``: ``max(0, A p |gamma| / (B sqrt(p) + C |gamma|) - D p / (1 + h / L)) /
          |gamma|``, 0 at rest, ``h`` the column thickness (``pouliquen_forterre``).

        The default, None, keeps this law on the numpy path (always correct).
        """
        return None

    def yield_stress_kernel(self, material: Material) -> tuple[str, tuple[float, ...]] | None:
        """Optional: the yield part as a compiled form of the engine, so that the
        velocity-independent coefficients of the vertical step are computed in one compiled
        pass (docs/plugins.md, "Compiled forms").

        Returns ``("frictional", (mu, mu_static))`` with :meth:`yield_stress` equal to
        ``mu max(p, 0)`` and :meth:`static_yield_stress` to ``mu_static max(p, 0)``; for a
        law with ``uses = ("thickness",)``, ``("frictional_thickness", (mu, mu_static, D,
        L))``: ``mu`` and ``mu_static`` each plus ``D / (1 + h / L)``, ``h`` the column
        thickness (``pouliquen_forterre``).
        The default, None, keeps the plugin's own methods (always correct).
        """
        return None
