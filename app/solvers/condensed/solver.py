"""The condensed step solver: one factorisation of the elasticity matrix per run, and per
step a condensation onto the Gamma3 dofs, the small Gamma3 problem and an expansion.

The step problem (3.4) with the nodal (vertex) Gamma3 rule reads: find u minimising
1/2 u^T K u - F_n^T u + sum_i w_i phi_i(u_i) with u_nu,i <= g, where K is the (constant)
elasticity matrix and F_n = f_n - B^T H_n (rhs.py).  ``CondensedStepSolver`` composes
    a Condensation of K (condensation.py: CHOLMOD, MUMPS Schur or PETSc back end),
    the Gamma3Problem on the condensed dofs (problem.py, in the WorkFrames of frames.py),
and solves a step as y0 = condense(F_n); y = the Gamma3 problem from y0; u = expand(y).
It solves the same discrete problem as SNESVISolver, which takes over a step whose Gamma3
problem fails.  Two bodies (contact pairs): the same in the unknown x of
app/solvers/pairmap.py (u = P x + c), with K_x = P^T K P, F_x and G of
app/solvers/condensed/pairs.py.  One body with rigid caps: the same in z of u = T z
(condensed/caps.py; two bodies: T is in P).
"""
from __future__ import annotations

import logging

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from vpcontact.forms.elasticity import eps
from vpcontact.io.errors import StepSolveError
from vpcontact.solvers.choice import held_by_contact
from vpcontact.solvers.condensed.caps import CapRightHandSide, cap_stiffness
from vpcontact.solvers.condensed.condensation import factorise
from vpcontact.solvers.condensed.frames import work_frames
from vpcontact.solvers.condensed.layout import Gamma3Layout
from vpcontact.solvers.condensed.pairs import (
    PairLayout,
    PairRightHandSide,
    pair_frames,
    pair_sections,
    pair_stiffness,
)
from vpcontact.solvers.condensed.problem import Gamma3Problem
from vpcontact.solvers.condensed.rhs import StepRightHandSide
from vpcontact.solvers.nodal import gamma3_points
from vpcontact.solvers.pairmap import PairVariables

log = logging.getLogger("vpcontact")


