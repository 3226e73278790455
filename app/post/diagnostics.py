"""Stability and well-posedness diagnostics printed before a run.

- Explicit stability indicator: the history update of (3.2) relaxes the stress like
  sigma_n ~ (I - k E/(2 lambda1)) sigma_{n-1} on the excess over the yield ball, so with the
  largest relaxation rate r_max = lambda_max(E) / (2 lambda1) (the law's
  ``relaxation_rate``, else its Lipschitz constant L_G, app/model/laws.py) the explicit
  scheme needs k_max r_max <= 2 (above 1 the relaxation overshoots and oscillates).  A law
  whose rate grows with the stress (Norton's, Chaboche's) gives its linearisation's rate
  r(S) at the data's stress scale S (``rate_at_stress``; S of app/post/divergence.py
  ``stress_scale``: the loads, initial data, contact laws and E g / L).  A law that knows
  none of these has its rate estimated: the spectral radius of the finite-difference
  Jacobian dG/dsigma at the state's cell of largest ||sigma||_VM (``estimated_rate``);
  where that vanishes (a state at rest) the indicator is unknown.  The implicit variant has
  no such limit.
- Well-posedness (2.6): m_E > max{sqrt(3) c1~, m_j} ||gamma||^2 with m_E the smallest
  eigenvalue of E, m_j the friction law's ``m_j`` (c1 for law (4.2): its relaxed
  monotonicity) times the slip law's ``theta_max`` (1 for theta <= 1), c1~ = 0 (theta is
  bounded: the friction bound does not grow with the slip)
  and ||gamma||^2 = max_v ||v||^2_{L2(Gamma3)} / ||eps(v)||^2_{L2} on the discrete space,
  computed by power iteration with the factorised stiffness (LU), or by LOBPCG
  preconditioned with GAMG on the iterative path, or bounded from the condensed solver's
  Schur complement.
"""
from __future__ import annotations

from contextlib import nullcontext
from dataclasses import asdict, dataclass

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from vpcontact import threads
from vpcontact.forms.elasticity import eps
from vpcontact.model.history import UPDATE_ERRORS, first_failure
from vpcontact.solvers import dense
from vpcontact.solvers.amg import AMG_PETSC, AMG_PREFIX, near_nullspace, rigid_body_modes
from vpcontact.solvers.options import push_options, remove_options
from vpcontact.solvers.schur import LAPACK_MIN
from vpcontact.solvers.snesvi import PREFIX, direct_solver

STABILITY_LIMIT = 2.0
# (2.6) with ||gamma||^2 = inf: K of the trace constant is singular, a rigid motion of a
# body that only contact holds (no Dirichlet condition stops it; two bodies), not c1
UNBOUNDED_TRACE = (
    "well-posedness (2.6) cannot be checked: the trace constant ||gamma||^2 is unbounded "
    "because a body is held only by contact (a rigid motion that no Dirichlet condition "
    "stops), so m_E > max(sqrt(3) c1~, m_j) ||gamma||^2 cannot hold for any softening m_j "
    "> 0: uniqueness of the solution is not guaranteed")
TRACE_PREFIX = PREFIX + "trace_"        # the iterative K^-1 of trace_constant
# LOBPCG (the iterative path of trace_constant) stops at a residual of EIGEN_RTOL times the
# value in the norm of the preconditioner (about K^-1's); the value's error is about the
# square of that over the gap to the next eigenvalue.  It replaced Lanczos on K^-1 M, whose
# every iteration was a CG solve to 1e-6: far fewer preconditioner applications for the same
# value (docs/performance.md, section 7, "Forcing version 3, no copy of K").
EIGEN_RTOL = 1e-4
# Its GAMG, set up once: smoothed aggregation, whose set-up costs more and whose iterations
# are fewer and do not grow with the mesh, unlike the unsmoothed aggregation of SNES VI's
# path (docs/performance.md, section 9).
TRACE_GAMG = {"pc_gamg_agg_nsmooths": 1}


def ellipticity(elasticity) -> float:
    """The ellipticity constant m_E of (2.6).

    Args:
        elasticity: the Elasticity E (app/model/material.py).

    Returns:
        m_E, the smallest eigenvalue of E on symmetric tensors.
    """
    return elasticity.bounds()[0]


