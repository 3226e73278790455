"""Derived fields that solution.xdmf writes beside the State's own: the full stress sigma
(in 2D plane strain with sigma_33 of app/model/fullstress.py).

dolfinx 0.5 writes a 2D DG0 d x d tensor per cell as 9 components (row-major 3 x 3) with
the out-of-plane ones 0, and a 3 x 3 tensor on a 2D mesh not per cell at all; so in plane
strain ``sigma`` is written by dolfinx and its component 8 (sigma_33) replaced by the cells'
sigma_33 after (FieldWriter.write's ``columns``): the file keeps its size and layout.
"""
from __future__ import annotations

import numpy as np


class StressOutput:
    """The columns of the written ``sigma`` to replace: none in 3D (the full tensor) and 2D
    plane stress (sigma_33 = 0 by definition); in 2D plane strain sigma_33 (component 8).

    Args:
        problem: the ContactProblem (its sigma, sigma_33 and owned cells).
    """

    def __init__(self, problem):
        self.problem = problem

    def columns(self) -> dict | None:
        """The replaced components, for FieldWriter.write.

        Returns:
            {("sigma", 8): sigma_33 of the owned cells in local cell order}, or None.
        """
        p = self.problem
        if p.sigma_33 is None:
            return None
        rows = np.asarray(p.Y.dofmap.list.array)[:p.num_owned_cells]
        return {("sigma", 8): p.sigma_33.x.array[rows]}