class CondensedStepSolver:
    """Solves one step of (3.4) by condensation onto the Gamma3 dofs, for eligible cases
    (explicit history scheme, nodal Gamma3 rule, two bodies held by Dirichlet data:
    solvers/choice.py).  A StepSolver (app/solvers/__init__.py).

    Attributes:
        gamma3: whether there is a Gamma3 problem (Gamma3 dofs not all prescribed).
        m: the number of Gamma3 dofs (two bodies: of G, with the coupled target nodes).
        layout: the Gamma3Layout (a PairLayout with pairs; None without Gamma3).
        pairs: the PairVariables of two bodies (app/solvers/pairmap.py), or None.
        condensation: the Condensation of K (its S and C on GAMMA3_ROOT).
        semidefinite: K is singular in rigid motions that only the contact holds (a pair's
            or the foundation's): S only positive semidefinite, the Gamma3 problem reduced.

    Args:
        problem: the ContactProblem.
        options: PETSc options; options named fast_* configure the direct solver of K
            (and select the PETSc back end); all are passed to the SNES VI fallback.
        rtol: relative tolerance of the projected gradient of the Gamma3 problem.
        roundoff_floor: for the SNES VI fallback (SNESVISolver's argument).
    """

    name = "condensed"

    def __init__(self, problem, options: dict | None = None, rtol: float = 1e-13,
                 roundoff_floor: bool = True):
        disc = problem.disc
        self.problem, self.u, self.comm = problem, problem.u, disc.comm
        self.continuation_stages, self.fallback, self.sticky_robust = 0, None, False
        self.roundoff_floor = roundoff_floor
        self.options = options or {}
        self._snes = None
        # two bodies: the problem in x of app/solvers/pairmap.py (condensed/pairs.py)
        self.pairs = None if disc.pairs is None else PairVariables(problem)
        self.caps_T = None                   # one body's rigid caps: (T, T^+)
        self.K, self.rhs = self._stiffness()
        self.b, self.x = self.K.createVecRight(), self.K.createVecRight()
        self.layout = self._layout()
        self.gamma3 = self.layout is not None
        self.m = self.layout.m if self.gamma3 else 0
        G_rows = self.layout.global_rows() if self.gamma3 else np.zeros(0, dtype=np.int32)
        # a rigid motion held only by the contact (a pair's, or the foundation's:
        # app/model/semicoercive.py) leaves S semidefinite: the Gamma3 problem takes r = S y0
        self.semidefinite = problem.hold is not None or \
            (self.pairs is not None and held_by_contact(disc))
        self.condensation = factorise(self.K, G_rows, disc.dim, self.layout, self.options,
                                      self.comm, self.semidefinite)
        self.factorisations = self.condensation.factorisations
        self.gamma3_problem = self._gamma3_problem(rtol) if self.gamma3 else None
        # two bodies or S semidefinite: the Gamma3 problem takes r = S y0, not y0
        self.gamma3_problem_reduced = self.pairs is not None or self.semidefinite
        if self.pairs is not None:
            self.warm_start()           # the reduced Gamma3 problem starts from u_0

    def _stiffness(self):
        """(K, the StepRightHandSide): the elasticity matrix with the Dirichlet rows and
        columns the identity; two bodies: K_x and F_x of condensed/pairs.py."""
        p = self.problem
        if self.pairs is not None:
            return pair_stiffness(self.pairs), PairRightHandSide(p, self.pairs)
        C = p.elastic_operator
        disc = p.disc
        du, v = ufl.TrialFunction(disc.V), ufl.TestFunction(disc.V)
        a = fem.form(ufl.inner(C(eps(du)), eps(v)) * ufl.dx)
        # serial: d x d blocks (BAIJ), the fastest PETSc back-substitution
        blocks = self.comm.size == 1 and disc.caps is None
        K = fem.petsc.create_matrix(a, "baij" if blocks else None)
        fem.petsc.assemble_matrix(K, a, bcs=disc.bcs)
        K.assemble()
        if disc.caps is None:
            return K, StepRightHandSide(p, a)
        # rigid caps: in z of u = T z (condensed/caps.py)
        self.caps_T = disc.caps.matrices()
        return cap_stiffness(K, disc.caps, self.caps_T[0]), \
            CapRightHandSide(p, StepRightHandSide(p, a), K, self.caps_T[0])

    def _gamma3_problem(self, rtol: float) -> Gamma3Problem:
        """The Gamma3 problem on the condensed dofs (collective)."""
        p, layout = self.problem, self.layout
        if self.pairs is None:
            return Gamma3Problem(self.comm, self.condensation.S, work_frames(p.disc, layout),
                                 layout.w, p.contact_law(x=gamma3_points(p, layout)), rtol,
                                 reduced=self.semidefinite)
        surface = layout.surface            # the nodal energy's nodes and weights
        law = pair_sections(p, surface) or p.contact_law(x=gamma3_points(p, surface))
        return Gamma3Problem(self.comm, self.condensation.S, pair_frames(p.disc, layout),
                             surface.w, law, rtol, coupling=layout.coupling)

    def _layout(self) -> Gamma3Layout | None:
        """The Gamma3 dofs, or None where there are none to condense (collective)."""
        disc = self.problem.disc
        if disc.gamma3 is None:
            return None
        start = self.K.getOwnershipRange()[0]
        layout = Gamma3Layout(disc, start) if self.pairs is None else \
            PairLayout(disc, self.pairs, start)
        if layout.m == 0:
            # every Gamma3 node is fully prescribed (Discretisation._gamma3_nodes drops those): a
            # Gamma3 problem of size 0, nothing to condense -- u = K^-1 F_n, as SNES VI
            # solves it with no bound left (the same on every rank: g_nodes is gathered)
            log.info("  condensed solver: every Gamma3 node is prescribed, no Gamma3 problem")
            return None
        return layout

    @property
    def S(self) -> np.ndarray | None:
        """The Schur complement on GAMMA3_ROOT (None elsewhere, or without Gamma3).  One
        body only: with two bodies there is no Schur complement of u on Gamma3 (the
        condensation's S is x's on G), and the attribute is absent (AttributeError), so
        that the trace bound of app/post/diagnostics.py is not taken from it."""
        if self.pairs is not None or self.semidefinite:
            raise AttributeError("S: two bodies condense x onto G (condensation.S); a body "
                                 "held only by the contact has a singular S")
        return self.condensation.S

    @property
    def C(self) -> np.ndarray | None:
        """S's lower Cholesky factor where S is (one body only, as ``S``)."""
        if self.pairs is not None or self.semidefinite:
            raise AttributeError("C: two bodies condense x onto G (condensation.C); a body "
                                 "held only by the contact has a singular S")
        return self.condensation.C

    def describe(self) -> str:
        """The solver as the run's log line names it.

        Returns:
            'condensed (one factorisation, <m> Gamma3 dofs)', or without the count if there
            is no Gamma3 problem; ', two bodies' added with contact pairs (m counts G: the
            surface nodes and the target nodes coupled to them).
        """
        bodies = ", two bodies" if self.pairs is not None else ""
        return (f"condensed (one factorisation, {self.m} Gamma3 dofs{bodies})" if self.gamma3
                else f"condensed (one factorisation{bodies})")

    def gamma3_stats(self) -> dict | None:
        """The Gamma3 problem's linear algebra so far (summary.json: solver.gamma3), the
        same on every rank.

        Returns:
            {"dofs": m, "factorisations": dense Cholesky factorisations of the Newton
            matrix, "cg_iterations": CG iterations with a kept factor, "threads": BLAS
            threads of its large operations}, or None without Gamma3.
        """
        if not self.gamma3:
            return None
        return {"dofs": self.m, **self.gamma3_problem.stats()}

    def warm_start(self) -> None:
        """Start the next Gamma3 problem from the current u (after a restart)."""
        if not self.gamma3:
            return
        if self.pairs is not None:              # y = the values of G in x
            self.pairs.to_x(self.u.vector, self.x)
            self.gamma3_problem.warm_start(self.layout.gather_vector(self.x))
            return
        self.gamma3_problem.warm_start(self.layout.gather_vector(self.u.vector))

    def solve(self) -> int:
        """Solve step (3.4) from u_{n-1}; on success u holds u_n.  If the Gamma3 problem
        fails (the projected Newton iteration can zig-zag when nodes sit at nearly nonsmooth
        points), this step is solved by SNES VI instead (the same discrete problem;
        ``self.fallback`` = "snes_vi").

        Returns:
            The iterations of the Gamma3 problem (or SNES's Newton iterations).

        Raises:
            StepSolveError: the SNES VI fallback failed too.
        """
        self.fallback = None
        try:
            return self._solve_condensed()
        except StepSolveError as exc:
            if self._snes is None:
                from vpcontact.solvers.snesvi import SNESVISolver
                self._snes = SNESVISolver(self.problem, self.options,
                                          roundoff_floor=self.roundoff_floor)
            log.warning("  condensed solver: %s; solving this step with SNES VI", exc)
            its = self._snes.solve()
            self.fallback = "snes_vi"
            return its

    def _solve_condensed(self) -> int:
        """y0 = condense(F_n), the Gamma3 problem, u = expand(y)."""
        self.rhs.assemble(self.b)
        y0 = self.condensation.reduce(self.b) if self.gamma3_problem_reduced else \
            self.condensation.condense(self.b)        # r = S y0 (Gamma3Problem.reduced)
        its, y = 0, np.zeros(0)
        if self.gamma3:
            self._gamma3_inputs()
            t = float(self.problem.time_data.t.value)
            y, its = self.gamma3_problem.solve_on_root(y0, t)
        self.condensation.expand(y, self.x)
        self._set_u()
        return its

    def _gamma3_inputs(self) -> None:
        """The step's memory term xi_n and slip factor theta(s_n) at the Gamma3 nodes."""
        p = self.problem
        layout = self.layout if self.pairs is None else self.layout.surface
        self.gamma3_problem.set_data(
            None if p.xi is None else layout.gather_nodal(p.disc, p.xi),
            None if p.theta is None else layout.gather_nodal(p.disc, p.theta))

    def _set_u(self) -> None:
        """u = x (two bodies: u = P x + c), unless x is not finite anywhere (then
        StepSolveError on every rank)."""
        if self.comm.allreduce(not np.all(np.isfinite(self.x.array_r)), op=MPI.LOR):
            raise StepSolveError("condensed solver: non-finite solution")
        if self.pairs is not None:
            self.pairs.to_u(self.x, self.u)
            return
        if self.caps_T is not None:              # u = T z
            self.caps_T[0].mult(self.x, self.u.vector)
        else:
            self.u.vector.array[:self.x.getLocalSize()] = self.x.array_r
        self.u.x.scatter_forward()

    def destroy(self) -> None:
        """Free the PETSc objects (and those of the SNES VI fallback, if it was created)."""
        for obj in (self.K, self.b, self.x, self.rhs, self.condensation, self.pairs,
                    *(self.caps_T or ())):
            if obj is not None:
                obj.destroy()
        if self._snes is not None:
            self._snes.destroy()