class RateEstimateError(RuntimeError):
    """The law raised at the state where its rate is estimated (on some rank; raised on
    every rank)."""


def estimated_rate(law, t: np.ndarray, kappa: np.ndarray, eps: np.ndarray | None = None,
                   comm=None, rel_step: float = 1e-6) -> float | None:
    """An estimate of the relaxation rate of a law without a rate bound: the spectral radius
    of the Jacobian dG/dsigma (central differences in the t-coordinates, kappa held) at the
    cell of largest ||sigma||_VM, the largest over the ranks; collective with ``comm``.
    Where the law's rates overflow there (G not finite: Norton's law with A = 1e-3, n = 300
    at ||sigma||_VM = 9) the estimate is infinite: no time step is stable there.

    Args:
        law: the ViscoplasticLaw (its ``rates``, with eps where it ``uses_eps``).
        t: rows (ncells, mt) of sigma in t-coordinates.
        kappa: (ncells, m) internal variables.
        eps: rows (ncells, mt) of eps(u) (a law that uses the strain), or None.
        comm: the MPI communicator, or None (this process only).
        rel_step: the difference step relative to the cell's largest |sigma_ij|.

    Returns:
        The estimate [1/s] (inf where the rates overflow), or None where it vanishes
        (every cell at rest).

    Raises:
        RateEstimateError: the law raised (a user's law: LawEvaluationError) or failed
            numerically there, on some rank (raised on every rank with ``comm``).
    """
    rate, error = 0.0, None
    try:
        rate = _jacobian_radius(law, t, kappa, eps, rel_step) if len(t) else 0.0
    except UPDATE_ERRORS as exc:
        error = exc
    reason = first_failure(comm, error) if comm is not None else \
        (None if error is None else str(error))
    if reason is not None:
        raise RateEstimateError(reason) from error
    if comm is not None:
        from mpi4py import MPI
        rate = comm.allreduce(rate, op=MPI.MAX)
    return rate if rate > 0.0 else None


def _jacobian_radius(law, t, kappa, eps, rel_step: float) -> float:
    """The spectral radius of dG/dsigma at the cell of largest ||sigma||_VM (see
    estimated_rate): inf where G is not finite at the differenced states."""
    i = int(np.argmax(law.elasticity.von_mises(t)))
    t0, mt = t[i], t.shape[1]
    h = rel_step * max(float(np.max(np.abs(t0))), 1e-300)
    steps = np.concatenate([t0 + h * np.eye(mt), t0 - h * np.eye(mt)])
    rows = [np.repeat(np.asarray(kappa, dtype=float).reshape(len(t), -1)[i:i + 1],
                      2 * mt, axis=0)]
    if getattr(law, "uses_eps", False):
        rows.append(np.repeat(eps[i:i + 1], 2 * mt, axis=0))
    with law.elasticity.rows(np.full(2 * mt, i)), \
            np.errstate(over="ignore", invalid="ignore"):       # E per cell: cell i's
        G, _ = law.rates(steps, *rows)
        jac = (G[:mt] - G[mt:]).T / (2.0 * h)
    if not np.isfinite(jac).all():
        return np.inf
    return float(np.max(np.abs(np.linalg.eigvals(jac))))


def _gamma3_mass(disc) -> PETSc.Mat:
    """M = (v, w)_{L2(Gamma3)} on V^h of the Discretisation ``disc`` (Gauss degree 2: exact
    for P1)."""
    u, v = ufl.TrialFunction(disc.V), ufl.TestFunction(disc.V)
    M = fem.petsc.assemble_matrix(fem.form(ufl.inner(u, v) * disc.gamma3_exact_measure()))
    M.assemble()
    return M


