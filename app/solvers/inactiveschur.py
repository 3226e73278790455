"""SNES VI's Newton systems by one factorisation of the bulk stiffness K per run and a dense
Gamma3 Schur complement per Newton iteration (explicit scheme, one body).

With the explicit scheme the Jacobian of (3.4) is J = K + B: K the constant bulk stiffness
(E eps(du), eps(v)) and B the Gamma3 terms, which couple Gamma3 dofs only (the nodal or
facet rule of the Gamma3 integrals).  The bounds u_nu <= g act only on normal dofs of the
Gamma3 nodes, so every inactive set I of vinewtonrsls holds every bulk dof b (the dofs
outside the Gamma3 dofs G) and a subset gI of G.  With x_gA = 0 on the active dofs,
    J_II x = r  <=>  (S + B)_{gI,gI} x_gI = r_gI - (K_Gb K_bb^-1 r_b)_gI,
                     x_b = K_bb^-1 (r_b - K_bG x_G),
with the Schur complement S = K_GG - K_Gb K_bb^-1 K_bG (dense m x m, m = |G|).  K is
factorised once, with G last, by the condensed solver's back end (CholmodCondensation,
app/solvers/condensed/cholmod.py: its forward sweep gives r_G - K_Gb K_bb^-1 r_b, its
backward sweep x_b); per Newton iteration only the dense (S + B)_{gI,gI} (|gI| <= m) is
factorised: by the condensed solver's compiled Cholesky of the free block
(dense.NewtonDirection; in 3D, from 1000 dofs, CG with the kept factor of an earlier
iteration first, as the condensed solver does) where B is made of symmetric nodal blocks
(the nodal Gamma3 rule, a convex contact energy), else by LU.  Under mpirun K is gathered
and factorised on GAMMA3_ROOT (RootCondensation): each Newton system's right-hand side is
gathered there and its solution scattered back, B_GG and the inactive set's Gamma3 part
pass as entries, while the other ranks wait asleep.  ``InactiveSetSchur`` is the python PC
(KSP preonly) that applies J_II^-1 so; ``schur_refusal`` says where it does not apply (SNES
VI then factorises J_II by LU at every Newton iteration, as before).
"""
from __future__ import annotations

import logging

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact import threads
from vpcontact.solvers import dense
from vpcontact.solvers.options import DEFAULT_PETSC
from vpcontact.threads import GAMMA3_ROOT

log = logging.getLogger("vpcontact")

SNES_TYPE = "vinewtonrsls"      # the reduced-space SNES VI whose J_II this PC inverts
# SNES VI's linear solver options with this PC (in place of DEFAULT_PETSC's LU)
SCHUR_PETSC = {"ksp_type": "preonly", "pc_type": "python"}
# from dense.PCG_MIN Gamma3 dofs (3D), (S + B)_{gI,gI} y = r by CG preconditioned with the
# kept Cholesky factor of an earlier Newton iteration (dense.NewtonDirection), to this
# relative residual (a new factorisation where CG does not get there in a few iterations):
# the Newton iterates stay those of LU to 1e-10 (tests/system/test_snes_schur.py)
CG_RTOL = 1e-12


def user_linear_options(options: dict) -> list[str]:
    """The options that choose SNES VI's linear solver themselves (a ksp_* or pc_* option
    other than a default of DEFAULT_PETSC; monitors and views only look, and are not).

    Args:
        options: SNES VI's PETSc options (name without '-' -> value).

    Returns:
        Their names, sorted (empty: the linear solver is ours to choose).
    """
    return sorted(k for k, v in options.items()
                  if str(k).startswith(("ksp_", "pc_")) and DEFAULT_PETSC.get(k) != v
                  and not any(w in str(k) for w in ("monitor", "view")))


