"""Step solver: PETSc SNES vinewtonrsls for the discrete inequality (3.4) on U^h.

Bounds only on the normal dofs of Gamma3 nodes (in the nodal frames where Gamma3 is curved:
app/solvers/rotation.py); Dirichlet dofs are imposed in the residual and Jacobian (set_bc /
diagonal 1).  Direct LU (MUMPS) by default.  The options (app/solvers/options.py) are put
into PETSc's database under our prefix once, when the solver is built, and taken out when it
is destroyed, so every PETSc option works, also those PETSc reads while solving (monitors,
views, the multigrid levels' set-up).
"""
from __future__ import annotations

import logging

import numpy as np
from dolfinx import cpp as _cpp
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact.io.errors import StepSolveError
from vpcontact.solvers.amg import InactiveSetAMG, rigid_body_modes
from vpcontact.solvers.bulkresidual import BulkProductResidual
from vpcontact.solvers.inactiveschur import (
    SCHUR_PETSC,
    GammaSchur,
    InactiveSetSchur,
    schur_refusal,
)
from vpcontact.solvers.levels import SymmetricCopy, is_symmetric
from vpcontact.solvers.matrices import share_pattern
from vpcontact.solvers.options import PREFIX, push_options, remove_options
from vpcontact.solvers.pairmap import PairMap
from vpcontact.solvers.rotation import FrameMap

log = logging.getLogger("vpcontact")

# SNES types that rewrite the Jacobian matrix in place (vinewtonssls: D_b J + D_a)
REWRITES_J = ("vinewtonssls",)
_REASONS = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}
_KSP_REASONS = {v: k for k, v in vars(PETSc.KSP.ConvergedReason).items() if isinstance(v, int)}
# CG's stops on negative curvature, and the Krylov method that replaces it then
INDEFINITE = (PETSc.KSP.ConvergedReason.DIVERGED_INDEFINITE_PC,
              PETSc.KSP.ConvergedReason.DIVERGED_INDEFINITE_MAT)
INDEFINITE_KSP = {"ksp_type": "gmres", "ksp_gmres_restart": 100}
# the residual's round-off floor: ROUNDOFF_FACTOR eps || |J| |x| ||_2 (RoundoffFloor), the
# componentwise bound of the error of a computed residual: a nearly incompressible body
# stalls above snes_atol, while the paper's case keeps the results it has without the floor
# (docs/performance.md, section 9)
ROUNDOFF_FACTOR = 1.0
# an iterate with |x| beyond BLOWUP times the body's size has run away (small strains):
# the floor is not raised there, and a failure says why
BLOWUP = 1e3
# a SNES whose residual repeats itself (equal to 1e-6 to that of two iterations before, in
# 4 iterations in a row: Newton cycling between one or two iterates) has stagnated: it is
# stopped, and the next fallback takes over (_watch_stagnation)
STAGNATION = (4, 1e-6)
RUNAWAY_HINT = ("the Newton iterate ran away (|u| beyond 1000 times the body's size): the "
                "Newton matrix is (nearly) singular, e.g. a body free in a rigid motion that "
                "only a contact not yet active holds")


def describe_petsc_error(exc: Exception) -> str:
    """One line for a PETSc error: petsc4py's text is 'error code N', PETSc's stack of
    calls ('[0] SNESSolve() at file:line', ...) and the message; keep the code and the
    message.

    Args:
        exc: a petsc4py.PETSc.Error (or any exception: its text is used).

    Returns:
        'PETSc error code N; <message lines joined by '; '>'.
    """
    lines = [x.strip() for x in str(exc).splitlines() if x.strip()]
    message = [x for x in lines[1:] if not (x.startswith("[") and "() at " in x)]
    message = [x.split("] ", 1)[1] if x.startswith("[") and "] " in x else x for x in message]
    return "; ".join(([f"PETSc {lines[0]}"] if lines else []) + message)


def reason_name(reason: int) -> str:
    """The name of a SNES converged reason.

    Args:
        reason: SNES.getConvergedReason() (negative: diverged).

    Returns:
        The name in PETSc.SNES.ConvergedReason (e.g. 'DIVERGED_MAX_IT'), or the number as
        text if it has none.
    """
    return _REASONS.get(reason, str(reason))


def direct_solver(A: PETSc.Mat, comm, prefix: str | None = None) -> PETSc.KSP:
    """A KSP applying A^-1 by LU: PETSc's own LU with nested dissection in serial (the fastest
    back-substitution on these machines: docs/performance.md, section 3), MUMPS in parallel.
    Options under ``prefix`` (e.g. -vpcontact_fast_pc_factor_mat_solver_type mumps) are read by
    the caller's setFromOptions.

    Args:
        A: the matrix to factorise (square, assembled).
        comm: A's MPI communicator (one rank: PETSc LU; more: MUMPS).
        prefix: the KSP's options prefix, or None for none.

    Returns:
        The KSP (type preonly, PC lu), not yet set up.
    """
    ksp = PETSc.KSP().create(comm)
    if prefix:
        ksp.setOptionsPrefix(prefix)
    ksp.setOperators(A)
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType("lu")
    if comm.size == 1:
        pc.setFactorSolverType("petsc")
        pc.setFactorOrdering("nd")
    else:
        pc.setFactorSolverType("mumps")
    return ksp


