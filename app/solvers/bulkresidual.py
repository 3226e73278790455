"""The residual of (3.4) with the explicit scheme from the kept bulk matrix, for SNES VI.

With the explicit scheme the bulk part of the residual is linear in u:
    F(u) = K u + c_n + F_Gamma3(u),   c_n = (H_n, eps(v)) - f_n(v),
K = (E eps(du), eps(v)) the bulk Jacobian, which SNES VI assembles once per run
(app/solvers/snesvi.py), H_n and f_n fixed during a step's solve.  So a residual evaluation
is one product with K, the sum with c_n (assembled once per solve) and the assembly of the
Gamma3 terms alone, instead of a volume assembly over every cell and its packing and lifting
(docs/performance.md, section 9).

The Dirichlet conditions as in dolfinx's nonlinear residual (assemble, lift with the
Jacobian at x, set_bc(b, bcs, x, -1)): rows i off the Dirichlet dofs D get
    sum_{j not in D} K_ij x_j + [c_n + K_iD g_D] + F_Gamma3,i(x) + J_Gamma3,iD(x) (g_D - x_D),
the first term the product with SNES VI's matrix (D's rows and columns zero, diagonal 1),
the bracket assembled once per solve (the load lifted with K at x0 = 0), the last two the
Gamma3 terms lifted with their own Jacobian at x.  SNES VI's matrix holds K + B (B the Gamma3
Jacobian, written in place at the entries of B's rows R, app/solvers/snesvi.GammaEntries):
the product's rows R are taken from K_R, K's rows R kept apart (a surface's rows), not as
(K + B) x - B x, whose subtraction would leave B's round-off (a stiff compliance: B ~ 1e16 K)
in the residual.
"""
from __future__ import annotations

import numpy as np
from dolfinx import fem
from petsc4py import PETSc


class BulkProductResidual:
    """F(x) of the explicit scheme as K x + c_n + the Gamma3 terms (see the module).

    Args:
        problem: the ContactProblem (its forms: bulk_load, boundary_residual; bcs).
        bulk_form: the compiled bulk Jacobian K (for the lifting of c_n).
        boundary_form: the compiled Gamma3 Jacobian, or None without Gamma3 terms.
        b: a vector of the residual's layout (ghosted; duplicated for the work vectors).
    """

    def __init__(self, problem, bulk_form, boundary_form, b: PETSc.Vec):
        forms = problem.forms
        self.bcs = problem.disc.bcs
        self._K_form, self._B_form = bulk_form, boundary_form
        self._load = fem.form(forms.bulk_load) if forms.bulk_load is not None else None
        self._contact = (fem.form(forms.boundary_residual)
                         if forms.boundary_residual is not None else None)
        self.c, self.work = b.duplicate(), b.duplicate()
        self.current = False
        self.K_R = self.y_R = self.rows_local = None

    def keep_rows(self, A: PETSc.Mat, rows: np.ndarray) -> None:
        """Keep K's rows R apart, while A holds K alone (before B first enters A).

        Args:
            A: SNES VI's matrix, holding K (Dirichlet rows and columns zero, diagonal 1).
            rows: the global rows R that B writes (owned by this rank).
        """
        rows = np.asarray(rows, dtype=PETSc.IntType)
        start, end = A.getOwnershipRange()
        isrow = PETSc.IS().createGeneral(rows, comm=A.comm)
        iscol = PETSc.IS().createStride(end - start, first=start, step=1, comm=A.comm)
        self.K_R = A.createSubMatrix(isrow, iscol)
        self.y_R = self.K_R.createVecLeft()
        self.rows_local = rows - start
        isrow.destroy()
        iscol.destroy()

    def new_solve(self) -> None:
        """H_n, f_n or g_n may have changed: c_n is assembled again at the next residual."""
        self.current = False

    def __call__(self, A: PETSc.Mat, x: PETSc.Vec, b: PETSc.Vec) -> None:
        """b = F(x) with the Dirichlet rows x_D - g_D (x's ghosts up to date, the Gamma3
        terms' coefficients at x).

        Args:
            A: the matrix K x is formed with: SNES VI's matrix (K + B; its rows R from
                K_R, once ``keep_rows`` was called) or a copy of K.
            x: the iterate.
            b: the residual (written).
        """
        if not self.current:
            self._constant()
        A.mult(x, b)
        if self.K_R is not None:
            self.K_R.mult(x, self.y_R)
            b.array[self.rows_local] = self.y_R.array_r
        b.axpy(1.0, self.c)
        if self._contact is not None:
            self._assemble(self.work, self._contact, self._B_form, x)
            b.axpy(1.0, self.work)
        fem.petsc.set_bc(b, self.bcs, x, -1.0)

    def _constant(self) -> None:
        """c_n + K_.D g_D: the bulk residual at x = 0, lifted (collective)."""
        self._assemble(self.c, self._load, self._K_form, None)
        self.current = True

    def _assemble(self, vec, form, jacobian, x0) -> None:
        """vec = form (zero if None) lifted with jacobian at x0 (None: 0), ghosts summed."""
        with vec.localForm() as local:
            local.set(0.0)
        if form is not None:
            fem.petsc.assemble_vector(vec, form)
        fem.petsc.apply_lifting(vec, [jacobian], [self.bcs],
                                x0=[x0] if x0 is not None else [], scale=-1.0)
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)

    def destroy(self) -> None:
        """Free the PETSc objects."""
        for obj in (self.c, self.work, self.K_R, self.y_R):
            if obj is not None:
                obj.destroy()
