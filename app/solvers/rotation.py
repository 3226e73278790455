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


def rotation_matrix(disc) -> PETSc.Mat:
    """R = diag(Q_i) over the owned nodes (identity where there is no frame, or no Gamma3).

    Args:
        disc: the Discretisation (V, frames).

    Returns:
        The assembled AIJ matrix with u's row and column layout.
    """
    V, d, fr = disc.V, disc.dim, disc.frames
    imap = V.dofmap.index_map
    n = imap.size_local
    blocks = np.broadcast_to(np.eye(d), (n, d, d)).copy()
    if fr is not None:                          # no contact: the identity
        owned = fr.nodes < n
        blocks[fr.nodes[owned]] = fr.Q[owned]
    start = imap.local_range[0] * d
    cols = start + (np.arange(n)[:, None, None] * d + np.arange(d)[None, None, :])
    indices = np.broadcast_to(cols, (n, d, d)).reshape(-1).astype(PETSc.IntType)
    indptr = np.arange(0, n * d * d + 1, d, dtype=PETSc.IntType)
    R = PETSc.Mat().createAIJ(size=((n * d, PETSc.DECIDE), (n * d, PETSc.DECIDE)),
                              csr=(indptr, indices, blocks.reshape(-1)), comm=disc.comm)
    R.assemble()
    return R


class FrameMap:
    """The residual and Jacobian of the step problem of one body in the nodal frames and,
    with rigid caps (app/model/rigidcap.py), in the caps' amplitudes: u = M x with M = T R
    (T the caps' elimination, the identity without caps; the caps' nodes have no frame, so T
    and R commute), x = R^T T^+ u; the residual M^T F(M x) and the Jacobian M^T J M, the
    identity with a zero residual at the caps' fixed dofs (``caps.fixed``).

    Args:
        problem: the ContactProblem with rotated frames or rigid caps.
        template: a vector like u (ghosted), for the work vectors.
    """

    def __init__(self, problem, template: PETSc.Vec):
        self.problem, self.caps = problem, problem.disc.caps
        self.R = rotation_matrix(problem.disc)
        self.T = self.T_inv = None
        self.M = self.R
        if self.caps is not None:
            self.T, self.T_inv = self.caps.matrices()
            self.M = self.T.matMult(self.R)
        self.u_work, self.F_work = template.duplicate(), template.duplicate()
        self.fixed = np.zeros(0, PETSc.IntType) if self.caps is None else self.caps.fixed
        start = template.getOwnershipRange()[0]
        self.fixed_global = (self.fixed + start).astype(PETSc.IntType)

    def to_frames(self, u: PETSc.Vec, x: PETSc.Vec) -> None:
        """x = R^T T^+ u, the caps' fixed dofs at their values.

        Args:
            u: the displacement (global frame).
            x: output, in the nodal frames.
        """
        if self.T_inv is None:
            self.R.multTranspose(u, x)
            return
        self.T_inv.mult(u, self.F_work)
        self.R.multTranspose(self.F_work, x)
        self.fix(x)

    def fix(self, x: PETSc.Vec) -> None:
        """The caps' fixed dofs of x at their values at the step's t (none without caps).

        Args:
            x: the unknown.
        """
        if self.caps is not None:
            self.caps.fix(x, float(self.problem.time_data.t.value))

    def from_frames(self, x: PETSc.Vec, u: PETSc.Vec) -> None:
        """u = M x.

        Args:
            x: the displacement in the nodal frames.
            u: output (global frame; ghosts not updated).
        """
        self.M.mult(x, u)

    def pull_back(self, F: PETSc.Vec, b: PETSc.Vec) -> None:
        """b = M^T F less the caps' loads, zero at their fixed dofs.

        Args:
            F: the residual in u.
            b: output, in x.
        """
        self.M.multTranspose(F, b)
        if self.caps is not None:
            self.caps.add_loads(b, float(self.problem.time_data.t.value), -1.0)
            b.array[self.fixed] = 0.0

    def product(self, J: PETSc.Mat, result: PETSc.Mat | None = None) -> PETSc.Mat:
        """M^T J M, the identity at the caps' fixed dofs.

        Args:
            J: the Jacobian in u.
            result: the matrix of an earlier product (its pattern), or None.

        Returns:
            The product.
        """
        A = J.PtAP(self.M, result=result)
        if self.caps is not None:
            A.zeroRowsColumns(self.fixed_global, diag=1.0)
        return A

    def destroy(self) -> None:
        """Free the PETSc objects."""
        for obj in (self.R, self.u_work, self.F_work, self.T, self.T_inv):
            if obj is not None:
                obj.destroy()
        if self.caps is not None:
            self.M.destroy()