def _stiffness_solver(K: PETSc.Mat, disc, linear: str) -> PETSc.KSP:
    """A KSP applying K^-1 (LU), or for ``linear="amg"`` one V-cycle of GAMG (``preonly``) as
    SNES VI's iterative path sets it up (app/solvers/amg.AMG_PETSC) but with smoothed
    aggregation (TRACE_GAMG) and the rigid body modes as near-nullspace.

    Args:
        K: the stiffness (eps(u), eps(v)) with the Dirichlet rows and columns set.
        disc: the Discretisation (V, comm).
        linear: "direct" or "amg".

    Returns:
        The KSP, set up for "amg".
    """
    if linear != "amg":
        return direct_solver(K, disc.comm)
    K.setNearNullSpace(near_nullspace(rigid_body_modes(disc.V), K))
    ksp = PETSc.KSP().create(disc.comm)
    ksp.setOptionsPrefix(TRACE_PREFIX)
    ksp.setOperators(K)
    ksp.setType("preonly")
    ksp.getPC().setType("gamg")
    options = {**{k[len(AMG_PREFIX):]: v for k, v in AMG_PETSC.items()
                  if k.startswith(AMG_PREFIX)}, **TRACE_GAMG}
    push_options(options, TRACE_PREFIX)
    try:                                # the multigrid levels read theirs when set up
        ksp.setFromOptions()
        ksp.setUp()
    finally:
        remove_options(options, TRACE_PREFIX)
    return ksp


def trace_constant(disc, rtol: float = 1e-8, max_iter: int = 500,
                   linear: str = "direct") -> tuple[float, int]:
    """The squared trace constant ||gamma||^2 of (2.6) on the discrete space; collective.

    ||gamma||^2 is the largest eigenvalue of M v = lam K v, M = (v, w)_{L2(Gamma3)},
    K = (eps(v), eps(w)) on V^h with v = 0 on Gamma1.  With LU: power iteration
    x <- K^-1 M x until the Rayleigh quotient (a lower bound of lam converging at twice the
    rate of the vector) changes by less than rtol.  With the iterative solver: LOBPCG
    preconditioned by GAMG (one V-cycle per iteration, no inner solves) until the residual
    is below EIGEN_RTOL times the value (``_lobpcg``).

    Args:
        disc: the Discretisation (app/model/discretisation.py).
        rtol: the relative change of the power iteration that stops it (see above).
        max_iter: iterations allowed.
        linear: "direct" (LU and the power iteration) or "amg" (GAMG and LOBPCG).

    Returns:
        (||gamma||^2, the iterations used).
    """
    V, comm, bcs = disc.V, disc.comm, disc.bcs
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    a = fem.form(ufl.inner(eps(u), eps(v)) * ufl.dx)
    K = fem.petsc.create_matrix(a, "baij" if comm.size == 1 and linear != "amg" else None)
    fem.petsc.assemble_matrix(K, a, bcs=bcs)
    K.assemble()
    M = _gamma3_mass(disc)                                           # Dirichlet rows: below
    ksp = _stiffness_solver(K, disc, linear)
    x = K.createVecRight()
    x.setRandom(PETSc.Random().create(comm))
    fem.petsc.set_bc(x, bcs, scale=0.0)
    iterate = _lobpcg if linear == "amg" else _power_iteration
    try:
        return iterate(K, M, ksp, x, bcs, rtol if linear != "amg" else EIGEN_RTOL,
                       max_iter)
    finally:
        for obj in (K, M, ksp, x):
            obj.destroy()


def _power_iteration(K, M, ksp, x, bcs, rtol: float, max_iter: int) -> tuple[float, int]:
    """lam_max(M v = lam K v) by power iteration from x (see trace_constant)."""
    y, Mx = K.createVecRight(), K.createVecRight()
    lam, its = 0.0, 0
    for its in range(1, max_iter + 1):  # noqa: B007  (its, the count, is returned)
        M.mult(x, Mx)
        fem.petsc.set_bc(Mx, bcs, scale=0.0)           # v = 0 on Gamma1: K^-1 keeps it 0
        ksp.solve(Mx, y)
        new = _adot(M, y) / max(_adot(K, y), 1e-300)   # Rayleigh quotient (y = 0 on Gamma1)
        y.normalize()
        y.copy(x)
        if abs(new - lam) <= rtol * abs(new):
            lam = new
            break
        lam = new
    for obj in (y, Mx):
        obj.destroy()
    return float(lam), its


