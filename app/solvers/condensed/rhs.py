"""The right-hand side of the condensed solver's linear step: F_n = f_n - B^T H_n.

K u = F_n is the bulk part of the step problem (3.4) with the history term H_n of (3.2) at
u = 0: the loads f_n by assembly, the pre-stress by B^T, the transposed cell-strain operator,
and prescribed displacements u_D by lifting (b -= K_{:,D} u_D, b_D = u_D).
"""
from __future__ import annotations

from dolfinx import fem
from petsc4py import PETSc


class StepRightHandSide:
    """Assembles F_n for the current time data and history (collective).

    Args:
        problem: the ContactProblem (load_vector, H, strain_operator, Dirichlet data).
        a: the compiled bilinear form of K (for the lifting).
    """

    def __init__(self, problem, a):
        self.problem, self.a = problem, a
        self._lift = None if problem.disc.dirichlet.homogeneous else problem.u.vector.duplicate()

    def assemble(self, b: PETSc.Vec) -> None:
        """b = F_n = f_n - B^T H_n (zero at the clamped dofs, u_D at the prescribed ones).

        Args:
            b: a vector of K's row layout, overwritten.
        """
        p = self.problem
        if p.load_vector is not None:        # assembled once if the loads do not change
            b.array[:] = p.load_vector.at_current_time().array_r
        else:
            b.set(0.0)
        if p.H is not None:
            p.strain_operator.pre_stress_load(p.H, b)        # b -= B^T H_n
        disc = p.disc
        if disc.dirichlet.homogeneous:
            fem.petsc.set_bc(b, disc.bcs, scale=0.0)
            return
        lift = self._lift
        with lift.localForm() as loc:
            loc.set(0.0)
        fem.petsc.apply_lifting(lift, [self.a], [disc.bcs])
        lift.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        b.array[:] += lift.array_r
        fem.petsc.set_bc(b, disc.bcs)

    def destroy(self) -> None:
        """Free the PETSc vectors."""
        if self._lift is not None:
            self._lift.destroy()
