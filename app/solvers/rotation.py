"""Nodal frames as one linear map: the block-diagonal rotation R with the frame Q_i of every
Gamma3 node (app/model/frames.py) and the identity elsewhere.

SNES VI keeps exact box bounds on a curved Gamma3 by solving for x = R^T u, the displacement
in the nodal frames, where u_nu of node i is one dof: its residual is R^T F(R x) and its
Jacobian R^T J R (PETSc's PtAP).  R is orthogonal, so norms, the Newton iterates and the
solution are those of the original problem, rotated.  Dirichlet conditions stay conditions on
single dofs: a prescribed axis keeps its own column in Q_i.
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc


def rotation_matrix(problem) -> PETSc.Mat:
    """R = diag(Q_i) over the owned nodes (identity where there is no frame).

    Args:
        problem: the ContactProblem (V, frames).

    Returns:
        The assembled AIJ matrix with u's row and column layout.
    """
    V, d, fr = problem.V, problem.dim, problem.frames
    imap = V.dofmap.index_map
    n = imap.size_local
    blocks = np.broadcast_to(np.eye(d), (n, d, d)).copy()
    owned = fr.nodes < n
    blocks[fr.nodes[owned]] = fr.Q[owned]
    start = imap.local_range[0] * d
    cols = start + (np.arange(n)[:, None, None] * d + np.arange(d)[None, None, :])
    indices = np.broadcast_to(cols, (n, d, d)).reshape(-1).astype(PETSc.IntType)
    indptr = np.arange(0, n * d * d + 1, d, dtype=PETSc.IntType)
    R = PETSc.Mat().createAIJ(size=((n * d, PETSc.DECIDE), (n * d, PETSc.DECIDE)),
                              csr=(indptr, indices, blocks.reshape(-1)), comm=problem.comm)
    R.assemble()
    return R


class FrameMap:
    """The residual and Jacobian of the step problem in the nodal frames.

    Args:
        problem: the ContactProblem with rotated frames.
        template: a vector like u (ghosted), for the work vectors.
    """

    def __init__(self, problem, template: PETSc.Vec):
        self.R = rotation_matrix(problem)
        self.u_work, self.F_work = template.duplicate(), template.duplicate()

    def to_frames(self, u: PETSc.Vec, x: PETSc.Vec) -> None:
        """x = R^T u.

        Args:
            u: the displacement (global frame).
            x: output, in the nodal frames.
        """
        self.R.multTranspose(u, x)

    def from_frames(self, x: PETSc.Vec, u: PETSc.Vec) -> None:
        """u = R x.

        Args:
            x: the displacement in the nodal frames.
            u: output (global frame; ghosts not updated).
        """
        self.R.mult(x, u)

    def destroy(self) -> None:
        """Free the PETSc objects."""
        for obj in (self.R, self.u_work, self.F_work):
            obj.destroy()