def _lobpcg(K, M, ksp, x, bcs, rtol: float, max_iter: int) -> tuple[float, int]:
    """lam_max(M v = lam K v) by LOBPCG (Knyazev 2001, block size one) from x: the Rayleigh
    quotient x.Mx / x.Kx maximised over span{x, w, p} in every iteration, w = T r the
    preconditioned residual r = M x - lam K x (T: ksp's PC, one V-cycle, about K^-1) and p
    the last change of x.  Stops when sqrt(r.Tr) (the residual's K^-1 norm, about) is at
    most rtol lam.  Every vector is carried with its products by K and M (one product by each
    per iteration)."""
    X = _with_products(K, M, x, bcs)
    s = 1.0 / np.sqrt(X[0].dot(X[1]))
    for v in X:
        v.scale(s)
    lam, P = X[0].dot(X[2]), None
    r, w = K.createVecLeft(), K.createVecLeft()
    for its in range(1, max_iter + 1):  # noqa: B007  (its, the count, is returned)
        X[2].copy(r)
        r.axpy(-lam, X[1])
        fem.petsc.set_bc(r, bcs, scale=0.0)            # v = 0 on Gamma1
        ksp.getPC().apply(r, w)
        if np.sqrt(max(r.dot(w), 0.0)) <= rtol * lam:
            break
        W = _with_products(K, M, w, bcs)
        lam, c = _rayleigh_ritz([X, W] if P is None else [X, W, P])
        step = [v.copy() for v in W]                   # c1 w + c2 p, and its products
        for k in range(3):
            step[k].scale(c[1])
            if P is not None:
                step[k].axpy(c[2], P[k])
            X[k].aypx(c[0], step[k])                   # x <- c0 x + c1 w + c2 p
        for v in W + (P or []):
            v.destroy()
        P = step
    for v in X + (P or []) + [r, w]:
        v.destroy()
    return float(lam), its


def _with_products(K, M, v, bcs) -> list:
    """[v, K v, M v] (copies; M v zero at the Dirichlet dofs, as v and K v are)."""
    v = v.copy()
    fem.petsc.set_bc(v, bcs, scale=0.0)
    Kv, Mv = K.createVecLeft(), K.createVecLeft()
    K.mult(v, Kv)
    M.mult(v, Mv)
    fem.petsc.set_bc(Mv, bcs, scale=0.0)
    return [v, Kv, Mv]


def _rayleigh_ritz(S: list) -> tuple[float, np.ndarray]:
    """The largest Ritz pair of M v = lam K v on span S (vectors with their products): the
    Gram matrices scaled to a unit diagonal of K's; p is dropped if it has become dependent
    on x and w (K's Gram matrix no longer positive definite)."""
    from scipy.linalg import LinAlgError, eigh
    GK = np.array([[a[0].dot(b[1]) for b in S] for a in S])
    GM = np.array([[a[0].dot(b[2]) for b in S] for a in S])
    d = 1.0 / np.sqrt(np.diag(GK))
    GK, GM = 0.5 * (GK + GK.T) * np.outer(d, d), 0.5 * (GM + GM.T) * np.outer(d, d)
    try:
        theta, C = eigh(GM, GK)
    except LinAlgError:
        theta, C = eigh(GM[:2, :2], GK[:2, :2])
        d = d[:2]
    c = np.zeros(len(S))
    c[:len(d)] = C[:, -1] * d
    return float(theta[-1]), c


def trace_constant_bound(problem, solver) -> float | None:
    """Upper bound of ||gamma||^2 from the fast solver's Schur complement S; collective.

    No extra factorisation: with the Gamma3 mass matrix M_G,
        lam_K = max_v |v|^2_{L2(Gamma3)} / (E eps(v), eps(v)) = lam_max(M_G x = lam S x),
    and since (E tau):tau <= c_max tau:tau (c_max the largest eigenvalue of E),
        ||gamma||^2 <= c_max lam_K.

    Args:
        problem: the ContactProblem.
        solver: the step solver.

    Returns:
        c_max lam_K, or None if the solver has no condensed Gamma3 problem.
    """
    if not getattr(solver, "gamma3", False) or not hasattr(solver, "S"):
        return None
    M = _gamma3_mass(problem.disc)
    MG = _gamma3_block(M, solver.layout)             # on the rank that holds S
    M.destroy()

    def largest():
        with threads.blas_threads(large=solver.m >= dense.PCG_MIN):
            return _largest_generalised_eigenvalue(0.5 * (MG + MG.T), solver.C)
    lam_K = threads.root_call(problem.disc.comm, largest)
    return problem.elasticity.bounds()[1] * lam_K


