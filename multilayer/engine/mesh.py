"""The X-sigma mesh: a FiPy ``Grid2D`` whose rows are the layers.

Columns are the finite volumes along the slope (``dx``), rows are the layers with
``dy = l_alpha`` (the fraction of the local thickness each layer holds), so cell
``(i, alpha)`` of the grid is layer ``alpha`` of column ``i``.  FiPy orders cells row by
row, hence a cell array reshaped to ``(L, N)`` is indexed ``[layer, column]``.
"""

from __future__ import annotations

import fipy
import numpy as np


class LayeredMesh:
    """Geometry of the multilayer model on a FiPy ``Grid2D`` in (x, sigma)."""

    def __init__(self, x_min: float, x_max: float, cells: int, fractions: np.ndarray):
        fractions = np.asarray(fractions, dtype=float)
        self.cells = int(cells)
        self.layers = fractions.size
        self.dx = (x_max - x_min) / self.cells
        self.grid = fipy.Grid2D(dx=self.dx, dy=fractions, nx=self.cells, ny=self.layers) + (
            (x_min,),
            (0.0,),
        )
        self.line = fipy.Grid1D(dx=self.dx, nx=self.cells) + ((x_min,),)
        centres = self.grid.cellCenters.value
        #: cell centres along the slope (N,)
        self.x = centres[0][: self.cells].copy()
        #: layer fractions l_alpha (L,)
        self.fractions = fractions
        #: layer centres as a fraction of h (L,)
        self.sigma = centres[1][:: self.cells].copy()
        #: interface positions as a fraction of h, from the bed (0) to the surface (1), (L+1,)
        self.interfaces = np.concatenate([[0.0], np.cumsum(fractions)])
        self.interfaces[-1] = 1.0

    def cell_variable(
        self, name: str, value: np.ndarray | float = 0.0, *, layered: bool
    ) -> fipy.CellVariable:
        """A state variable on the layered grid (``layered``) or on the line of columns."""
        return fipy.CellVariable(mesh=self.grid if layered else self.line, name=name, value=value)
