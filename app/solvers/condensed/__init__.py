"""The condensed step solver: (3.4) condensed onto the Gamma3 dofs.

One factorisation of the elasticity matrix K per run (a ``Condensation``: CHOLMOD serially,
MUMPS with Schur variables under mpirun, PETSc's direct solver otherwise); per step the
right-hand side F_n = f_n - B^T H_n is condensed onto Gamma3 (y0), the small Gamma3 problem
with the nodal contact energy is solved by projected Newton (``Gamma3Problem``, on one rank
under mpirun), and its solution y is expanded to the whole body.  Modules:
    solver.py        CondensedStepSolver, the StepSolver composing the parts below
    condensation.py  the Condensation interface and the choice of back end (factorise)
    cholmod.py, mumps.py, petsc.py   the three back ends
    problem.py       Gamma3Problem: projected Newton, forcing, warm start, the root call
    frames.py        WorkFrames: the Gamma3 problem's coordinates and bounds
    layout.py        Gamma3Layout: the Gamma3 dofs over the ranks
    rhs.py           StepRightHandSide: F_n
    pairs.py         two bodies (contact.pairs): the problem in x of app/solvers/pairmap.py,
                     G = the surface nodes and the target nodes coupled to them, the
                     coupling C_G of the contact energy (PairLayout, PairCoupling, ...)
"""
from __future__ import annotations

from vpcontact.solvers.condensed.condensation import Condensation, factorise
from vpcontact.solvers.condensed.solver import CondensedStepSolver

__all__ = ["Condensation", "CondensedStepSolver", "factorise"]
