"""SNES VI for two bodies in contact: the bound on a combination of dofs made a box bound
by a change of variables.

The bound of a pair, [u]_nu - d_i <= g with [u]_i = u_i - sum_k N_ik u_k
(app/model/pairs.py), bounds a combination of dofs, which SNES VI cannot do.  The unknown x
is therefore u in the nodal frames (app/solvers/rotation.py: u = R y) with the slot dof of
each Gamma3 node replaced by sign_i ([u]_nu - d_i):

    u = P x + c,   P = R (I + S),   c = d_i nu_i at the Gamma3 nodes,
    x = (I - S) R^T (u - c),

where S (``PairOperators.lift`` = I + S) couples the slot dof of node i to the target nodes
of its projection.  The bound is then the box sign_i x_slot <= g (``Discretisation.bounds``),
P is invertible and the Newton matrix P^T K P + C^T J_w C stays symmetric (positive definite where
J_n is convex).  The Gamma3 terms are evaluated on w = B u - c_w = C x with C = B P
(``PairOperators``), so

    F(x) = P^T F_bulk(P x + c) + C^T F_w(C x),   J(x) = P^T K P + C^T J_w C.

Dirichlet dofs keep their index (they are never slot dofs, and target dofs keep x = u): x
takes their values before each solve, and their rows and columns are the identity with a
zero residual, so Newton never moves them.

Rigid caps (app/model/rigidcap.py) add their elimination T on the left, u = T (R (I + S) x
+ c): P = T R (I + S) and x = (I - S) R^T (T^+ u - c) (the caps' nodes are neither Gamma3
nor target nodes, so T commutes with R and S and T c = c); the caps' slaves and prescribed
amplitudes are fixed dofs of x like the Dirichlet dofs, and their loads enter the residual
at the amplitudes.
"""
from __future__ import annotations

import numpy as np
from dolfinx import fem
from petsc4py import PETSc

from vpcontact.solvers.rotation import rotation_matrix

_SUBSET = PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN


class PairVariables:
    """The change of variables of two bodies (module docstring): u = P x + c, w = C x, the
    Dirichlet dofs of x (those of u) and the bulk stiffness P^T K P.  Shared by SNES VI
    (``PairMap``) and the condensed solver (app/solvers/condensed/pairs.py).

    Args:
        problem: the ContactProblem with contact pairs (its Discretisation's
            ``pair_operators``).

    Attributes:
        R, P, C, unlift, c: the nodal rotation, P = R (I + S), C = B P, I - S and the
            offset c (PETSc).
        dirichlet, dirichlet_global: the owned Dirichlet dofs (local, global indices).
    """

    def __init__(self, problem):
        self.problem = problem
        disc = problem.disc
        ops = disc.pair_operators
        self.R = rotation_matrix(problem.disc)
        self.caps, self.T = disc.caps, None
        self.P = self.R.matMult(ops.lift)
        if self.caps is not None:                  # u = T (R (I + S) x + c)
            self.T, self.T_inv = self.caps.matrices()
            lifted, self.P = self.P, self.T.matMult(self.P)
            lifted.destroy()
        self.C = ops.B.matMult(self.P)
        self.unlift = ops.unlift
        self.c = ops.c
        self.x_work, self.y_work = self.c.duplicate(), self.c.duplicate()
        imap = disc.V.dofmap.index_map
        n = imap.size_local * disc.dim
        dofs = np.unique(np.concatenate([bc.dof_indices()[0] for bc in disc.bcs]
                                        or [np.zeros(0, np.int32)]))
        if self.caps is not None:
            dofs = np.union1d(dofs, self.caps.fixed)
        self.dirichlet = dofs[dofs < n].astype(PETSc.IntType)
        self.dirichlet_global = (self.dirichlet + imap.local_range[0] * disc.dim
                                 ).astype(PETSc.IntType)

    def bulk_stiffness(self) -> PETSc.Mat:
        """P^T K P of the constant bulk matrix K (explicit scheme; no Dirichlet rows).

        Returns:
            A new AIJ matrix with x's layout.
        """
        K = fem.petsc.assemble_matrix(fem.form(self.problem.forms.bulk_jacobian))
        K.assemble()
        Kx = K.PtAP(self.P)
        K.destroy()
        return Kx

    def to_x(self, u: PETSc.Vec, x: PETSc.Vec) -> None:
        """x = (I - S) R^T (T^+ u - c), then the Dirichlet values (and the caps' fixed
        values) at their dofs.

        Args:
            u: the displacement.
            x: output.
        """
        if self.T is None:
            u.copy(self.x_work)
        else:
            self.T_inv.mult(u, self.x_work)
        self.x_work.axpy(-1.0, self.c)
        self.R.multTranspose(self.x_work, self.y_work)
        self.unlift.mult(self.y_work, x)
        self.fix(x)

    def fix(self, x: PETSc.Vec) -> None:
        """The Dirichlet values and the caps' fixed values (at the step's t) at their dofs.

        Args:
            x: a vector of x's layout.
        """
        fem.petsc.set_bc(x, self.problem.disc.bcs)
        if self.caps is not None:
            self.caps.fix(x, self.time)

    @property
    def time(self) -> float:
        """The step's t_n (of the time data)."""
        return float(self.problem.time_data.t.value)

    def modes(self, Z: np.ndarray) -> np.ndarray:
        """Rigid body modes in x: (I - S) R^T z for each column z (no offset c).

        Args:
            Z: (owned dofs, modes) in u.

        Returns:
            The modes in x, same shape.
        """
        z, y = self.c.duplicate(), self.c.duplicate()
        out = Z.copy()
        for j in range(Z.shape[1]):
            z.array[:] = Z[:, j]
            if self.T is not None:
                self.T_inv.mult(z, y)
                y.copy(z)
            self.R.multTranspose(z, y)
            self.unlift.mult(y, z)
            out[:, j] = z.array
        z.destroy()
        y.destroy()
        return out

    def to_u(self, x: PETSc.Vec, u) -> None:
        """u = P x + c, ghosts updated.

        Args:
            x: the unknown.
            u: the displacement Function (output).
        """
        self.P.mult(x, u.vector)
        u.vector.axpy(1.0, self.c)
        u.x.scatter_forward()

    def destroy(self) -> None:
        """Free the PETSc objects."""
        for obj in (self.R, self.P, self.C, self.x_work, self.y_work) + \
                ((self.T, self.T_inv) if self.T is not None else ()):
            obj.destroy()


