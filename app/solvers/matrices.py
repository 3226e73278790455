"""Copies of PETSc matrices that keep a matrix's nonzero pattern (app/solvers/snesvi.py's
Jacobian, bulk stiffness and round-off floor; app/solvers/amg.py's embedded Jacobian)."""
from __future__ import annotations

from petsc4py import PETSc


def share_pattern(A: PETSc.Mat):
    """How to duplicate a matrix that keeps A's nonzero pattern: sharing A's column
    indices where PETSc can (AIJ: a third less memory per copy; docs/performance.md,
    section 9), else as a copy of A's values (BAIJ).

    Args:
        A: the matrix.

    Returns:
        The ``copy`` argument of ``Mat.duplicate``.
    """
    if A.getType() in ("seqaij", "mpiaij"):
        return PETSc.Mat.DuplicateOption.SHARE_NONZERO_PATTERN
    return True
