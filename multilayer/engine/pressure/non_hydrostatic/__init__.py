"""``model.pressure: non_hydrostatic``: a vertical velocity per layer and a non-hydrostatic
pressure, projected each step after the vertical step (docs/nonhydrostatic.md;
Fernandez-Nieto, Parisot, Penel & Sainte-Marie 2018).

The projection (:mod:`.projection`) assembles the layer divergence constraint
(:mod:`.constraint`) and solves its normal equations with the pressure bound ``p >= 0``
(:mod:`.banded`); those are imported when a model is made, not to name it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from multilayer.engine.pressure.model import Option, PressureModel, PressureSetup

if TYPE_CHECKING:
    from multilayer.engine.state import FlowState

DEFAULT_PRESSURE_LAYERS = 4
"""The pressure layers by default, at most the layers (docs/nonhydrostatic.md, "Fewer pressure layers")."""


class NonHydrostatic(PressureModel):
    """The pressure of the last projection (of its update) in the yield stresses; the
    velocities of the vertical step projected on the constraint; ``w`` and ``q`` kept in
    the state, and the velocities before the projection as the seed of the next Newton
    iteration (they keep the plugs, layers locked together, that the per-layer corrections
    would break; where that seed does not converge the iteration starts again from the
    state's velocities)."""

    name = "non_hydrostatic"
    options = {
        "pressure_layers": Option(
            accepted="an integer from 1 to domain.layers = {layers}",
            valid=lambda value, layers: type(value) is int and 1 <= value <= layers,
            default=lambda layers: min(DEFAULT_PRESSURE_LAYERS, layers),
        ),
        "vertical_shear": Option(
            accepted="true or false",
            valid=lambda value, layers: type(value) is bool,
            default=lambda layers: False,
        ),
    }
    checked = {"w": "vertical velocity w", "q": "non-hydrostatic pressure q"}

    def __init__(self, setup: PressureSetup, state: FlowState):
        from multilayer.engine.pressure.non_hydrostatic.projection import Projection
        from multilayer.engine.vertical_shear import VerticalShear

        super().__init__(setup, state)
        self.layers: int = setup.options["pressure_layers"]
        sizes = {"dx": setup.dx, "dry": setup.dry, "g_n": setup.g_n}
        shear = None
        if setup.options["vertical_shear"]:
            if setup.stresses is None:
                raise ValueError(
                    "model.vertical_shear needs the vertical step's laws (PressureSetup.stresses)"
                )
            shear = VerticalShear(setup.stresses, setup.fractions, solver=setup.solver, **sizes)
        self.projection = Projection(
            setup.fractions,
            setup.bed,
            periodic=setup.wraps,
            pressure_layers=self.layers,
            shear=shear,
            **sizes,
        )
        self._seed = state.add_field("newton_seed", default="u")

    def found_finite(self) -> bool:
        return self.projection.finite

    def yield_gravity(self, state: FlowState, h: np.ndarray) -> np.ndarray:
        return self.projection.yield_gravity(state.q, h, state.window)

    def seeds(self, state: FlowState) -> tuple[np.ndarray, ...]:
        return (self._seed, state.u)

    def project(
        self, state: FlowState, h: np.ndarray, u: np.ndarray, dt: float
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        projected, w, q = self.projection(h, u, (state.h, state.u, state.w, state.q), dt, state.window)
        return projected, {"w": w, "q": q, "newton_seed": u}