def schur_refusal(problem, options: dict, reuse: bool, rotated: bool) -> str:
    """Why the Schur complement PC cannot solve SNES VI's Newton systems here ("" where it
    can; the same on every rank: collective).

    Args:
        problem: the ContactProblem.
        options: SNES VI's PETSc options.
        reuse: the bulk Jacobian K is constant (explicit scheme: SNESVISolver.reuse).
        rotated: SNES VI solves in nodal frames or for rigid caps' amplitudes.

    Returns:
        The reason, or "".
    """
    from vpcontact import kernels
    snes_type = options.get("snes_type", SNES_TYPE)
    given = user_linear_options(options)
    disc = problem.disc
    comm = disc.comm
    gamma3 = 0 if disc.gamma3 is None else len(disc.gamma3.nodes)
    reasons = [
        (disc.pairs is not None, "two bodies (contact pairs)"),
        (not reuse, "the bulk Jacobian changes (implicit scheme)"),
        (rotated, "nodal frames (curved Gamma3) or rigid caps"),
        (problem.hold is not None, "a body held only by contact (K singular)"),
        (comm.allreduce(gamma3) == 0, "no Gamma3 dofs"),
        (snes_type != SNES_TYPE, f"snes_type {snes_type} (not {SNES_TYPE})"),
        (bool(given), "the PETSc options " + ", ".join(given) + " choose the linear solver"),
    ]
    for refused, why in reasons:
        if refused:
            return why
    if not comm.allreduce(kernels.load() is not None, op=MPI.LAND):
        return "the compiled kernels are not available"
    return ""


