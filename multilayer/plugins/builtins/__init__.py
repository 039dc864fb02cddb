"""Built-in rheologies of ``multilayer`` (docs/model.md, "Rheologies").

They are registered through the same entry point and hook as third-party plugins
(``[project.entry-points.multilayer] builtins = "multilayer.plugins.builtins"``).
"""

from collections.abc import Callable

from multilayer.plugins.builtins.dilatant_coulomb import DilatantCoulomb
from multilayer.plugins.builtins.drucker_prager import DruckerPrager
from multilayer.plugins.builtins.jop_mu_i import JopMuI
from multilayer.plugins.builtins.pouliquen_forterre import PouliquenForterre
from multilayer.plugins.builtins.power_law_mu_i import PowerLawMuI
from multilayer.plugins.builtins.wall_friction import WallFriction
from multilayer.plugins.contract import Rheology
from multilayer.plugins.host import hookimpl

__all__ = ["DilatantCoulomb", "DruckerPrager", "JopMuI", "PouliquenForterre", "PowerLawMuI", "WallFriction"]


@hookimpl
def multilayer_register_rheologies(register: Callable[[type[Rheology]], None]) -> None:
    """Register the built-in laws."""
    for cls in (DilatantCoulomb, DruckerPrager, JopMuI, PouliquenForterre, PowerLawMuI, WallFriction):
        register(cls)