def _gamma3_block(M: PETSc.Mat, layout):
    """M's block on the Gamma3 dofs, G order, on GAMMA3_ROOT (None on the other ranks;
    collective): a scipy CSR matrix, or below LAPACK_MIN dofs a dense array (no scipy import
    at start-up).  Sparse: a dense m x m block is slow to extract, gather and symmetrise at
    3D sizes and doubles each Lanczos step (docs/performance.md, section 9)."""
    g_rows = layout.global_rows()                    # collective
    order = np.argsort(g_rows)
    ai, aj, av = M.getValuesCSR()
    local = layout.owned_rows - M.getOwnershipRange()[0]
    starts, lengths = ai[local], ai[local + 1] - ai[local]
    idx = np.repeat(starts - np.cumsum(lengths) + lengths, lengths) + np.arange(lengths.sum())
    rows = np.repeat(layout.owned_positions, lengths)
    sorted_rows, cols = g_rows[order], aj[idx]
    k = np.minimum(np.searchsorted(sorted_rows, cols), len(g_rows) - 1)
    in_G = sorted_rows[k] == cols
    parts = layout.comm.gather((rows[in_G], order[k[in_G]], av[idx][in_G]),
                               root=threads.GAMMA3_ROOT)
    if parts is None:
        return None
    r, c, v = (np.concatenate(x) for x in zip(*parts))
    if layout.m < LAPACK_MIN:
        A = np.zeros((layout.m, layout.m))
        A[r, c] = v                                  # each entry from its row's owner once
        return A
    from scipy.sparse import csr_matrix
    return csr_matrix((v, (r, c)), shape=(layout.m, layout.m))


def _largest_generalised_eigenvalue(A, C: np.ndarray) -> float:
    """lam_max of A x = lam S x (A symmetric positive semidefinite, dense or scipy sparse;
    S = C C^T symmetric positive definite with its Cholesky factor C at hand), as lam_max of
    C^-1 A C^-T: Lanczos (ARPACK) with O(m^2) products and triangular solves, or the dense
    reduction if ARPACK does not converge (the dense reduction alone is a large part of a 3D
    run; docs/performance.md, section 9).  Below LAPACK_MIN dofs the dense reduction by
    numpy (the 2D runs; cheap there, no scipy import)."""
    if len(C) < LAPACK_MIN:
        A = A.toarray() if hasattr(A, "toarray") else A
        B = np.linalg.solve(C, np.linalg.solve(C, A).T)          # C^-1 A C^-T, A symmetric
        return float(np.linalg.eigvalsh(0.5 * (B + B.T))[-1])
    from scipy.linalg.lapack import dtrtrs
    from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigsh
    m = len(C)

    def reduced(x):                                  # C^-1 A C^-T x
        z = dtrtrs(C, x, lower=1, trans=1)[0]
        return dtrtrs(C, A @ z, lower=1)[0]
    try:
        op = LinearOperator((m, m), matvec=reduced, dtype=float)
        return float(eigsh(op, k=1, which="LA", tol=1e-12, return_eigenvectors=False)[0])
    except (ArpackNoConvergence, ValueError):
        A = A.toarray() if hasattr(A, "toarray") else A
        W = dtrtrs(C, A, lower=1)[0]                 # C^-1 A
        B = dtrtrs(C, np.asfortranarray(W.T), lower=1)[0]
        return float(np.linalg.eigvalsh(0.5 * (B + B.T))[-1])


def _adot(A, y):
    """y . A y"""
    Ay = A.createVecLeft()
    A.mult(y, Ay)
    val = y.dot(Ay)
    Ay.destroy()
    return val


