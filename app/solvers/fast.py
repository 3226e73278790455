"""Fast step solver: one factorisation of the elasticity matrix per run, and per
step only back-substitutions plus a small problem on the Gamma3 dofs.

With the nodal (vertex) Gamma3 rule every boundary term is a sum of nodal energies, so the
step problem (3.4) reads: find u minimising 1/2 u^T K u - F_n^T u + sum_i w_i phi_i(u_i) with
u_nu,i <= g, where K is the (constant) elasticity matrix, F_n = f_n - B^T H_n the step's
right-hand side and phi_i the nodal contact energy (normal compliance, memory, friction with
the same regularisation delta as the SNES path).  Condensing onto the Gamma3 dofs G
(S = K_GG - K_GI K_II^-1 K_IG the Schur complement, once) leaves per step
    min_y  1/2 (y - y0)^T S (y - y0) + sum_i w_i phi_i(y_i),  y0 = (K^-1 F_n)_G,  y_nu <= g,
which is solved by a projected Newton method with an Armijo line search on this (convex
under (2.6)) energy, started from the previous step's Gamma3 values; then
u = K^-1 (F_n + E_G lambda) with the Gamma3 forces lambda = S (y - y0).  Both paths solve the
same discrete problem.  Under mpirun the Gamma3 problem (S, its Cholesky factor and the
Newton iteration: dense, O(m^2) memory) lives on one rank, threads.GAMMA3_ROOT, which uses
the cores of its node's ranks while they wait asleep (threads.root_call); only the m values
of r and y, and the iteration's outcome, pass between the ranks.

Serial runs factorise K once, the Gamma3 dofs ordered last: K = L D L^T by CHOLMOD
(schur.GLastLDL; SuperLU's L U where CHOLMOD is missing).  The trailing blocks give
S = L_GG D_G L_GG^T, and a step is one forward sweep (which yields y0), the Gamma3 problem,
and one backward sweep with u_G = y (kernels.GLastSolve: L in d x d node blocks, compiled):
at h = 1/128 about 6 ms per step against 9.4-12 ms for the two PETSc back-substitutions
u_free = K^-1 F_n, u = K^-1 (F_n + E_G lambda) of the general path.  Under mpirun the same
split is one distributed MUMPS factorisation with the Gamma3 dofs as Schur variables
(app/solvers/mumps.py): S comes from MUMPS once, on rank 0, and a step is a condensation
(r on rank 0), the Gamma3 problem and an expansion with u_G = y, the right-hand side and the
solution distributed.  The general path (two PETSc solves per step; under mpirun S from a
G-last factorisation of the matrix gathered on rank 0: two factorisations, counted) serves
runs without a C compiler or the MUMPS wrapper, and runs where PETSc options for the fast
solver are given (-vpcontact_fast_pc_factor_mat_solver_type ...).
"""
from __future__ import annotations

import logging

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact import kernels
from vpcontact.forms.elasticity import elasticity_operator, eps
from vpcontact.io.errors import CaseError
from vpcontact.solvers import dense, threads
from vpcontact.solvers.nodal import NodalContact
from vpcontact.solvers.schur import (
    GLastLDL,
    cholesky_solve,
    g_last_factor,
    gamma3_schur_pair,
    gather_csr,
    schur_pair,
)
from vpcontact.solvers.snesvi import StepSolveError

log = logging.getLogger("vpcontact")


_EPS = np.finfo(float).eps
THREADED_FACTOR_MIN = 50_000    # dofs from which the G-last factorisation uses BLAS threads


def _projected(y, g, lo, hi) -> float:
    """The largest projected gradient component: g where no bound holds y back."""
    binding = ((y <= lo) & (g > 0)) | ((y >= hi) & (g < 0))
    return float(np.abs(np.where(binding, 0.0, g)).max(initial=0.0))


