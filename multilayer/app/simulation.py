"""``multilayer.Simulation(scenario)``: the engine's simulation of a scenario (docs/api.md)."""

from __future__ import annotations

from multilayer.app import factory, numba_environment
from multilayer.engine import simulation
from multilayer.errors import InputError
from multilayer.scenario import Scenario
from multilayer.scenario.messages import shown


class Simulation(simulation.Simulation):
    """``multilayer.Simulation(scenario)``: the engine's
    :class:`~multilayer.engine.simulation.Simulation` of a validated scenario (from
    :func:`multilayer.load`), which it keeps as ``scenario``.  numba's variables are
    checked first (:func:`multilayer.app.numba_environment.check`): numba reads
    ``NUMBA_THREADING_LAYER`` at its first parallel kernel, where an unknown layer was
    numba's own ``ValueError``, mid-run."""

    def __init__(self, scenario: Scenario):
        if not isinstance(scenario, Scenario):
            raise InputError(
                f"Simulation: got {shown(scenario)}; accepted: a Scenario, as multilayer.load returns "
                "it from a file or a mapping"
            )
        numba_environment.check()
        self.scenario = scenario
        bulk, walls = factory.laws(scenario)
        super().__init__(
            factory.engine_config(scenario),
            bulk,
            walls,
            column_solver=factory.column_solver(scenario.numerics.vertical_solver),
        )
