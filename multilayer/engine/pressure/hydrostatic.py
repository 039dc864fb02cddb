"""``model.pressure: hydrostatic``: the pressure of the shallow model, ``p = rho g cos(theta)
(h - z)``, in the yield stresses; the velocities of the vertical step are the step's
(docs/model.md)."""

from __future__ import annotations

from multilayer.engine.pressure.model import PressureModel


class Hydrostatic(PressureModel):
    """The hydrostatic pressure (everything as :class:`PressureModel` does by default)."""

    name = "hydrostatic"