def continuation_deltas(target: float, length: float) -> list[float]:
    """The stages of the continuation in the regularisation delta (of |xi|_delta =
    sqrt(|xi|^2 + delta^2) in the friction (4.2) and of r^+ in the memory term).

    Args:
        target: the case's delta [m].
        length: the problem's length scale [m].

    Returns:
        Decreasing deltas from delta_0 = max(target, 1e-4 length) by factors of 10, the last
        exactly ``target`` (just [target] if delta_0 = target).
    """
    start = max(target, 1e-4 * length)
    n = int(np.ceil(np.log10(start / target) - 1e-9))
    return [target * 10.0 ** k for k in range(n, 0, -1)] + [target] if n > 0 else [target]


def _assemble_without_diagonal(A: PETSc.Mat, form, bcs) -> None:
    """Add a bilinear form into A with the Dirichlet rows and columns left out, as
    dolfinx's assemble_matrix does, but without its diagonal at every Dirichlet row (outside
    the pattern of a form on a part of the boundary).

    Args:
        A: the matrix (not final: call A.assemble()).
        form: the compiled bilinear form.
        bcs: the Dirichlet conditions.
    """
    _cpp.fem.petsc.assemble_matrix(A, form, _cpp.fem.pack_constants(form),
                                   _cpp.fem.pack_coefficients(form), bcs)


class GammaEntries:
    """K's values at the entries of the Gamma3 matrix B (B's owned rows, in CSR order), read
    from A while A holds K alone; ``insert`` sets A's entries there to K + B (exactly:
    INSERT_VALUES, so a B many orders above K does not leave its round-off in A).

    Args:
        A: the Jacobian matrix, holding the bulk stiffness K only.
        B: the Gamma3 matrix, assembled once (its pattern is fixed from then on).
    """

    def __init__(self, A: PETSc.Mat, B: PETSc.Mat):
        ai, aj, _ = B.getValuesCSR()
        counts = np.diff(ai)
        self.rows = (B.getOwnershipRange()[0] + np.flatnonzero(counts)).astype(PETSc.IntType)
        self.ptr = np.concatenate([[0], np.cumsum(counts[counts > 0])]).astype(PETSc.IntType)
        self.cols = aj.astype(PETSc.IntType)
        self.values = np.concatenate(
            [A.getValues([r], self.cols[self.ptr[k]:self.ptr[k + 1]]).ravel()
             for k, r in enumerate(self.rows)]) if len(self.rows) else np.zeros(0)

    def insert(self, A: PETSc.Mat, B: PETSc.Mat) -> None:
        """A's entries at B's set to K + B (A to be assembled after).

        Args:
            A: the Jacobian matrix.
            B: the Gamma3 matrix, assembled, with the pattern it had at construction.
        """
        _, aj, av = B.getValuesCSR()
        if len(aj) != len(self.cols):
            raise RuntimeError("the Gamma3 matrix changed its pattern")
        A.setValuesIJV(self.ptr, self.cols, self.values + av, rowmap=self.rows,
                       addv=PETSc.InsertMode.INSERT_VALUES)


class RoundoffFloor:
    """The residual norm that Newton's method cannot go below in floating point: the
    residual F(x) = J x - f + ... is summed from terms as large as |J| |x| (entrywise
    absolute values), so its computed value carries errors of order eps |J| |x|.  A problem
    whose stiffness varies by orders of magnitude (nu -> 1/2: lambda / mu = 5000 at
    nu = 0.4999) has ||F|| >> eps || |J| |x| || only far from the solution, and a fixed
    absolute tolerance below the floor is never met (the condensed solver's tolerances scale
    with its Schur complement S y0 the same way, app/solvers/condensed/).

    The floor is ROUNDOFF_FACTOR eps || |J| |x| ||_2 with |J| from the first assembled
    Jacobian (its magnitude, not its value, matters).  |J| is kept for the run: on one rank,
    where J is symmetric with whole d x d blocks (the Hessian of the step energy), in the
    SBAIJ format (app/solvers/levels.py: the upper block triangle, about half of the AIJ
    copy's values; docs/performance.md, section 7), else as an AIJ matrix sharing J's
    pattern.
    """

    def __init__(self):
        self.abs_J = None
        self.abs_x = self.y = None

    def __call__(self, J: PETSc.Mat, x: PETSc.Vec) -> float:
        """The floor at the iterate x.

        Args:
            J: the Jacobian (AIJ; used once, when first assembled).
            x: the iterate, in J's dofs.

        Returns:
            ROUNDOFF_FACTOR eps || |J| |x| ||_2; 0 before J is assembled.
        """
        if self.abs_J is None:
            if not J.assembled:
                return 0.0
            self.abs_J = _absolute(J)
            self.abs_x, self.y = self.abs_J.createVecs()
        self.abs_x.array[:] = np.abs(x.array_r)
        self.abs_J.mult(self.abs_x, self.y)
        return ROUNDOFF_FACTOR * np.finfo(float).eps * self.y.norm()

    def destroy(self) -> None:
        """Free the PETSc objects."""
        for obj in (self.abs_J, self.abs_x, self.y):
            if obj is not None:
                obj.destroy()