@dataclass
class Diagnostics:
    """The stability indicator and the well-posedness margin of (2.6) of a case.

    Attributes:
        scheme: time.scheme (explicit or implicit).
        k_max: the largest time step.
        relaxation_rate: r_max stated by the law (its relaxation rate, else its L_G), or None
            (no law, or a law without a rate bound); the adaptive steps use it.
        stability_indicator: k_max r_max (r_max the law's, else its r(S) at the data's
            stress scale, else the estimate), or None (no law, or unknown).
        stability_limit: the explicit scheme's limit of k_max r_max.
        explicit_stable: the indicator is within the limit (None without viscoplasticity).
        m_E: the ellipticity constant of E.
        m_j: the relaxed-monotonicity constant of the friction law (its ``m_j``: c1 for
            (4.2)) times theta_max; None: a law written by the user that states none.
        c1_tilde: the growth constant c1~ of (2.6).
        gamma2: ||gamma||^2 (or its upper bound), None without friction.
        wellposedness_margin: m_E - max(sqrt(3) c1~, m_j) ||gamma||^2, None without friction.
        unique: the margin is positive, None without friction.
        adaptive: the case has time.adaptive.
        gamma2_is_bound: gamma2 is the upper bound c_max lam_K, not the value.
        lipschitz_G: the law's L_G (app/model/laws.py), None where unknown or no law.
        rate_estimate: the law's rate r(S) at the data's stress scale (``rate_at_stress``)
            or the estimated rate (``estimated_rate``) of a law without a rate bound, else
            None.
        indicator_source: "law", "stress_scale" (the law's r(S)), "estimated", "unknown"
            or None (no law).
        stress_scale: S [Pa] of the source "stress_scale", else None.
        estimate_error: why the estimate failed (the law raised at the initial state: the
            source is "unknown"), else None.
        before_hardening: the rate r(S) is the law's at its initial internal state (a law
            that hardens, ``ViscoplasticLaw.hardens``: its rates fall as it hardens), so an
            indicator above the limit is a bound, not a prediction.
    """

    scheme: str
    k_max: float
    relaxation_rate: float | None
    stability_indicator: float | None
    stability_limit: float
    explicit_stable: bool | None
    m_E: float
    m_j: float | None
    c1_tilde: float
    gamma2: float | None
    wellposedness_margin: float | None
    unique: bool | None
    adaptive: bool = False
    gamma2_is_bound: bool = False    # gamma2 is the upper bound c_max lam_K, not the value
    lipschitz_G: float | None = None
    rate_estimate: float | None = None
    indicator_source: str | None = None
    stress_scale: float | None = None
    estimate_error: str | None = None
    before_hardening: bool = False

    def as_dict(self) -> dict:
        """The fields as a dict.

        Returns:
            Field name -> value (summary.json's "diagnostics").
        """
        return asdict(self)

    def _unstable(self) -> str:
        """The warning's tail for an indicator above the explicit limit."""
        growth = self.stability_indicator - 1
        where = "here" if self.indicator_source != "stress_scale" else \
            "where the stresses reach S (the run estimates it at every step)"
        if not np.isfinite(growth):     # the law's rate overflows: no k is small enough
            return (f": the explicit scheme is unstable {where} for every time step (the "
                    "law's rate overflows a float there); use time.scheme: implicit or "
                    "smaller law constants")
        return (f": the explicit scheme is unstable {where} (errors can grow by up to "
                f"{growth:.3g}x per step); use time.scheme: implicit, a smaller time step or "
                "time.adaptive")

    def messages(self) -> list[tuple[str, str]]:
        """The lines for the run log.

        Returns:
            (level, text) pairs, level "info" or "warning".
        """
        out = []
        if self.indicator_source == "unknown":
            why = "its rates do not vary with sigma in the initial state" \
                if self.estimate_error is None else \
                f"its rates failed in the initial state: {self.estimate_error}"
            out.append(("info" if self.estimate_error is None else "warning",
                        f"stability indicator: unknown (the law states no rate bound and "
                        f"{why}; the explicit scheme's step is not checked: watch for growing "
                        "oscillations, or use time.scheme: implicit)"))
        if self.stability_indicator is not None:
            est = self.indicator_source in ("estimated", "stress_scale")
            rate = self.rate_estimate if est else self.relaxation_rate
            how = "" if not est else \
                "(estimated: the law states no rate bound; dG/dsigma at the initial " \
                "state's largest ||sigma||_VM) " if self.stress_scale is None else \
                f"(the law's linearisation at the data's stress scale S = " \
                f"{self.stress_scale:.4g} Pa) "
            text = ("stability indicator " + how
                    + f"k_max r_max = {self.k_max:g} x {rate:.4g}"
                    f" = {self.stability_indicator:.3g} (explicit limit {self.stability_limit:g})")
            if self.scheme == "explicit" and not self.explicit_stable and self.adaptive \
                    and self.relaxation_rate is not None:      # the steps know r_max
                out.append(("info", text + ": adaptive steps will keep k r_max within "
                                           "time.adaptive.max_indicator"))
            elif self.scheme == "explicit" and not self.explicit_stable \
                    and self.before_hardening:
                out.append(("info", text + " before the law hardens (its rates fall as it "
                                           "hardens): the run estimates the indicator at "
                                           "every step and warns if it passes the limit"))
            elif self.scheme == "explicit" and not self.explicit_stable:
                out.append(("warning", text + self._unstable()))
            else:
                out.append(("info", text + ("" if self.scheme == "explicit" else
                                            "; the implicit scheme has no such limit")))
        if self.gamma2 is None and self.wellposedness_margin is not None:
            out.append(("info", f"well-posedness (2.6): m_j = 0 (the friction law does not "
                                f"soften): margin m_E = {self.m_E:.4g}"))
        if self.gamma2 is not None and not np.isfinite(self.gamma2):
            out.append(("warning", UNBOUNDED_TRACE))
        elif self.gamma2 is not None:
            rel = "<=" if self.gamma2_is_bound else "="
            text = (f"well-posedness (2.6): m_E = {self.m_E:.4g} vs max(sqrt(3) c1~, m_j) "
                    f"||gamma||^2 {rel} {max(np.sqrt(3) * self.c1_tilde, self.m_j):.4g} x "
                    f"{self.gamma2:.4g}: margin {'>= ' if self.gamma2_is_bound else ''}"
                    f"{self.wellposedness_margin:.4g}"
                    + (" (upper bound of ||gamma||^2 from the condensed stiffness)"
                       if self.gamma2_is_bound else ""))
            if self.unique:
                out.append(("info", text))
            else:
                out.append(("warning", text + " <= 0: uniqueness of the solution is not "
                                              "guaranteed (the friction softening c1 is too "
                                              "large for this body)"))
        return out


