"""The Gamma3 part of the error estimate's time part (docs/model.md, "Error estimates"): the
error of the explicit Gamma3 sums of (3.4) and its effect on u and sigma.

The memory term xi_n = sum_j k_j b(t_n - t_{j-1}) u_{j-1,nu}^+ and the slip s_n = sum_j k_j
|u_{j-1,tau}| are left-rectangle sums (app/model/gamma3.py); the trapezoidal sums, second
order and known once u_n is, differ from them by

    D^xi_n = (T_n - xi_n) / 2,   T_n = sum_j k_j b(t_n - t_j) u_{j,nu}^+  (the right sum;
             for the exponential kernel T_n = e^(-beta k_n) T_{n-1} + k_n b0 u_{n,nu}^+),
    D^s_n = D^s_{n-1} + (k_n / 2) (|u_{n,tau}| - |u_{n-1,tau}|),

per Gamma3 node: the error of the sums against the integrals of (1.6)-(1.7).  On the step
they act as a contact traction error: D^xi_n in the normal direction where u_nu > 0 (the
force of xi_n v_nu^+), and the friction stress of the laws (app/post/quantities.py
``law_friction``) times theta(s_n + D^s_n) / theta(s_n) - 1 in the tangential one.  Its
effect on the step is that of a load: the linearised step (the Jacobian of (3.4) at u_n, with
the Dirichlet conditions) solved for the nodal forces w_i dt_i (the nodal rule's weights), e,
and the term is ||E eps(e)||_Q + ||e||_V.  One more Jacobian assembly and direct solve (MUMPS,
its analysis kept) per step where dt is not 0, several times the condensed solver's own solves
(docs/performance.md, section 9).  The error of u_n fed back into the later sums and the history
is not followed.  One body only (pairs: no term).
"""
from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact.model.primitives import NUMPY
from vpcontact.post.quantities import law_friction


class Gamma3TimeError:
    """D^xi_n, D^s_n and their effect ||E eps(e)||_Q + ||e||_V (module docstring);
    collective.

    Args:
        problem: the ContactProblem, its State with a Gamma3 history (memory or slip).
    """

    def __init__(self, problem):
        self.problem, self.g3 = problem, problem.state.gamma3
        m = len(self.g3.nodes)
        mem = self.g3.memory
        self.right = np.zeros(m) if mem is not None and mem.recursion else None
        self.ds = np.zeros(m) if self.g3.slip is not None else None
        self.abs_tau = self._components()[1]
        disc = problem.disc
        gm = disc.gamma3
        self.own = np.searchsorted(self.g3.nodes, gm.nodes)   # the owned nodes' rows
        self.weight = gm.weight
        self.e = fem.Function(disc.V, name="gamma3_time_error")
        strain = ufl.sym(ufl.grad(self.e))
        stress = problem.elastic_operator(strain)
        self.norms = [fem.form(ufl.inner(stress, stress) * ufl.dx),
                      fem.form(ufl.inner(strain, strain) * ufl.dx)]
        self.A = fem_petsc.create_matrix(problem.J_form)   # one pattern: one analysis
        self.f, self.x = self.A.createVecLeft(), self.A.createVecRight()
        self.ksp = PETSc.KSP().create(disc.comm)
        self.ksp.setOperators(self.A)
        self.ksp.setType("preonly")
        self.ksp.getPC().setType("lu")
        self.ksp.getPC().setFactorSolverType("mumps")

    def _components(self):
        """(u_nu, |u_tau|, u_tau) at the history's Gamma3 nodes."""
        u_nu, u_tau = self.g3.components()
        return u_nu, np.linalg.norm(u_tau, axis=1), u_tau

    def state(self) -> dict:
        """The sums for a checkpoint.

        Returns:
            {"right": T_n or None, "ds": D^s_n or None} at the local Gamma3 nodes.
        """
        return {"right": self.right, "ds": self.ds}

    def load_state(self, state: dict) -> None:
        """T_n, D^s_n from a checkpoint.

        Args:
            state: ``state()`` of the checkpointed run (a key absent: zeros).
        """
        for key in ("right", "ds"):
            if getattr(self, key) is not None and state.get(key) is not None:
                setattr(self, key, np.array(state[key], dtype=float))

    def traction(self, k: float, t_n: float) -> np.ndarray:
        """The traction error dt at the Gamma3 nodes after step n (local, no collectives).

        Args:
            k: the step k_n.
            t_n: its time.

        Returns:
            (nodes, d) traction errors.
        """
        g3 = self.g3
        u_nu, abs_tau, u_tau = self._components()
        dt = np.zeros_like(u_tau)
        if g3.memory is not None:
            dt += (self._memory_error(u_nu, k, t_n) * (u_nu > 0))[:, None] * g3.normal
        if self.ds is not None:
            self.ds = self.ds + 0.5 * k * (abs_tau - self.abs_tau)
            law = g3.slip.law
            ratio = law.theta(g3.slip.s + self.ds) / law.theta(g3.slip.s) - 1.0
            dt += ratio[:, None] * law_friction(self.problem, np.arange(len(u_nu)), u_tau)
        self.abs_tau = abs_tau
        return dt

    def _memory_error(self, u_nu: np.ndarray, k: float, t_n: float) -> np.ndarray:
        """D^xi_n = (T_n - xi_n) / 2 with T_n, the right sum (module docstring)."""
        g3 = self.g3
        mem = g3.memory
        r = NUMPY.pos(u_nu) if g3.b0 is None else g3.b0 * NUMPY.pos(u_nu)
        b = mem.kernel
        if self.right is not None:                   # the exponential kernel's recursion
            self.right = (b(k) / b(0.0)) * self.right + k * b(0.0) * r
            right = self.right
        else:
            st = mem.state()
            t_j = np.asarray(st["t_prev"]) + np.asarray(st["k"])
            rows = st["r"][1:] + [r]
            right = (np.asarray(st["k"]) * b(t_n - t_j)) @ np.asarray(rows)
        return 0.5 * (right - mem.xi)

    def step(self, k: float, t_n: float) -> float:
        """The Gamma3 time term of step n (collective).

        Args:
            k: the step k_n.
            t_n: its time.

        Returns:
            ||E eps(e)||_Q + ||e||_V.
        """
        p = self.problem
        dt = self.traction(k, t_n)
        disc = p.disc
        if not disc.comm.allreduce(bool(np.any(dt[self.own])), op=MPI.LOR):
            return 0.0                               # no traction error: no solve
        bs = disc.V.dofmap.index_map_bs
        f, A = self.f, self.A
        f.set(0.0)
        f.getArray().reshape(-1, bs)[disc.gamma3.nodes] = self.weight[:, None] * dt[self.own]
        fem_petsc.set_bc(f, disc.bcs, scale=0.0)
        A.zeroEntries()
        fem_petsc.assemble_matrix(A, p.J_form, bcs=disc.bcs)
        A.assemble()
        self.ksp.solve(f, self.x)
        self.e.x.array[:len(self.x.getArray())] = self.x.getArray()
        self.e.x.scatter_forward()
        return float(sum(np.sqrt(max(disc.comm.allreduce(fem.assemble_scalar(a)), 0.0))
                         for a in self.norms))