def _absolute(J: PETSc.Mat) -> PETSc.Mat:
    """|J|, entrywise: in SBAIJ where J is sequential, symmetric (levels.is_symmetric) and
    made of whole blocks, else AIJ with J's pattern shared."""
    if J.getComm().size == 1 and J.getBlockSize() > 1 and is_symmetric(J):
        try:
            return SymmetricCopy(J, absolute=True).mat
        except ValueError:                      # a pattern without whole blocks
            pass
    ai, aj, av = J.getValuesCSR()
    abs_J = J.duplicate(copy=share_pattern(J))
    abs_J.setValuesCSR(ai, aj, np.abs(av))
    abs_J.assemble()
    return abs_J


class SNESVISolver:
    """Solves one step of (3.4): u_n = argmin J_n over U^h (the variational inequality on the
    convex set of the bound u_nu <= g), starting from the current ``problem.u``.  A StepSolver
    (app/solvers/__init__.py).

    A second SNES with a backtracking line search (other options as given) is the fallback when
    the first fails: full Newton steps can cycle between two iterates when a node crosses a
    nearly nonsmooth point (u_nu = 0 with a memory force, |u_tau| = 0 with friction).

    The Newton systems are solved by ``options`` (default: LU) or, with ``linear="amg"``, by
    the KSP the options give (CG) preconditioned by GAMG with the rigid body modes restricted
    to the inactive set (app/solvers/amg.py), or, with ``linear="schur"`` where it applies,
    by one factorisation of K per run and a dense Gamma3 Schur complement per Newton
    iteration (app/solvers/inactiveschur.py; elsewhere LU, the reason logged).

    Args:
        problem: the ContactProblem (forms F, J, bounds, Dirichlet conditions).
        options: PETSc options (name without '-' -> value), set under ``prefix``.
        prefix: the PETSc options prefix of the SNES.
        linear: "direct" (the options' KSP and PC), "amg" (InactiveSetAMG as the PC) or
            "schur" (InactiveSetSchur as the PC where it applies, else "direct").
        roundoff_floor: the absolute tolerance is the options' snes_atol or the residual's
            round-off floor (RoundoffFloor), whichever is larger, at every iteration; False
            (a snes_atol the user gave): the options' snes_atol alone.
    """

    ROBUST = {"snes_linesearch_type": "bt"}
    name = "snes_vi"
    factorisations = None          # refactorised in every Newton iteration (not "schur": 1)

    def __init__(self, problem, options: dict, prefix: str = PREFIX, linear: str = "direct",
                 roundoff_floor: bool = True):
        self.problem = problem
        self.floor = RoundoffFloor() if roundoff_floor else None
        self.ran_away = self.stagnated = False
        self._fnorms: list[float] = []
        self.linear = linear
        self.linear_iterations = 0
        self.u = problem.u
        self.b = fem.petsc.create_vector(problem.F_form)
        self.A = fem.petsc.create_matrix(problem.J_form)
        # two bodies: SNES solves for x of app/solvers/pairmap.py (the pairs' bound a box)
        disc = problem.disc
        self.pairs = PairMap(problem) if disc.pairs is not None else None
        if self.pairs is None:
            self._setup_jacobian_reuse(problem)
        else:
            self.reuse, self.K, self.B, self._residual = False, None, None, None
        self.x = self.u.vector.copy()
        # curved Gamma3: SNES solves for x = R^T u in the nodal frames (app/solvers/rotation.py)
        self.frames = None
        # rigid caps: and for their amplitudes (app/model/rigidcap.py; two bodies: in PairMap)
        rotated = disc.frames is not None and disc.frames.rotated
        if (rotated or disc.caps is not None) and self.pairs is None:
            self.frames = FrameMap(problem, self.u.vector)
            self.b_frames = self.b.duplicate()
            if not self.reuse:                   # the pattern of J for the first PtAP
                fem.petsc.assemble_matrix(self.A, problem.J_form, disc.bcs)
                self.A.assemble()
            self.A_frames = self.frames.product(self.A)
        self.options, self.prefix = dict(options), prefix
        push_options(self.options, prefix)      # in the database while the solver lives
        self.schur = None                        # linear "schur": app/solvers/inactiveschur.py
        if linear == "schur":
            self._setup_schur(self.frames is not None)
        self._lb = self._ub = None               # the bounds (set with the first VI SNES)
        self.snes = self._create()
        self._keep_bulk()
        self._robust = None
        self.continuation_stages = 0
        self.fallback = None
        self.sticky_robust = False
        self._past: list[tuple[float, np.ndarray]] = []   # (t, x) of the last two solves
        self._pinned = None     # press_next: x's dofs held at their values in a first solve

    def _create(self, robust: bool = False):
        """A SNES reading this solver's options; ``robust``: with ROBUST on top (the
        database keeps this solver's options: ROBUST is put in for the SNES's
        setFromOptions only)."""
        snes = PETSc.SNES().create(self.problem.disc.comm)
        snes.setOptionsPrefix(self.prefix)
        if self.pairs is not None:
            snes.setFunction(self._F_pairs, self.b)
            snes.setJacobian(self._J_pairs, self.pairs.A, self.pairs.A)
        elif self.frames is None:
            snes.setFunction(self._F, self.b)
            snes.setJacobian(self._J, self.A, self.A)
        else:
            snes.setFunction(self._F_frames, self.b_frames)
            snes.setJacobian(self._J_frames, self.A_frames, self.A_frames)
        if robust:
            push_options(self.ROBUST, self.prefix)
        try:
            snes.setFromOptions()
        finally:
            if robust:
                remove_options(self.ROBUST, self.prefix)
                push_options({k: v for k, v in self.options.items() if k in self.ROBUST},
                             self.prefix)
        if snes.getType().startswith("vi"):
            lb, ub = self.problem.disc.bounds(self.problem.u.vector)
            snes.setVariableBounds(lb, ub)
            self._lb, self._ub = lb, ub
        if self.floor is not None:
            atol = snes.getTolerances()[1]
            snes.setMonitor(lambda s, its, fnorm: self._raise_atol(s, atol))
        max_funcs = snes.getMaxFunctionEvaluations()
        snes.setMonitor(lambda s, its, fnorm: self._watch_stagnation(s, its, fnorm,
                                                                     max_funcs))
        if self.linear == "amg":
            pc = snes.getKSP().getPC()
            pc.setType("python")
            pc.setPythonContext(InactiveSetAMG(snes, self._rigid_body_modes(), self.prefix,
                                               self._changing_rows))
        elif self.linear == "schur":             # (KSP preonly, PC python: SCHUR_PETSC)
            snes.getKSP().getPC().setPythonContext(InactiveSetSchur(snes, self.schur))
        return snes

    def _setup_schur(self, framed: bool) -> None:
        """The Newton systems by one factorisation of K and the Gamma3 Schur complement
        (app/solvers/inactiveschur.py) where it applies, else (logged with the reason) by LU
        at every Newton iteration (``linear`` becomes "direct").  A holds K alone here.

        Args:
            framed: SNES VI solves in nodal frames or for rigid caps' amplitudes.
        """
        why = schur_refusal(self.problem, self.options, self.reuse, framed)
        if not why:
            try:
                self.schur = GammaSchur(self.problem, self.A, lambda: self.B)
            except np.linalg.LinAlgError:
                why = "K's Schur complement on Gamma3 is not positive definite"
        if self.schur is not None:
            lb, ub = self.problem.disc.bounds(self.problem.u.vector)
            if not self.schur.covers(lb, ub):
                why = "bounds on dofs outside the Gamma3 nodes"
            for obj in (lb, ub):
                obj.destroy()
        if why:
            if self.schur is not None:
                self.schur.destroy()
            self.schur, self.linear = None, "direct"
            log.info("  SNES VI: LU of every Newton system (the Gamma3 Schur complement "
                     "does not apply: %s)", why)
            return
        self.factorisations = 1
        # in the database: vinewtonrsls resets its KSP from the options when the inactive
        # set changes (KSPResetFromOptions), and pc_type lu there would replace this PC
        self.options.update(SCHUR_PETSC)
        push_options(SCHUR_PETSC, self.prefix)
        log.info("  SNES VI: one factorisation of K, the Newton systems by the Gamma3 Schur "
                 "complement (%d Gamma3 dofs)", self.schur.m)

    def _changing_rows(self) -> np.ndarray | None:
        """The local rows of SNES's Jacobian that change between Newton iterations (explicit
        scheme: the Gamma3 terms B and the bounded dofs, with every dof of their nodes, as
        the nodal frames mix a node's dofs); None when all may (implicit scheme, two bodies).
        """
        if not self.reuse or self.pairs is not None or self._lb is None \
                or self.problem.disc.comm.size > 1:
            return None
        bounded = (self._lb.array_r > PETSc.NINFINITY) | (self._ub.array_r < PETSc.INFINITY)
        if self.B is not None:
            bounded[np.flatnonzero(np.diff(self.B.getRowIJ()[0]))] = True
        bs = self.A.getBlockSize()
        nodes = np.flatnonzero(bounded.reshape(-1, bs).any(axis=1))
        return (bs * nodes[:, None] + np.arange(bs)).ravel()

    def _watch_stagnation(self, snes, its: int, fnorm: float, max_funcs: int) -> None:
        """Stop a SNES whose residual has stagnated (STAGNATION: it repeats itself, Newton
        cycling between one or two iterates at a nearly nonsmooth point of the friction or
        memory term; iterates that still move, however wildly, go on), so that the
        next fallback starts at once instead of after snes_max_it iterations.  SNES stops
        with DIVERGED_FUNCTION_COUNT at its convergence test (the residual evaluations
        allowed are lowered to those done; restored at the start of the next solve)."""
        if its == 0:
            self._fnorms = []
            snes.setMaxFunctionEvaluations(max_funcs)
        self._fnorms.append(fnorm)
        count, tol = STAGNATION
        f = self._fnorms
        if len(f) >= count + 2 and all(abs(f[k] - f[k - 2]) <= tol * f[k]
                                       for k in range(len(f) - count, len(f))):
            self.stagnated = True
            snes.setMaxFunctionEvaluations(snes.getFunctionEvaluations())

    def _raise_atol(self, snes, atol: float) -> None:
        """Before SNES's convergence test of an iteration (PETSc calls the monitors first):
        its absolute tolerance becomes max(atol, the round-off floor at the iterate) -- not
        at an iterate that has run away (|x| beyond BLOWUP times the body's size: a
        (nearly) singular Newton matrix, e.g. a body free in a rigid motion that only an
        inactive contact would hold), whose floor would grow with it and stop SNES at a
        residual of the order of the loads."""
        x = snes.getSolution()
        if x.norm(PETSc.NormType.NORM_INFINITY) > BLOWUP * self.problem.disc.length_scale:
            self.ran_away = True
            snes.setTolerances(atol=atol)
            return
        J = snes.getJacobian()[0]
        snes.setTolerances(atol=max(atol, self.floor(J, x)))

    def _rigid_body_modes(self) -> np.ndarray:
        """The rigid body modes in the dofs SNES solves for: Z, or R^T Z in the nodal frames.

        Returns:
            (owned dofs, modes) array.
        """
        Z = rigid_body_modes(self.problem.disc.V)
        if self.pairs is not None:
            return self.pairs.modes(Z)
        if self.frames is None:
            return Z
        z, zr = self.A_frames.createVecs()
        for j in range(Z.shape[1]):
            z.array[:] = Z[:, j]
            self.frames.to_frames(z, zr)
            Z[:, j] = zr.array
        return Z

    @property
    def gamma3(self) -> bool:
        """Whether this solver holds K's Schur complement on Gamma3 (linear "schur"): the
        (2.6) diagnostic's bound of ||gamma||^2 (app/post/diagnostics.py) reads ``S``,
        ``C``, ``layout`` and ``m`` then, as of the condensed solver."""
        return self.schur is not None

    @property
    def S(self) -> np.ndarray:
        """K's Schur complement on Gamma3 (linear "schur" only: else AttributeError)."""
        return self._schur_part("S")

    @property
    def C(self) -> np.ndarray:
        """S's lower Cholesky factor (linear "schur" only)."""
        return self._schur_part("C")

    @property
    def layout(self):
        """The Gamma3Layout of S (linear "schur" only)."""
        return self._schur_part("layout")

    @property
    def m(self) -> int:
        """The Gamma3 dofs of S (linear "schur" only)."""
        return self._schur_part("m")

    def _schur_part(self, name: str):
        """An attribute of the GammaSchur (C: its condensation's), or AttributeError
        without one."""
        if self.schur is None:
            raise AttributeError(f"{name}: SNES VI holds no Schur complement (linear "
                                 f"{self.linear})")
        return getattr(self.schur.condensation if name == "C" else self.schur, name)

    def describe(self) -> str:
        """The solver as the run's log line names it.

        Returns:
            'SNES <type>', e.g. 'SNES vinewtonrsls'.
        """
        linear = {"amg": ", CG + GAMG with the rigid body modes",
                  "schur": ", one factorisation of K and the Gamma3 Schur complement"}.get(
                      self.linear, "")
        return f"SNES {self.snes.getType()}{linear}"

    def amg_stats(self) -> dict | None:
        """The iterative path's multigrid work so far (summary.json solver.amg).

        Returns:
            {"setups": GAMG set-ups, "interpolations": those that built the interpolation
            (the others: Galerkin products on the kept one), "kept": Newton iterations that
            kept the PC}, over this solver's SNESes; None on the direct path.
        """
        if self.linear != "amg":
            return None
        pcs = [s.getKSP().getPC().getPythonContext() for s in (self.snes, self._robust)
               if s is not None]
        return {"setups": sum(pc.setups for pc in pcs), "kept": sum(pc.reuses for pc in pcs),
                "interpolations": sum(pc.interpolations for pc in pcs)}

    def warm_start(self) -> None:
        """Start the next solve from the current u (after a restart: u_n), not from an
        extrapolation of solutions before it."""
        self._past = []

    def _remember(self) -> None:
        """Keep this solve's solution x_n and t_n for the next start (a second solve at
        the same t_n, Coulomb's fixed point, replaces it)."""
        t = float(self.problem.time_data.t.value)
        past = [p for p in self._past if p[0] != t][-1:]
        self._past = [*past, (t, self.x.array_r.copy())]

    def _extrapolate(self) -> None:
        """The Newton iteration's start x (holding u_{n-1}): the linear extrapolation in
        time x_{n-1} + (t_n - t_{n-1}) / (t_{n-1} - t_{n-2}) (x_{n-1} - x_{n-2}) of the
        last two solutions, put into the bounds (SNES VI starts from a feasible point).
        Unchanged where they are not the last two steps of this run (first step, a
        restart, a rejected or repeated step).  The step problems change smoothly in t, so
        Newton needs fewer iterations (docs/performance.md, section 7)."""
        t = float(self.problem.time_data.t.value)
        x = self.x.array
        ok = len(self._past) == 2 and t > self._past[1][0] > self._past[0][0] \
            and np.array_equal(x, self._past[1][1])
        if not self.problem.disc.comm.allreduce(ok, op=MPI.LAND):
            return
        (t0, x0), (t1, x1) = self._past
        x += (t - t1) / (t1 - t0) * (x1 - x0)
        np.clip(x, self._lb.array_r, self._ub.array_r, out=x)

    @property
    def robust(self):
        """The fallback SNES with a backtracking line search (created when first needed)."""
        if self._robust is None:
            self._robust = self._create(robust=True)
        return self._robust

    def _F(self, snes, x, b):
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        x.copy(self.u.vector)
        self.u.x.scatter_forward()
        if self._residual is not None:           # explicit scheme: K x + c_n + Gamma3 terms
            self._residual(self.K if self.K is not None else self.A, x, b)
            return
        with b.localForm() as bl:
            bl.set(0.0)
        if not self.problem.before_residual():
            with b.localForm() as bl:   # the local stress update failed: let SNES see NaN
                bl.set(np.nan)
            return
        bcs = self.problem.disc.bcs
        fem.petsc.assemble_vector(b, self.problem.F_form)
        fem.petsc.apply_lifting(b, [self.problem.J_form], [bcs], x0=[x], scale=-1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem.petsc.set_bc(b, bcs, x, -1.0)

    def _F_pairs(self, snes, x, b):
        """The residual of two bodies in x (app/solvers/pairmap.py)."""
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        if not self.pairs.residual(x, b):
            with b.localForm() as bl:   # the local stress update failed: let SNES see NaN
                bl.set(np.nan)

    def _J_pairs(self, snes, x, A, P):
        """The Jacobian of two bodies in x (at the w of the last residual)."""
        self._release_last_system(snes)
        self.pairs.jacobian()

    def _F_frames(self, snes, x, b):
        """The residual in the nodal frames (and the caps' amplitudes): M^T F(M x)."""
        fm = self.frames
        fm.from_frames(x, fm.u_work)
        self._F(snes, fm.u_work, fm.F_work)
        fm.pull_back(fm.F_work, b)

    def _J_frames(self, snes, x, A, P):
        """The Jacobian in the nodal frames: M^T J M (J at u = M x, set by the residual)."""
        self._J(snes, None, self.A, self.A)
        self.frames.product(self.A, result=A)

    def _setup_jacobian_reuse(self, problem) -> None:
        """Explicit scheme: the bulk Jacobian K = (E eps(du), eps(v)) is the same in every
        Newton iteration of every step.  Assemble it once, into A; per iteration only the
        Gamma3 terms change.  They are assembled into B, a matrix with the pattern of the
        Gamma3 facets' dofs only, and A's entries there are set to K's values (kept,
        GammaEntries) plus B's: J = K + B in A with J's sparsity pattern throughout (the
        direct solver keeps its symbolic factorisation and only refactorises numerically)
        and no copy of K (docs/performance.md, section 7).  (Not A <- A - B_old + B_new: a stiff
        compliance, c_nu = 1e20 with B about 1e16 K, loses K's digits in the subtraction.)
        A SNES that rewrites J in place (REWRITES_J: vinewtonssls scales its rows and shifts
        its diagonal) gets A from a kept copy of K first (``_keep_bulk``)."""
        self.reuse = False
        self.K = self.B = self._boundary_form = self._residual = None
        forms = problem.forms
        if problem.implicit or forms.bulk_jacobian is None:
            return
        # K's assembly sets every entry of every cell's dofs (zeros included), so A keeps
        # the whole pattern of J = K + B: B couples the dofs of a Gamma3 facet's cell only
        bulk_form = fem.form(forms.bulk_jacobian)
        fem.petsc.assemble_matrix(self.A, bulk_form, problem.disc.bcs)
        self.A.assemble()
        self.reuse = True
        if forms.boundary_jacobian is not None:
            self._boundary_form = fem.form(forms.boundary_jacobian)
            self.B = fem.petsc.create_matrix(self._boundary_form)
        self._K_at_B = None
        self._residual = BulkProductResidual(problem, bulk_form, self._boundary_form, self.b)

    def _keep_bulk(self) -> None:
        """A copy K of the bulk Jacobian in A (before any Gamma3 term is added) when the SNES
        rewrites its Jacobian in place (see _setup_jacobian_reuse)."""
        if self.reuse and self.snes.getType() in REWRITES_J:
            self.K = self.A.duplicate(copy=share_pattern(self.A))
            self.A.copy(self.K, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)

    def _release_last_system(self, snes) -> None:
        """Before a new Jacobian, the KSP lets go of the last Newton system (CG + GAMG path):
        vinewtonrsls extracts the next J_II while the KSP still holds the last one, two copies
        of the largest matrix at once (the peak memory it saves: docs/performance.md, section
        7).  The direct path keeps its KSP (the LU's symbolic factorisation is reused)."""
        if self.linear == "amg":
            snes.getKSP().reset()

    def _J(self, snes, x, A, P):
        self._release_last_system(snes)
        if not self.reuse:                       # implicit scheme: the tangent changes
            A.zeroEntries()
            fem.petsc.assemble_matrix(A, self.problem.J_form, self.problem.disc.bcs)
            A.assemble()
            return
        if self.K is not None:
            self.K.copy(A, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        if self.B is not None:
            # Dirichlet rows/columns: skipped (their diagonal: K's 1 in A)
            self.B.zeroEntries()
            _assemble_without_diagonal(self.B, self._boundary_form, self.problem.disc.bcs)
            self.B.assemble()
            if self._K_at_B is None:             # A holds K alone: its values at B's entries
                self._K_at_B = GammaEntries(A, self.B)
                if self.K is None and self._residual is not None:   # K x's rows R from K
                    self._residual.keep_rows(A, self._K_at_B.rows)
            self._K_at_B.insert(A, self.B)
        A.assemble()                             # (a never-assembled A stays flagged so)

    def _snes_solve(self, snes, extrapolate: bool = False) -> None:
        """SNES from the current u, or with ``extrapolate`` from the extrapolation of the
        last steps (our options are in the database while it runs: PCs set up their parts,
        e.g. multigrid levels, from it when the inactive set changes)."""
        self._to_x()
        if extrapolate and self._lb is not None:
            self._extrapolate()
            if self.frames is not None:       # the caps' prescribed amplitudes at t_n
                self.frames.fix(self.x)
            elif self.pairs is not None:
                self.pairs.fix(self.x)
        if self._residual is not None:
            self._residual.new_solve()
        snes.solve(None, self.x)

    def _met_negative_curvature(self, snes) -> bool:
        """Whether CG stopped on a direction of negative curvature: the Jacobian was
        indefinite (nonmonotone friction beyond the well-posedness bound (2.6)); then
        GMRES (INDEFINITE_KSP) replaces CG in this solver's SNESes from now on.

        Args:
            snes: the SNES that just ran.

        Returns:
            True if CG was replaced (the solve should be repeated).
        """
        ksp = snes.getKSP()
        if snes.getConvergedReason() != PETSc.SNES.ConvergedReason.DIVERGED_LINEAR_SOLVE \
                or ksp.getType() != "cg" or ksp.getConvergedReason() not in INDEFINITE:
            return False
        log.warning("SNES VI: the Newton system is indefinite (CG: %s); GMRES from now on",
                    _KSP_REASONS.get(ksp.getConvergedReason()))
        self.options = {**self.options, **INDEFINITE_KSP}
        push_options(INDEFINITE_KSP, self.prefix)
        for other in (self.snes, self._robust):
            if other is not None:
                other.getKSP().setType("gmres")
                other.getKSP().setGMRESRestart(INDEFINITE_KSP["ksp_gmres_restart"])
        return True

    def _solve_once(self, snes, extrapolate: bool = False) -> int:
        self.ran_away = self.stagnated = False
        self._snes_solve(snes, extrapolate)
        wasted = 0
        if self._met_negative_curvature(snes):
            wasted = snes.getIterationNumber()
            self.linear_iterations += snes.getLinearSolveIterations()
            self._snes_solve(snes)
        reason = snes.getConvergedReason()
        its = snes.getIterationNumber() + wasted
        self.linear_iterations += snes.getLinearSolveIterations()
        if reason <= 0:
            hint = f" ({RUNAWAY_HINT})" if self.ran_away else \
                " (stagnated: Newton cycled, its residual repeating itself)" \
                if self.stagnated else ""
            raise StepSolveError(f"SNES did not converge: {reason_name(reason)} ({reason}) "
                                 f"after {its} Newton iterations{hint}", reason)
        self._to_u()
        self._remember()
        return its

    def solve(self) -> int:
        """Solve (3.4) from the current u (u_{n-1}); on success u holds u_n.

        Fallbacks when SNES fails: (1) the backtracking SNES at the case's delta; (2) if the
        step has a regularised term, continuation in delta with it, from a wide
        regularisation down to the case's delta by factors of 10, each stage warm-started.
        Every fallback ends on the same discrete problem; ``self.fallback`` says which one
        was used (None: none) and ``self.continuation_stages`` how many stages.  After the
        first step that needed backtracking, later steps start with the backtracking SNES.

        Returns:
            The Newton iterations of all attempts of this step.

        Raises:
            StepSolveError: every attempt failed; u is restored to u_{n-1}.
        """
        if self._pinned is not None:
            self._press()
        start = self.u.x.array.copy()
        self.continuation_stages, self.fallback = 0, None
        self.linear_iterations = 0
        its = 0
        if not self.sticky_robust:
            try:
                return self._solve_once(self.snes, extrapolate=True)
            except StepSolveError as exc:
                first = exc
            its = self.snes.getIterationNumber()
            self.u.x.array[:] = start
        else:
            first = StepSolveError("(basic Newton skipped after an earlier failure)")
        try:
            its += self._solve_once(self.robust, extrapolate=self.sticky_robust)
            if not self.sticky_robust:
                self.fallback = "backtracking"
                self.sticky_robust = True  # the basic iteration cycles here: skip it from now on
            return its
        except StepSolveError as exc:
            second = exc
        its += self.robust.getIterationNumber()
        delta = self.problem.constants.get("delta")
        self.u.x.array[:] = start  # keep the last good state u_{n-1}
        if delta is None:
            raise StepSolveError(f"{first}; with backtracking: {second}", second.reason)
        target = float(delta.value)
        stages = continuation_deltas(target, self.problem.disc.length_scale)
        try:
            for d in stages:
                delta.value = d
                its += self._solve_once(self.robust)
        except StepSolveError as exc:
            self.u.x.array[:] = start
            raise StepSolveError(f"{first}; with backtracking: {second}; delta continuation "
                                 f"{stages[0]:g} -> {target:g} failed at delta = {d:g}: {exc}",
                                 exc.reason) from None
        finally:
            delta.value = target
        self.fallback = "delta continuation"
        self.continuation_stages = len(stages)
        return its

    def press_next(self, pinned: np.ndarray) -> None:
        """Start the next solve from a first solve with the dofs ``pinned`` of x (local
        indices: the normal slots of the Gamma3 nodes that a ContactHold brought into
        contact, app/model/semicoercive.py) held at their values.  A body held only by
        contact that starts touching has no residual on Gamma3 (its load reaches Gamma3
        only through the body): the VI's active set is empty and the Newton matrix singular
        in the free rigid motions; held, the body carries its load to Gamma3, whose
        reactions then press on the bound.

        Args:
            pinned: local indices into x (owned).
        """
        self._pinned = pinned

    def _press(self) -> None:
        """The first solve of ``press_next``: one Newton step from u with the pinned dofs
        held (their rows and columns of the Jacobian the identity, their increments 0),
        put into the bounds."""
        pinned, self._pinned = self._pinned, None
        comm = self.problem.disc.comm
        if self._lb is None or comm.allreduce(len(pinned)) == 0:
            return
        start = self.u.x.array.copy()
        F, J, b, A = (self._F_pairs, self._J_pairs, self.b, self.pairs.A) \
            if self.pairs is not None else (self._F, self._J, self.b, self.A) \
            if self.frames is None else (self._F_frames, self._J_frames, self.b_frames,
                                         self.A_frames)
        self._to_x()
        F(self.snes, self.x, b)
        J(self.snes, self.x, A, A)
        M, rhs, dx = A.duplicate(copy=True), b.copy(), self.x.duplicate()
        M.zeroRowsColumns((pinned + self.x.getOwnershipRange()[0]).astype(PETSc.IntType),
                          diag=1.0)
        rhs.array[pinned] = 0.0
        ksp = direct_solver(M, self.problem.disc.comm)
        ksp.solve(rhs, dx)
        self.x.axpy(-1.0, dx)
        np.clip(self.x.array, self._lb.array_r, self._ub.array_r, out=self.x.array)
        self._to_u()
        for obj in (ksp, M, rhs, dx):
            obj.destroy()
        if comm.allreduce(not np.all(np.isfinite(self.u.x.array)), op=MPI.LOR):
            self.u.x.array[:] = start           # the step's own solve starts from u
            return
        log.debug("  SNES VI: started from the body held at its %d contact node(s)",
                  comm.allreduce(len(pinned)))

    def _to_x(self) -> None:
        """x from u (two bodies: x of u = P x + c; curved Gamma3: in the nodal frames)."""
        if self.pairs is not None:
            self.pairs.to_x(self.u.vector, self.x)
        elif self.frames is None:
            self.u.vector.copy(self.x)
        else:
            self.frames.to_frames(self.u.vector, self.x)

    def _to_u(self) -> None:
        """u from x (``_to_x``'s inverse), ghosts updated."""
        if self.pairs is not None:
            self.pairs.to_u(self.x, self.u)
        elif self.frames is None:
            self.x.copy(self.u.vector)
        else:
            self.frames.from_frames(self.x, self.u.vector)
        self.u.x.scatter_forward()

    def destroy(self) -> None:
        """Free the PETSc objects (SNES, matrices, vectors) and take the options out of
        PETSc's database."""
        remove_options(self.options, self.prefix)
        for obj in (self.snes, self._robust, self.A, self.b, self.x, self.K, self.B,
                    self.floor, self._residual, self.schur):
            if obj is not None:
                obj.destroy()
        if self.frames is not None:
            for obj in (self.frames, self.b_frames, self.A_frames):
                obj.destroy()
        if self.pairs is not None:
            self.pairs.destroy()