def diagnose(problem, solver=None) -> Diagnostics:
    """The diagnostics of a case; collective.

    With the fast solver the trace constant is first bounded from its Schur complement (no
    factorisation); the exact power iteration runs only when that bound cannot show the
    margin of (2.6) to be positive.

    Args:
        problem: the ContactProblem.
        solver: the step solver, or None.

    Returns:
        The Diagnostics.
    """
    case, elasticity = problem.case, problem.elasticity
    ks = np.diff(case.time.times)
    k_max = float(ks.max())
    law = problem.law
    rate, lipschitz, estimate, source, scale, failed = _law_rate(problem)
    indicator = k_max * rate if rate is not None else \
        (k_max * estimate if estimate is not None else None)
    m_E = ellipticity(elasticity)
    # m_j: the largest of the laws' (one set, or one per pair)
    fr = [friction_constant(case, law.friction, c) for c, law in
          zip(case.contact.sections, problem.section_laws()) if c.friction is not None]
    m_j = None if None in fr else max(fr, default=0.0)
    gamma2 = margin = unique = None
    is_bound = False
    if fr and m_j == 0:     # no softening (Coulomb's bound, a monotone law): the margin is
        margin, unique = m_E, m_E > 0       # m_E, ||gamma||^2 is not needed (nor computed)
    elif fr and m_j is not None:     # None: a user's law that states no m_j
        bound = trace_constant_bound(problem, solver) if solver is not None else None
        if bound is not None and m_E - m_j * bound > 0:
            gamma2, is_bound = bound, True
        else:
            gamma2, _ = trace_constant(problem.disc,
                                       linear=getattr(solver, "linear", "direct"))
        margin = m_E - max(np.sqrt(3) * 0.0, m_j) * gamma2
        unique = margin > 0
    return Diagnostics(case.time.scheme, k_max, rate, indicator, STABILITY_LIMIT,
                       None if indicator is None else indicator <= STABILITY_LIMIT,
                       m_E, m_j, 0.0, gamma2, margin, unique, case.time.adaptive is not None,
                       is_bound, lipschitz, estimate, source if law is not None else None,
                       scale, failed,
                       source == "stress_scale" and bool(getattr(law, "hardens", False)))


