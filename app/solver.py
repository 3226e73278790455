"""Step solver: PETSc SNES vinewtonrsls for the discrete inequality (3.4) on U^h.

Bounds only on the normal dofs of Gamma3 nodes; Dirichlet dofs of Gamma1 are imposed in the
residual and Jacobian (set_bc / diagonal 1).  Direct LU (MUMPS) by default.  Options are read
from the PETSc options database under our prefix, so every PETSc option works.
"""
from __future__ import annotations

from dolfinx import fem
from petsc4py import PETSc

PREFIX = "vpcontact_"

_REASONS = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}


class StepFailure(RuntimeError):
    """A step solve failed; carries the SNES converged reason."""

    def __init__(self, message: str, reason: int | None = None):
        super().__init__(message)
        self.reason = reason


def reason_name(reason: int) -> str:
    return _REASONS.get(reason, str(reason))


def set_petsc_options(options: dict, prefix: str = PREFIX) -> None:
    """Put ``options`` (name without '-' -> value) into the PETSc database under ``prefix``."""
    db = PETSc.Options()
    for key, value in options.items():
        if value is None or value is True:
            db.setValue(prefix + key, "")
        elif value is False:
            db.setValue(prefix + key, "false")
        else:
            db.setValue(prefix + key, str(value))


def clear_petsc_options(options: dict, prefix: str = PREFIX) -> None:
    db = PETSc.Options()
    for key in options:
        db.delValue(prefix + key)


class SNESVISolver:
    """Solves one step: u_n = argmin J_n over U^h, starting from the current ``problem.u``."""

    def __init__(self, problem, options: dict, prefix: str = PREFIX):
        self.problem = problem
        self.u = problem.u
        self.b = fem.petsc.create_vector(problem.F_form)
        self.A = fem.petsc.create_matrix(problem.J_form)
        self.x = self.u.vector.copy()
        snes = self.snes = PETSc.SNES().create(problem.comm)
        snes.setOptionsPrefix(prefix)
        snes.setFunction(self._F, self.b)
        snes.setJacobian(self._J, self.A, self.A)
        # Options pass through unchanged under our prefix; removed again once read so that
        # they cannot leak into another solver created in the same process.
        set_petsc_options(options, prefix)
        try:
            snes.setFromOptions()
        finally:
            clear_petsc_options(options, prefix)
        if snes.getType().startswith("vi"):
            self.lb, self.ub = problem.bounds()
            snes.setVariableBounds(self.lb, self.ub)

    def _F(self, snes, x, b):
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        x.copy(self.u.vector)
        self.u.x.scatter_forward()
        with b.localForm() as bl:
            bl.set(0.0)
        fem.petsc.assemble_vector(b, self.problem.F_form)
        fem.petsc.apply_lifting(b, [self.problem.J_form], [self.problem.bcs], x0=[x], scale=-1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem.petsc.set_bc(b, self.problem.bcs, x, -1.0)

    def _J(self, snes, x, A, P):
        A.zeroEntries()
        fem.petsc.assemble_matrix(A, self.problem.J_form, self.problem.bcs)
        A.assemble()

    def solve(self) -> int:
        """Solve from the current u (u_{n-1}); on success u holds u_n and the Newton
        iteration count is returned.  On failure u is restored and StepFailure raised."""
        start = self.u.x.array.copy()
        self.u.vector.copy(self.x)
        self.snes.solve(None, self.x)
        reason = self.snes.getConvergedReason()
        its = self.snes.getIterationNumber()
        if reason <= 0:
            self.u.x.array[:] = start  # keep the last good state u_{n-1}
            raise StepFailure(f"SNES did not converge: {reason_name(reason)} ({reason}) after "
                              f"{its} Newton iterations", reason)
        self.x.copy(self.u.vector)
        self.u.x.scatter_forward()
        return its

    def destroy(self):
        for obj in (self.snes, self.A, self.b, self.x):
            obj.destroy()