class GammaSchur:
    """K factorised once with the Gamma3 dofs G last, S, and the solves of J_II x = r of
    the module docstring (one per SNES VI solver, shared by its SNESes' PCs).

    Args:
        problem: the ContactProblem (one body, serial).
        K: the bulk stiffness (assembled, the Dirichlet rows and columns the identity).
        gamma3_terms: returns B, the assembled matrix of the Gamma3 terms of the current
            Jacobian (None: no Gamma3 terms).

    Raises:
        np.linalg.LinAlgError: S is not positive definite (K singular).
    """

    def __init__(self, problem, K: PETSc.Mat, gamma3_terms):
        from vpcontact import kernels
        from vpcontact.solvers.condensed.layout import Gamma3Layout
        disc = problem.disc
        self.comm = disc.comm
        self.start, end = K.getOwnershipRange()
        self.layout = Gamma3Layout(disc, self.start)
        self.G = self.layout.global_rows().astype(np.int64)
        self.m, self.n = len(self.G), K.getSize()[0]
        self.condensation = _condensation(K, self.G.astype(np.int32), disc.dim,
                                          kernels.load(), self.comm)
        self.S = self.condensation.S                # on GAMMA3_ROOT, None elsewhere
        self.position = np.full(self.n, -1, dtype=np.int64)    # a dof's place in G, or -1
        self.position[self.G] = np.arange(self.m)
        self.bulk = np.count_nonzero(self.position[self.start:end] < 0)   # this rank's
        self.gamma3_terms = gamma3_terms
        self.b, self.x = K.createVecs()
        self.factorisations = 1
        self.d = disc.dim
        # (S + W)_ff by the condensed solver's compiled Cholesky (W: B's nodal blocks)
        self.direction = None if self.S is None else \
            dense.NewtonDirection(self.S, self.d, dense.load())
        self._entries = None        # B_GG's entries of this Newton iteration, on the root

    def covers(self, lb: PETSc.Vec, ub: PETSc.Vec) -> bool:
        """Whether every bounded dof is a Gamma3 dof (so every bulk dof stays inactive;
        collective).

        Args:
            lb: SNES VI's lower bounds.
            ub: its upper bounds.

        Returns:
            True if the bounds act on G only, on every rank.
        """
        bounded = (lb.array_r > PETSc.NINFINITY) | (ub.array_r < PETSc.INFINITY)
        inside = bool(np.all(self.position[self.start + np.flatnonzero(bounded)] >= 0))
        return self.comm.allreduce(inside, op=MPI.LAND)

    def gamma3_entries(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """B_GG, the Gamma3 terms of the current Jacobian on G, as entries (collective).

        Returns:
            (rows, columns, values): positions in G and the values there, every rank's, on
            GAMMA3_ROOT; None elsewhere.

        Raises:
            RuntimeError: B has a nonzero entry outside G x G (the PC would be wrong), on
                every rank.
        """
        B = self.gamma3_terms()
        if B is None:
            entries = (np.zeros(0, dtype=np.int64),) * 2 + (np.zeros(0),)
        else:
            ai, aj, av = B.getValuesCSR()
            pr = self.position[self.start + np.repeat(np.arange(len(ai) - 1), np.diff(ai))]
            pc = self.position[aj]
            inside = (pr >= 0) & (pc >= 0)
            outside = bool(np.any(av[~inside] != 0.0))
            if self.comm.allreduce(outside, op=MPI.LOR):
                raise RuntimeError("the Gamma3 terms couple dofs outside the Gamma3 nodes: "
                                   "the Schur complement solver of SNES VI does not apply")
            entries = pr[inside], pc[inside], av[inside]
        return self._on_root(entries)

    def _on_root(self, arrays: tuple) -> tuple | None:
        """Every rank's ``arrays``, each concatenated in rank order, on GAMMA3_ROOT; None
        elsewhere (collective; serial: ``arrays`` themselves)."""
        if self.comm.size == 1:
            return arrays
        parts = self.comm.gather(arrays, root=GAMMA3_ROOT)
        return None if parts is None else tuple(np.concatenate(a) for a in zip(*parts))

    def factor(self, rows: np.ndarray | None) -> tuple[np.ndarray, tuple] | tuple[None, None]:
        """What solves with (S + B)_{gI,gI} for the inactive set ``rows``: B's nodal blocks W
        where B is symmetric and couples no two nodes (the nodal Gamma3 rule; the Cholesky
        factorisation comes with the solve, ``solve``), else the LU factors (collective).

        Args:
            rows: this rank's inactive dofs (local, sorted), or None for all.

        Returns:
            On GAMMA3_ROOT (gI: the inactive positions in G, ("cholesky", W) or ("lu",
            scipy's lu_factor)); (None, None) elsewhere.

        Raises:
            RuntimeError: a bulk dof is active (the bounds act outside G), on every rank.
        """
        if rows is None:
            gI = np.arange(self.m)
        else:
            pos = self.position[self.start + rows]
            gI = pos[pos >= 0]
            missed = len(rows) - len(gI) != self.bulk
            if self.comm.allreduce(missed, op=MPI.LOR):
                raise RuntimeError("SNES VI's inactive set misses bulk dofs: the Schur "
                                   "complement solver does not apply")
            gathered = self._on_root((gI,))
            gI = None if gathered is None else np.sort(gathered[0])
        self._entries = self.gamma3_entries()
        if self.S is None:
            return None, None
        W = self._nodal_blocks(*self._entries)
        if W is not None:
            return gI, ("cholesky", W)
        return gI, ("lu", self._lu(gI, *self._entries))

    def _nodal_blocks(self, pr, pc, v) -> np.ndarray | None:
        """B's entries as symmetric nodal d x d blocks (m / d, d, d), or None if B couples
        two nodes or is not symmetric."""
        d = self.d
        nonzero = v != 0.0
        if np.any(pr[nonzero] // d != pc[nonzero] // d):
            return None
        W = np.zeros((self.m // d, d, d))
        same = pr // d == pc // d                       # (B's pattern holds zeros between)
        W[pr[same] // d, pr[same] % d, pc[same] % d] = v[same]
        return W if np.array_equal(W, W.transpose(0, 2, 1)) else None

    def _lu(self, gI, pr, pc, v) -> tuple:
        """scipy's LU factors of (S + B)_{gI,gI} from B's entries (scipy imported here: the
        nodal rule's runs do without its start-up cost: docs/performance.md, section 3)."""
        import scipy.linalg
        M = self.S[np.ix_(gI, gI)]
        where = np.full(self.m, -1, dtype=np.int64)     # a G position's place in gI
        where[gI] = np.arange(len(gI))
        pr, pc = where[pr], where[pc]
        keep = (pr >= 0) & (pc >= 0)
        np.add.at(M, (pr[keep], pc[keep]), v[keep])
        with threads.blas_threads(large=len(gI) >= dense.PCG_MIN):
            return scipy.linalg.lu_factor(M, overwrite_a=True, check_finite=False)

    def _gamma3_solve(self, gI: np.ndarray, how: tuple, r: np.ndarray) -> np.ndarray:
        """y with (S + B)_{gI,gI} y_gI = r_gI, y = 0 off gI (Cholesky by NewtonDirection,
        which returns -(S + W)_ff^-1 g_f for g = -r, from PCG_MIN dofs CG with its kept
        factor to CG_RTOL first; LU where B is not nodal and symmetric, or the matrix not
        positive definite)."""
        kind, data = how
        if kind == "cholesky":
            binding = np.ones(self.m, dtype=bool)
            binding[gI] = False
            y = self.direction(data, -r, binding, rtol=CG_RTOL)
            if y is not None:
                return y
            data = self._lu(gI, *self._entries)
        import scipy.linalg
        y = np.zeros(self.m)
        y[gI] = scipy.linalg.lu_solve(data, r[gI], check_finite=False)
        return y

    def solve(self, rows: np.ndarray | None, gI: np.ndarray, how: tuple, r: np.ndarray,
              out: np.ndarray) -> None:
        """x = J_II^-1 r by the condensation (module docstring; collective: the Gamma3 solve
        on GAMMA3_ROOT).

        Args:
            rows: this rank's inactive dofs (local), or None for all.
            gI: their positions in G (``factor``; on the root).
            how: the solve with (S + B)_{gI,gI} (``factor``; on the root).
            r: the right-hand side on this rank's inactive dofs.
            out: x on this rank's inactive dofs, overwritten.
        """
        b = self.b.array
        if rows is None:
            b[:] = r
        else:
            b[:] = 0.0
            b[rows] = r
        reduced = self.condensation.reduce(self.b)
        y = None if reduced is None else self._gamma3_solve(gI, how, np.array(reduced))
        self.condensation.expand(y, self.x)
        out[:] = self.x.array_r if rows is None else self.x.array_r[rows]

    def destroy(self) -> None:
        """Free the work vectors and the factorisation."""
        self.condensation.destroy()
        for obj in (self.b, self.x):
            obj.destroy()


def _condensation(K: PETSc.Mat, G: np.ndarray, d: int, module, comm):
    """K's G-last factorisation: CholmodCondensation, or under mpirun RootCondensation (the
    same on GAMMA3_ROOT, right-hand sides gathered there; app/solvers/condensed/cholmod.py).
    """
    from vpcontact.solvers.condensed.cholmod import CholmodCondensation, RootCondensation
    if comm.size == 1:
        return CholmodCondensation(K, G, d, module, comm)
    return RootCondensation(K, G, d, module, comm)


class InactiveSetSchur:
    """A PETSc python PC (KSP preonly) applying J_II^-1 exactly for SNES vinewtonrsls by
    GammaSchur: set up per Newton iteration from SNES's inactive set.

    Args:
        snes: the SNES whose KSP uses this PC (its inactive set is read in setUp).
        schur: the solver's GammaSchur.
    """

    def __init__(self, snes: PETSc.SNES, schur: GammaSchur):
        self.snes, self.schur = snes, schur
        self.rows = self.gI = self.how = None
        self.setups = 0

    def setUp(self, pc: PETSc.PC) -> None:
        """Prepare the solves with (S + B)_{gI,gI} for this Newton iteration's inactive set
        and Jacobian (GammaSchur.factor).

        Args:
            pc: the python PC (its operator: J_II of this Newton iteration, or J).

        Raises:
            RuntimeError: the inactive set does not match the operator's size.
        """
        _, P = pc.getOperators()
        x = self.snes.getSolution()
        if P.getSize()[0] == x.getSize():
            self.rows = None
        else:
            self.rows = self.snes.getVIInactiveSet().getIndices() - x.getOwnershipRange()[0]
            size = P.getLocalSize()[0]
            if len(self.rows) != size:
                raise RuntimeError(f"SNES VI's inactive set has {len(self.rows)} dofs here, "
                                   f"its Newton matrix {size}")
        self.gI, self.how = self.schur.factor(self.rows)
        self.setups += 1

    def apply(self, pc: PETSc.PC, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = J_II^-1 x.

        Args:
            pc: the python PC.
            x: the residual on the inactive dofs.
            y: output, the Newton direction on the inactive dofs.
        """
        self.schur.solve(self.rows, self.gI, self.how, x.array_r, y.array)

    def view(self, pc: PETSc.PC, viewer: PETSc.Viewer) -> None:
        """Say what this PC does (-ksp_view).

        Args:
            pc: the python PC.
            viewer: where to say it.
        """
        viewer.printfASCII(f"  Gamma3 Schur complement ({self.schur.m} Gamma3 dofs) on one "
                           "factorisation of K\n")