def _law_rate(problem) -> tuple:
    """(r_max stated by the law or None, L_G or None, the rate r(S) at the data's stress
    scale S or the estimate or None, the source, S or None, why the estimate failed or
    None); collective."""
    from vpcontact.post.divergence import stress_scale
    law = problem.law
    if law is None:
        return None, None, None, None, None, None
    # the largest over the ranks: with E per cell a law sees only this rank's cells
    comm = problem.disc.comm
    lipschitz = _largest_over_ranks(comm, law.lipschitz_constant())
    rate = _largest_over_ranks(comm, law.relaxation_rate())   # None if unknown
    rate = lipschitz if rate is None else rate
    if rate is not None:
        return rate, lipschitz, None, "law", None, None
    scale = stress_scale(problem.case, problem)
    at_scale = getattr(law, "rate_at_stress", lambda _: None)(scale) if scale > 0 else None
    at_scale = _largest_over_ranks(comm, at_scale)
    if at_scale is not None:
        return None, None, at_scale, "stress_scale", scale, None
    el, H = problem.elasticity, problem.state.H       # sigma_0 = E eps(u_0) + H_0 (3.2)
    eps = problem.strain_voigt()
    try:
        estimate = state_rate(problem, el.apply(eps) + el.to_voigt(H.x.array), eps)
    except RateEstimateError as exc:    # the first step's update fails there if the law does
        return None, None, None, "unknown", None, str(exc)
    return None, None, estimate, "estimated" if estimate is not None else "unknown", None, None


def _largest_over_ranks(comm, value: float | None) -> float | None:
    """The largest of a law's constant over the ranks (None stays None: the law's kind, the
    same on every rank, decides it)."""
    if value is None or comm.size == 1:
        return value
    from mpi4py import MPI
    return comm.allreduce(value, op=MPI.MAX)


def state_rate(problem, t: np.ndarray, eps: np.ndarray | None = None) -> float | None:
    """``estimated_rate`` of the problem's law at the stresses t and the State's kappa; for
    a body of several materials (app/model/materials.py) the largest of the groups' laws,
    each on its rows; collective.

    Args:
        problem: the ContactProblem (its law, State, communicator).
        t: rows (ncells, mt) of sigma in t-coordinates (owned and ghost cells).
        eps: rows of eps(u) (for a law that uses the strain), or None.

    Returns:
        The estimate [1/s], or None (every cell at rest).
    """
    law, kappa = problem.law, problem.state.kappa_cells
    if eps is None and getattr(law, "uses_eps", False):
        eps = problem.strain_voigt()
    parts = [(g.law, g.rows) for g in law.flowing] if hasattr(law, "flowing") else \
        [(law, slice(None))]
    found = []
    for g, rows in parts:          # a group's E per cell is the body's: select its rows
        with nullcontext() if isinstance(rows, slice) else g.elasticity.rows(rows):
            found.append(estimated_rate(g, t[rows], kappa[rows, :g.m],
                                        None if eps is None else eps[rows], problem.disc.comm))
    return max((e for e in found if e is not None), default=None)


def friction_constant(case, friction=None, section=None) -> float | None:
    """m_j of (2.6): the friction law's ``m_j`` times the slip law's ``theta_max``.

    Args:
        case: the Case (its contact section has friction).
        friction: the run's friction law (a law given through the Python API states its
            ``m_j``; one that does not is taken at the case's), or None: the case's.
        section: the set of laws (``Contact.sections``: a pair's own), or None: the
            case's contact section.

    Returns:
        m_j, or None: the case's friction law is written by the user and states none.
    """
    from vpcontact.model.contactregistry import friction_law, slip_law
    section = case.contact if section is None else section
    if getattr(friction, "m_j", None) is None:
        friction = friction_law(section.friction)
    if friction.m_j is None:            # a law written by the user that states no m_j
        return None
    slip = section.friction.slip
    return friction.m_j * (1.0 if slip is None else slip_law(slip).theta_max)