class FastStepSolver:
    """Solves one step of (3.4) by condensation onto the Gamma3 dofs (see the module
    docstring): the same discrete problem as SNESVISolver, for eligible cases (explicit
    history scheme, nodal Gamma3 rule).  A StepSolver (app/solvers/__init__.py).

    Args:
        problem: the ContactProblem.
        options: PETSc options; options named fast_* configure the direct solver of K
            (and select the PETSc path); all are passed to the SNES VI fallback.
        rtol: relative tolerance of the projected gradient of the Gamma3 problem.
        roundoff_floor: for the SNES VI fallback (SNESVISolver's argument).
    """

    name = "fast"

    def __init__(self, problem, options: dict | None = None, rtol: float = 1e-13,
                 roundoff_floor: bool = True):
        self.problem = problem
        self.u = problem.u
        self.comm = problem.comm
        self.continuation_stages, self.fallback, self.sticky_robust = 0, None, False
        self.factorisations = 0
        self.rtol, self.roundoff_floor = rtol, roundoff_floor
        self.options = options or {}
        self._snes = None
        V, d = problem.V, problem.dim
        self.d = d
        C = elasticity_operator(problem.constants["E"], problem.constants["nu"], d)
        du, v = ufl.TrialFunction(V), ufl.TestFunction(V)
        serial = self.comm.size == 1
        a = self.a = fem.form(ufl.inner(C(eps(du)), eps(v)) * ufl.dx)
        self._lift = None if problem.dirichlet.homogeneous else problem.u.vector.duplicate()
        # serial: d x d blocks (BAIJ), the fastest PETSc back-substitution
        K = fem.petsc.create_matrix(a, "baij" if serial else None)
        fem.petsc.assemble_matrix(K, a, bcs=problem.bcs)
        K.assemble()
        self.K = K
        self.ksp, self._split, self._mumps = None, None, None
        # the step's right-hand side F_n = f_n - B^T H_n (the bulk residual at u = 0): the
        # loads by assembly, the pre-stress by B^T = the transposed cell-strain operator
        self.loads_form = fem.form(problem.forms.loads) if problem.forms.loads is not None \
            else None
        self._loads = fem.petsc.create_vector(self.loads_form) if self.loads_form else None
        self.b, self.x = K.createVecRight(), K.createVecRight()
        self._y_prev = []               # (t, y) of the last two steps (_start)
        self._setup_gamma3()
        if not self.gamma3:
            self._factorise(np.zeros(0, dtype=np.int32))

    def _factorise(self, G_rows: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Factorise K once; returns the Schur complement S and its Cholesky factor C on
        GAMMA3_ROOT (None without Gamma3 dofs, and on the other ranks).

        Serial, with the compiled sweeps (kernels/ldl_blocks.c): one factorisation with the Gamma3
        dofs last (CHOLMOD L D L^T, else SuperLU L U) gives S and C (its trailing blocks) and
        every step's solve, one forward and one backward sweep with the Gamma3 problem in
        between (kernels.GLastSolve).  Under mpirun: one distributed MUMPS factorisation with
        the Gamma3 dofs as Schur variables (``_factorise_mumps``).  Otherwise (no C compiler
        or MUMPS wrapper, or PETSc options for the fast solver given): PETSc's direct solver
        for the steps (MUMPS in parallel) and S, C from a G-last factorisation of the
        gathered matrix on rank 0 -- two factorisations per run, counted as such."""
        from vpcontact.solvers.snesvi import (
            PREFIX,
            clear_petsc_options,
            direct_solver,
            set_petsc_options,
        )
        petsc_options = any(str(k).startswith("fast_") for k in self.options)
        module = kernels.load() if self.comm.size == 1 and not petsc_options else None
        if module is not None:
            A = gather_csr(self.K, self.comm)
            with threads.blas_threads(large=A.n >= THREADED_FACTOR_MIN):
                factor = g_last_factor(A, G_rows, self.d)
            self._split = kernels.GLastSolve(factor, module, self.d)
            self.factorisations = 1
            log.info("  fast solver: one %s factorisation (Gamma3 last), compiled sweeps",
                     "CHOLMOD L D L^T" if isinstance(factor, GLastLDL) else "SuperLU L U")
            return schur_pair(factor) if len(G_rows) else None
        if self.comm.size > 1 and not petsc_options and len(G_rows) and \
                self._factorise_mumps(G_rows):
            return (self._mumps.S, self._mumps.C) if self._mumps.S is not None else None
        self.ksp = direct_solver(self.K, self.comm, PREFIX + "fast_")
        set_petsc_options(self.options, PREFIX)      # user options, e.g. -fast_ksp_view
        try:
            self.ksp.setFromOptions()
        finally:
            clear_petsc_options(self.options, PREFIX)
        self.ksp.setUp()
        self.factorisations = 1
        log.info("  fast solver: PETSc %s for the steps%s",
                 self.ksp.getPC().getFactorSolverType() or "LU",
                 ", a G-last factorisation on rank 0 for S" if len(G_rows) else "")
        if not len(G_rows):
            return None
        self.factorisations += 1
        return gamma3_schur_pair(self.K, G_rows, self.comm)

    def _factorise_mumps(self, G_rows: np.ndarray) -> bool:
        """Under mpirun: one distributed MUMPS factorisation with the Gamma3 dofs as Schur
        variables (app/solvers/mumps.py); False (two factorisations then) where the
        wrapper cannot be built on every rank or MUMPS fails (the same on every rank)."""
        from vpcontact.solvers import mumps
        module = mumps.load()
        if not self.comm.allreduce(module is not None, op=MPI.LAND):
            return False
        try:
            self._mumps = mumps.SchurMumps(module, self.K, G_rows, self.d, self.comm)
        except mumps.MumpsError as exc:
            log.warning("  fast solver: %s; factorising twice instead", exc)
            return False
        self.factorisations = 1
        self._split = self._mumps                     # the same forward / backward sweeps
        log.info("  fast solver: one distributed MUMPS factorisation, Gamma3 as Schur "
                 "variables")
        return True

    # ------------------------------------------------------------------ Gamma3 condensation
    def _setup_gamma3(self):
        p, d = self.problem, self.d
        self.gamma3 = p.gamma3 is not None
        if not self.gamma3:
            return
        imap = p.V.dofmap.index_map
        owned_nodes = p.gamma3.nodes
        glob_nodes = imap.local_to_global(owned_nodes.astype(np.int32))
        parts = self.comm.allgather((glob_nodes, p.gamma3.weight))
        gn = np.concatenate([a for a, _ in parts])
        w = np.concatenate([b for _, b in parts])
        order = np.argsort(gn)
        self.g_nodes, self.w = gn[order], w[order]
        self.m = d * len(self.g_nodes)
        if self.m == 0:
            # every Gamma3 node is fully prescribed (problem._gamma3_nodes drops those): a
            # Gamma3 problem of size 0, nothing to condense -- u = K^-1 F_n, as SNES VI
            # solves it with no bound left (the same on every rank: g_nodes is gathered)
            log.info("  fast solver: every Gamma3 node is prescribed, no Gamma3 problem")
            self.gamma3 = False
            return
        # positions in G of the owned Gamma3 nodes, and their dofs in the local vector
        self.local_owned_g = np.searchsorted(self.g_nodes, glob_nodes)   # positions in G
        self.owned_dofs_local = (owned_nodes[:, None] * d + np.arange(d)).ravel()
        self._owned_positions = (self.local_owned_g[:, None] * d + np.arange(d)).ravel()
        # S (m x m) and its Cholesky factor C from one G-last factorisation (schur.py)
        start = self.K.getOwnershipRange()[0]
        self._owned_rows = start + self.owned_dofs_local          # global rows of owned G dofs
        self.on_root = self.comm.rank == threads.GAMMA3_ROOT
        self.S, self.C = self._factorise(self.global_G_dofs()) or (None, None)
        normal = self._setup_frames()
        self._direction = None

        def direction():                      # the dense Newton matrices, on the root
            self._direction = dense.NewtonDirection(self._work_matrix(), d, dense.load())
            return self._local_counts()
        self._counts = threads.root_call(self.comm, direction)
        c = p.case.contact
        fr = c.friction
        self.contact = NodalContact(self.w, normal, c.c_nu,
                                    None if fr is None else (fr.b, fr.c1, fr.c2, fr.u1),
                                    p.case.numerics.delta, kernels.load())

    def _setup_frames(self) -> np.ndarray:
        """The coordinates of the Gamma3 problem: the global ones where every node has the
        same axis-aligned normal and no rotated frame (the paper's flat bottom), else the
        nodal frames with the normal first (T_i, so y = T y_w).  Sets T (None in the global
        coordinates), the bounds u_nu <= g_i and the prescribed components (fixed, set per
        step).

        Returns:
            The normal in those coordinates (NodalContact's nu)."""
        p, d = self.problem, self.d
        fr, n = p.frames, len(self.g_nodes)
        pos = np.searchsorted(fr.nodes, p.gamma3.nodes)
        Q, slot, sign = fr.Q[pos], fr.slot[pos], fr.sign[pos]
        # normal first: the columns of Q in the order (slot, the others ascending)
        order = np.argsort(np.arange(d)[None, :] != slot[:, None], axis=1, kind="stable")
        T = np.take_along_axis(Q, order[:, None, :], axis=2)
        T[:, :, 0] *= sign[:, None]                   # T_i = (nu_i, the tangents)
        axis = np.abs(Q).max(axis=1) == 1.0            # (nodes, d): column is +-e_a
        col_axis = np.argmax(np.abs(Q), axis=1)
        fixed_nodes = p.dirichlet.fixed[p.gamma3.nodes]
        fixedQ = axis & np.take_along_axis(fixed_nodes, col_axis, axis=1)
        if (fixedQ.sum(axis=1) != fixed_nodes.sum(axis=1)).any():
            raise CaseError(f"{p.case.source}: solver.method: the fast solver cannot hold the "
                            "prescribed components of a Gamma3 node whose normal lies in them "
                            "and is not an axis (allowed here: snes_vi)")
        fixedT = np.take_along_axis(fixedQ, order, axis=1)
        g = fr.g[pos] if fr.g is not None else np.full(len(pos), np.inf)
        g = np.where(fr.bounded[pos], g, np.inf)
        place = self.local_owned_g
        T = self._place_on_all(place, T, (n, d, d))
        g = self._place_on_all(place, g, n)
        nu0 = self._place_on_all(place, sign[:, None] * np.eye(d)[slot], (n, d))
        uniform = not fr.rotated and (len(nu0) == 0 or (nu0 == nu0[0]).all())
        self.T = None if uniform else T
        self.fixed = self._place_on_all(place, fixedQ if uniform else fixedT, (n, d),
                                        dtype=bool).ravel()
        self.lb = np.full((n, d), -np.inf)
        self.ub = np.full((n, d), np.inf)
        if uniform:
            normal = nu0[0] if n else np.eye(d)[0]
            comp = int(np.argmax(np.abs(normal)))
            (self.ub[:, comp], self.lb[:, comp]) = (g, -np.inf) if normal[comp] > 0 \
                else (np.inf, -g)
            return normal
        self.ub[:, 0] = g
        return np.eye(d)[0]

    def _work_matrix(self) -> np.ndarray:
        """S in the Gamma3 problem's coordinates: S_w = T^T S T (S in the global ones)."""
        if self.T is None:
            return self.S
        n, d = len(self.g_nodes), self.d
        return np.einsum("ica,icjb,jbe->iaje", self.T, self.S.reshape(n, d, n, d),
                         self.T).reshape(n * d, n * d)

    def _to_work(self, y: np.ndarray) -> np.ndarray:
        """Gamma3 values in the problem's coordinates: y_w = T^T y."""
        if self.T is None:
            return y
        return np.einsum("iab,ia->ib", self.T, y.reshape(-1, self.d)).ravel()

    def _from_work(self, y_w: np.ndarray) -> np.ndarray:
        """Back to the global coordinates: y = T y_w."""
        if self.T is None:
            return y_w
        return np.einsum("iab,ib->ia", self.T, y_w.reshape(-1, self.d)).ravel()

    def _place_on_all(self, positions, values, shape, dtype=float) -> np.ndarray:
        """The array of ``shape`` whose entries at every rank's ``positions`` are that rank's
        ``values``, assembled on every rank (collective)."""
        out = np.empty(shape, dtype=dtype)
        for pos, vals in self.comm.allgather((positions, values)):
            out[pos] = vals
        return out

    def gather_GG(self, local_rows: np.ndarray) -> np.ndarray:
        """Assemble an m x m matrix from the ranks' rows (collective).

        Args:
            local_rows: this rank's rows, at its owned Gamma3 positions in G order, shape
                (number owned, m), columns in G order.

        Returns:
            The whole matrix, shape (m, m), on GAMMA3_ROOT; None on the other ranks.
        """
        parts = self.comm.gather((self._owned_positions, local_rows), root=threads.GAMMA3_ROOT)
        if parts is None:
            return None
        out = np.empty((self.m, self.m))
        for pos, rows in parts:
            out[pos] = rows
        return out

    def global_G_dofs(self) -> np.ndarray:
        """The global dof numbers of the Gamma3 dofs (collective).

        Returns:
            The global matrix row of every Gamma3 dof, in G order, shape (m,) (int32), on
            every rank.
        """
        return self._place_on_all(self._owned_positions, self._owned_rows, self.m, np.int32)

    def _gather_G(self, vec) -> np.ndarray:
        """Values of a PETSc vector at the Gamma3 dofs, in G order, on every rank."""
        return self._place_on_all(self._owned_positions, vec.array_r[self.owned_dofs_local],
                                  self.m)

    def _gather_nodal(self, field) -> np.ndarray:
        """A Gamma3 NodalField's values at the owned nodes, in G order, on every rank."""
        pos = np.searchsorted(self.problem.gamma3_local_nodes, self.problem.gamma3.nodes)
        return self._place_on_all(self.local_owned_g, field.function.x.array[field.dofs[pos]],
                                  len(self.g_nodes))

    # ------------------------------------------------------------------ the step
    def _assemble_rhs(self):
        """b = F_n = f_n - B^T H_n (zero at the clamped dofs)."""
        p = self.problem
        self.b.set(0.0)
        if self._loads is not None:
            with self._loads.localForm() as bl:   # ghosted: dolfinx assembles the local form
                bl.set(0.0)
            fem.petsc.assemble_vector(self._loads, self.loads_form)
            self._loads.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            self.b.array[:] = self._loads.array_r
        if p.H is not None:
            p.strain_operator.pre_stress_load(p.H, self.b)        # b -= B^T H_n
        if p.dirichlet.homogeneous:
            fem.petsc.set_bc(self.b, p.bcs, scale=0.0)
            return
        # prescribed displacements u_D: b -= K_{:,D} u_D (lifting), b_D = u_D
        lift = self._lift
        with lift.localForm() as loc:
            loc.set(0.0)
        fem.petsc.apply_lifting(lift, [self.a], [p.bcs])
        lift.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        self.b.array[:] += lift.array_r
        fem.petsc.set_bc(self.b, p.bcs)

    def _small_problem(self, y0_global: np.ndarray) -> tuple[np.ndarray, int]:
        """The Gamma3 problem in its coordinates (_setup_frames); returns (y, iterations)
        with y in the global coordinates."""
        y0 = self._to_work(y0_global)
        lb, ub = self.lb.ravel().copy(), self.ub.ravel().copy()
        lb[self.fixed] = ub[self.fixed] = y0[self.fixed]      # prescribed components
        y, its = self._projected_newton(y0, lb, ub)
        return self._from_work(y), its

    def _projected_newton(self, y0, lb, ub) -> tuple[np.ndarray, int]:
        """Projected Newton for min 1/2 (y-y0)^T S (y-y0) + sum w phi(y_i), lb <= y <= ub."""
        S, d = self._direction.product, self.d
        y = np.clip(self._start(y0), lb, ub)
        scale = max(np.abs(S(y0)).max(), np.abs(self.w).max(), 1e-300)

        def energy_grad(yv, hess=True):
            e, g, H = self.contact.evaluate(yv.reshape(-1, d), hess)
            dy = yv - y0
            Sdy = S(dy)
            return 0.5 * dy @ Sdy + e, Sdy + g.ravel(), H

        E, g, Hn = energy_grad(y)
        lo, hi = lb + 1e-14 * scale, ub - 1e-14 * scale
        for it in range(1, 200):
            binding = ((y <= lo) & (g > 0)) | ((y >= hi) & (g < 0))
            pg = np.where(binding, 0.0, g)
            if np.abs(pg).max() <= self.rtol * scale:
                self._remember(y)
                return y, it - 1
            p = self._direction(Hn, g, binding, rtol=self._forcing(np.abs(pg).max(), scale))
            if p is None:                 # not positive definite here: LU, else -pg
                H = self._direction.matrix(Hn)
                f = np.flatnonzero(~binding)
                p = np.zeros_like(y)
                try:
                    p[f] = np.linalg.solve(H[np.ix_(f, f)], -g[f])
                except np.linalg.LinAlgError:
                    p[f] = -g[f]
            if pg @ p >= 0:               # not a descent direction: steepest descent
                p = -pg
            alpha = 1.0
            for _ in range(60):
                yt = np.minimum(np.maximum(y + alpha * p, lb), ub)
                Et, gt, Ht = energy_grad(yt)
                # Armijo, or a step so small that the energy cannot resolve it any more.
                # (Accepting steps up to the round-off of E instead let the iteration zig-zag
                # at h = 1/256: 670 iterations against 278 for 32 steps; measured.)
                if Et <= E + 1e-4 * g @ (yt - y) or np.abs(yt - y).max() <= 1e-16 * scale:
                    break
                # Where the predicted decrease is below the round-off of E, the energy cannot
                # judge the step: the projected gradient does (3D, box3d n = 16: steps stalled
                # for 160-200 iterations at |pg| ~ 1e-11 with |g.dy| ~ 1e-21, E ~ 1e-4).
                if abs(g @ (yt - y)) <= 1e3 * _EPS * max(abs(E), abs(Et)) and \
                        _projected(yt, gt, lo, hi) < 0.5 * np.abs(pg).max():
                    break
                alpha *= 0.5
            y, E, g, Hn = yt, Et, gt, Ht
        if np.abs(pg).max() <= 1e-9 * scale:   # converged to round-off, not to rtol
            self._remember(y)
            return y, it
        raise StepSolveError("fast solver: the Gamma3 problem did not converge in 200 iterations")

    def _forcing(self, pg_max: float, scale: float) -> float:
        """The relative residual an inexact Newton direction needs: |pg| / scale (quadratic
        convergence), but no smaller than what brings the projected gradient below the
        tolerance in one more iteration (|r|_2 <= 0.1 rtol scale / sqrt(m)), at most 1e-2."""
        final = 0.1 * self.rtol * scale / (pg_max * np.sqrt(max(self.m, 1)))
        return min(1e-2, max(pg_max / scale, final))

    def _start(self, y0: np.ndarray) -> np.ndarray:
        """The Gamma3 iteration's start: the linear extrapolation in time of the last two
        steps' solutions (the step problems change smoothly: 276 Newton iterations against
        351 from the last solution alone at h = k = 1/128, measured), the last solution
        after one step or a restart, y0 (the free solution) at the first step."""
        t = float(self.problem.time_data.t.value)
        if len(self._y_prev) == 2:
            (t0, y_0), (t1, y_1) = self._y_prev
            if t0 is not None and t > t1 > t0:
                return y_1 + (t - t1) / (t1 - t0) * (y_1 - y_0)
        return self._y_prev[-1][1].copy() if self._y_prev else y0.copy()

    def _remember(self, y: np.ndarray) -> None:
        """Keep this step's Gamma3 solution (and its time) for the next start."""
        t = float(self.problem.time_data.t.value)
        self._y_prev = [*self._y_prev[-1:], (t, y)]

    def describe(self) -> str:
        """The solver as the run's log line names it.

        Returns:
            'fast (one factorisation, <m> Gamma3 dofs condensed)', or without the count if
            the case has no Gamma3.
        """
        return (f"fast (one factorisation, {self.m} Gamma3 dofs condensed)" if self.gamma3
                else "fast (one factorisation)")

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
        return {"dofs": self.m, **(self._local_counts() or self._counts)}

    def _local_counts(self) -> dict | None:
        """The counts of ``gamma3_stats`` on GAMMA3_ROOT, as they are; None elsewhere (which
        keep the root's of the last Gamma3 problem)."""
        if self._direction is None:
            return None
        return {"factorisations": self._direction.factorisations,
                "cg_iterations": self._direction.cg_iterations, "threads": threads.cores()}

    def warm_start(self) -> None:
        """Start the next Gamma3 problem from the current u (after a restart)."""
        if self.gamma3:
            y = self._to_work(self._gather_G(self.u.vector))
            self._y_prev = [(None, y)] if self.on_root else []

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
            return self._solve_fast()
        except StepSolveError as exc:
            if self._snes is None:
                from vpcontact.solvers.snesvi import SNESVISolver
                self._snes = SNESVISolver(self.problem, self.options,
                                          roundoff_floor=self.roundoff_floor)
            log.warning("  fast solver: %s; solving this step with SNES VI", exc)
            its = self._snes.solve()
            self.fallback = "snes_vi"
            return its

    def _gamma3_inputs(self) -> None:
        """The step's memory term xi_n and slip factor theta(s_n) at the Gamma3 nodes."""
        p = self.problem
        if p.xi is not None:
            self.contact.xi = self._gather_nodal(p.xi)
        if p.theta is not None:
            self.contact.theta = self._gather_nodal(p.theta)

    def _solve_split(self) -> int:
        """A step with the split solve (serial: the compiled sweeps; mpirun: MUMPS's
        condensation and expansion): u = K^-1 (F_n + E_G lambda) in one solve."""
        self._assemble_rhs()
        r = self._split.forward(self.b.array_r)       # r = F_G - K_GI K_II^-1 F_I (root)
        its, y = 0, np.zeros(0)
        if self.gamma3:
            self._gamma3_inputs()
            # y0 = S^-1 r: the Gamma3 values if free
            y, its = self._root_problem(lambda: cholesky_solve(self.C, r))
        self._split.backward(y, self.x.array)
        self._set_u()
        return its

    def _root_problem(self, free_values) -> tuple[np.ndarray, int]:
        """The Gamma3 problem on GAMMA3_ROOT, the other ranks waiting asleep for it
        (threads.root_call; collective).

        Args:
            free_values: called on the root only: y0, the Gamma3 values if free.

        Returns:
            (y, iterations), on every rank.

        Raises:
            StepSolveError: on every rank, if the root's iteration failed.
        """
        def solve():
            y, its = self._small_problem(free_values())
            return y, its, self._local_counts()
        y, its, self._counts = threads.root_call(self.comm, solve)
        return y, its

    def _set_u(self) -> None:
        """u = x, unless x is not finite anywhere (then StepSolveError on every rank)."""
        if self.comm.allreduce(not np.all(np.isfinite(self.x.array_r)), op=MPI.LOR):
            raise StepSolveError("fast solver: non-finite solution")
        self.u.vector.array[:self.x.getLocalSize()] = self.x.array_r
        self.u.x.scatter_forward()

    def _solve_fast(self) -> int:
        if self._split is not None:
            return self._solve_split()
        self._assemble_rhs()
        self.ksp.solve(self.b, self.x)               # u_free = K^-1 F_n
        its = 0
        if self.gamma3:
            y0 = self._gather_G(self.x)
            self._gamma3_inputs()
            y, its = self._root_problem(lambda: y0)
            lam = self.S @ (y - y0) if self.on_root else None           # Gamma3 forces
            lam = self.comm.bcast(lam, root=threads.GAMMA3_ROOT)
            self.b.array[self.owned_dofs_local] += lam[self._owned_positions]
            self.ksp.solve(self.b, self.x)           # u = K^-1 (F_n + E_G lambda)
        self._set_u()
        return its

    def destroy(self) -> None:
        """Free the PETSc objects (and those of the SNES VI fallback, if it was created)."""
        for obj in (self.K, self.ksp, self.b, self.x, self._loads, self._lift, self._mumps):
            if obj is not None:
                obj.destroy()
        if self._snes is not None:
            self._snes.destroy()
