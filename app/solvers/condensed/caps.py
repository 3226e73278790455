"""The condensed solver for one body with rigid caps (``loads.rigid``): (3.4) in the unknown
z of the caps' elimination u = T z (app/model/rigidcap.py).

The bulk problem 1/2 u^T K u - F_n^T u becomes 1/2 z^T K_z z - F_z^T z with
K_z = T^T K T (the caps' fixed dofs, slaves and prescribed amplitudes, its identity rows and
columns, like the Dirichlet dofs) and F_z = T^T (F_n - K T z_D) + L(t), z_D the fixed
values (the lifting; F_z = z_D there) and L the caps' loads at their amplitudes.  The caps'
nodes are not Gamma3 nodes, so the Gamma3 dofs of z are those of u and the condensation,
the Gamma3 problem and its frames are the one body's.
"""
from __future__ import annotations

from petsc4py import PETSc


def cap_stiffness(K: PETSc.Mat, caps, T: PETSc.Mat) -> PETSc.Mat:
    """K_z = T^T K T with the caps' fixed rows and columns the identity (collective).

    Args:
        K: the elasticity matrix (AIJ; the Dirichlet rows and columns the identity).
        caps: the RigidCaps.
        T: the caps' elimination.

    Returns:
        The assembled AIJ matrix.
    """
    Kz = K.PtAP(T)
    start = Kz.getOwnershipRange()[0]
    Kz.zeroRowsColumns((caps.fixed + start).astype(PETSc.IntType), diag=1.0)
    return Kz


class CapRightHandSide:
    """F_z of the module docstring (collective), around the one body's F_n.

    Args:
        problem: the ContactProblem (its caps and time data).
        inner: the StepRightHandSide of F_n.
        K: the elasticity matrix of u (kept for the lifting K T z_D; freed with this).
        T: the caps' elimination.
    """

    def __init__(self, problem, inner, K: PETSc.Mat, T: PETSc.Mat):
        self.problem, self.inner, self.K, self.T = problem, inner, K, T
        self.F, self.w = K.createVecs()
        self.z, self.Kw = T.createVecs()

    def assemble(self, b: PETSc.Vec) -> None:
        """b = F_z for the current time data and history.

        Args:
            b: a vector of K_z's row layout, overwritten.
        """
        caps, t = self.problem.disc.caps, float(self.problem.time_data.t.value)
        self.inner.assemble(self.F)
        self.z.set(0.0)
        caps.fix(self.z, t)
        self.T.mult(self.z, self.w)
        self.K.mult(self.w, self.Kw)
        self.F.axpy(-1.0, self.Kw)
        self.T.multTranspose(self.F, b)
        caps.add_loads(b, t, 1.0)
        b.array[caps.fixed] = self.z.array_r[caps.fixed]

    def destroy(self) -> None:
        """Free the PETSc objects (K is this right-hand side's, T the solver's)."""
        self.inner.destroy()
        for obj in (self.K, self.F, self.w, self.z, self.Kw):
            obj.destroy()