class PairMap(PairVariables):
    """The residual and Jacobian of the step problem of two bodies in x (module docstring).

    Args:
        problem: the ContactProblem with contact pairs (its ``w`` and ``pair_forms``, its
            Discretisation's ``pair_operators``).
    """

    def __init__(self, problem):
        super().__init__(problem)
        self.F_bulk = fem.form(problem.forms.bulk_residual)
        self.b_u = fem.petsc.create_vector(self.F_bulk)
        # the Gamma3 terms on w (none with the bound alone: hard contact)
        self.F_form = self.J_form = self.b_w = self.J_w = self.J_wx = None
        if problem.pair_forms[0] is not None:
            self.F_form = fem.form(problem.pair_forms[0])
            self.J_form = fem.form(problem.pair_forms[1])
            self.b_w = fem.petsc.create_vector(self.F_form)
            self.J_w = fem.petsc.create_matrix(self.J_form)
        self.K = None if problem.implicit else self.bulk_stiffness()
        if self.J_form is not None:
            self.J_wx = self._boundary_jacobian()
        self.A = self._pattern()

    def _boundary_jacobian(self, result: PETSc.Mat | None = None) -> PETSc.Mat:
        """C^T J_w C at the current w."""
        self.J_w.zeroEntries()
        fem.petsc.assemble_matrix(self.J_w, self.J_form)
        self.J_w.assemble()
        return self.J_w.PtAP(self.C, result=result)

    def _pattern(self) -> PETSc.Mat:
        """The Newton matrix with the union of the bulk's and the contact's patterns."""
        if self.K is not None:
            A = self.K.copy()
        else:
            Ju = fem.petsc.assemble_matrix(self.problem.J_form)
            Ju.assemble()
            A = Ju.PtAP(self.P)
            Ju.destroy()
        if self.J_wx is not None:
            A.axpy(1.0, self.J_wx, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        return A

    def residual(self, x: PETSc.Vec, b: PETSc.Vec) -> bool:
        """F(x) = P^T F_bulk(P x + c) + C^T F_w(C x), zero at the Dirichlet dofs.

        Args:
            x: the unknown.
            b: output.

        Returns:
            False if the residual hook (the implicit update) failed.
        """
        p = self.problem
        self.to_u(x, p.u)
        self.C.mult(x, p.w.vector)
        p.w.x.scatter_forward()
        if not p.before_residual():
            return False
        for vec, form in ((self.b_u, self.F_bulk), (self.b_w, self.F_form)):
            if form is None:
                continue
            with vec.localForm() as loc:
                loc.set(0.0)
            fem.petsc.assemble_vector(vec, form)
            vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        self.P.multTranspose(self.b_u, b)
        if self.b_w is not None:
            self.C.multTransposeAdd(self.b_w, b, b)
        if self.caps is not None:
            self.caps.add_loads(b, self.time, -1.0)
        b.array[self.dirichlet] = 0.0
        return True

    def jacobian(self) -> None:
        """J = P^T K P + C^T J_w C at the w of the last residual, identity on the Dirichlet
        rows and columns, into ``A``."""
        A = self.A
        A.zeroEntries()
        if self.K is not None:
            A.axpy(1.0, self.K, structure=_SUBSET)
        else:
            Ju = fem.petsc.assemble_matrix(self.problem.J_form)
            Ju.assemble()
            Jx = Ju.PtAP(self.P)
            A.axpy(1.0, Jx, structure=_SUBSET)
            for obj in (Ju, Jx):
                obj.destroy()
        if self.J_wx is not None:
            self._boundary_jacobian(result=self.J_wx)
            A.axpy(1.0, self.J_wx, structure=_SUBSET)
        A.zeroRowsColumns(self.dirichlet_global, diag=1.0)

    def destroy(self) -> None:
        """Free the PETSc objects."""
        super().destroy()
        for obj in (self.b_u, self.b_w, self.J_w, self.K, self.J_wx, self.A):
            if obj is not None:
                obj.destroy()
