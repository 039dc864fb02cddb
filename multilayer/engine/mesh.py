"""The X-sigma mesh: columns along the slope, layers of fixed fractions across the flow.

Columns are the finite volumes along the slope (``dx``), rows are the layers with
``dy = l_alpha`` (the fraction of the local thickness each layer holds), so cell
``(i, alpha)`` is layer ``alpha`` of column ``i`` and a cell array reshaped to ``(L, N)``
is indexed ``[layer, column]`` (FiPy's row-by-row order of a ``Grid2D``).

The geometry the engine needs (centres, fractions, interfaces) is computed directly.  The
FiPy ``Grid2D`` of the same mesh (``grid``) and the line of columns (``line``) are built on
first use only: FiPy stores about 2 kB per cell and builds a mesh at about 55 us per cell
(measured at 100 000 x 32), which would dominate the memory and the start of large runs
that never use it (docs/performance.md).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import fipy


def cell_centres(x_min: float, x_max: float, cells: int) -> np.ndarray:
    """The centres ``x_min + (i + 1/2) dx`` of ``cells`` equal cells on ``[x_min, x_max]`` (m)."""
    dx = (x_max - x_min) / cells
    return float(x_min) + dx * (np.arange(cells) + 0.5)


def layer_fractions(layers: int, rule: str | Sequence[float] | Mapping[str, float] = "uniform") -> np.ndarray:
    """Layer fractions ``l_1 .. l_L`` (bottom to top), (L,), summing to 1, by the rule of the
    scenario key ``domain.layer_fractions``: ``uniform``, ``1/L``; a list, as given
    (renormalised to round-off); ``{geometric: r}``, ``l_a`` proportional to ``r**(a-1)``
    (thin layers at the bed for r > 1)."""
    if isinstance(rule, Mapping):
        weights = float(rule["geometric"]) ** np.arange(layers)
    elif isinstance(rule, str):
        weights = np.ones(layers)
    else:
        weights = np.asarray(rule, dtype=float)
    return weights / weights.sum()


class LayeredMesh:
    """Geometry of the multilayer model in (x, sigma); FiPy meshes on demand.

    Its arrays are read-only: a mesh is fixed once made, and a caller who shifts
    ``mesh.x`` for a plot must not move the cells of a run.
    """

    def __init__(self, x_min: float, x_max: float, cells: int, fractions: np.ndarray):
        fractions = np.array(fractions, dtype=float)
        self.cells = int(cells)
        self.layers = fractions.size
        self.x_min = float(x_min)
        self.dx = (x_max - x_min) / self.cells
        #: cell centres along the slope (N,)
        self.x = cell_centres(x_min, x_max, self.cells)
        #: layer fractions l_alpha (L,)
        self.fractions = fractions
        #: interface positions as a fraction of h, from the bed (0) to the surface (1), (L+1,)
        self.interfaces = np.concatenate([[0.0], np.cumsum(fractions)])
        self.interfaces[-1] = 1.0
        #: layer centres as a fraction of h (L,)
        self.sigma = 0.5 * (self.interfaces[:-1] + self.interfaces[1:])
        for array in (self.x, self.fractions, self.interfaces, self.sigma):
            array.flags.writeable = False

    @cached_property
    def grid(self) -> fipy.Grid2D:
        """The FiPy ``Grid2D`` in (x, sigma): ``cells`` columns, ``L`` rows of height ``l_alpha``."""
        import fipy

        return fipy.Grid2D(dx=self.dx, dy=self.fractions, nx=self.cells, ny=self.layers) + (
            (self.x_min,),
            (0.0,),
        )

    @cached_property
    def line(self) -> fipy.Grid1D:
        """The FiPy ``Grid1D`` of the columns."""
        import fipy

        return fipy.Grid1D(dx=self.dx, nx=self.cells) + ((self.x_min,),)

    def cell_variable(
        self, name: str, value: np.ndarray | float = 0.0, *, layered: bool
    ) -> fipy.CellVariable:
        """A FiPy variable on the layered grid (``layered``) or on the line of columns."""
        import fipy

        return fipy.CellVariable(mesh=self.grid if layered else self.line, name=name, value=value)
