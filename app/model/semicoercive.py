"""A body held only by its contact with the rigid foundation (semi-coercive: no Dirichlet
data hold its rigid motions; force control of a block pressed and sheared on Gamma3).

The step matrix is then singular in the free rigid motions r_k, which only the contact
determines; the body is in equilibrium only if the contact forces can balance the applied
load on them: with W_k = f_n(r_k) (the loads vector of step n on the motion r_k; the
history term B^T H_n does no work on a rigid motion), there must be nodal contact forces
-p_i nu_i + t_i at the Gamma3 nodes, p_i >= 0, |t_i| <= mu p_i (Coulomb; 0 frictionless;
the friction law's bound psi'(oo) w_i otherwise, which does not scale with p_i), with
sum_i (-p_i nu_i + t_i) . r_k(x_i) = -W_k.  ``FoundationHold.check_loads`` refuses, before
any solve, a step whose load is not strictly inside that cone (a linear program: the slack
of every generator maximised): a pull-off, a tangential resultant at or above mu P, a
moment whose centre of pressure falls outside Gamma3, a free tangential motion of
frictionless contact (Code_Aster refuses such a singular system, Abaqus stabilises it; we
refuse, as Code_Aster).  Strictly inside, the rigid motion is determined by the contact.

To solve a step from a state out of contact (the first step: the Newton matrix is K, singular
in r_k), ``close_gap`` translates the part along its mean inward normal until its nearest
Gamma3 node is half-way into the gap (on the bound without a compliance), and
``pressure_start`` gives Coulomb's fixed point (app/model/coulomb.py) the uniform pressure
of the normal resultant instead of p_n = 0 (with p_n = 0 nothing holds the tangential
motion).  The condensed solver takes S as only positive semidefinite (``reduce``,
app/solvers/condensed/condensation.py), as for a body held by a contact pair.
"""
from __future__ import annotations

import logging

import numpy as np
from mpi4py import MPI

from vpcontact.io.errors import CaseError

log = logging.getLogger("vpcontact")

COULOMB_DIRECTIONS = 8      # 3D: the friction cone's inner polygon
SLACK = 1e-9                # the least slack (per generator, load scaled to 1) accepted


class FoundationHold:
    """The parts of the body held only by the foundation contact (collective to build).

    Args:
        problem: the ContactProblem (its Gamma3 nodes, frames, loads vector).
        parts: the HeldParts of ``check_rigid_motions`` (app/model/dirichlet.py).
    """

    def __init__(self, problem, parts: list):
        self.problem, self.parts = problem, parts
        gm, fr, d = problem.gamma3, problem.frames, problem.dim
        owned = problem.V.dofmap.index_map.size_local
        x = problem.V.tabulate_dof_coordinates()[:owned, :d]
        self.modes = [p.modes(x) * p.nodes[:owned, None, None] for p in parts]
        pos = np.searchsorted(fr.nodes, gm.nodes)
        self.normal, self.tangents = fr.normal[pos], fr.tangents[pos]
        self.g = None if fr.g is None else fr.g[pos]
        self.nodes, self.w = gm.nodes, gm.weight
        self.mine = [p.nodes[gm.nodes] for p in parts]      # owned Gamma3 nodes per part

    # ---------------------------------------------------------------- the loads' check
    def check_loads(self, times) -> None:
        """Refuse a step whose load the contact cannot balance (collective).

        Args:
            times: the step times t_1..t_N.

        Raises:
            CaseError: one line naming the loads' keys, the time and the numbers.
        """
        p = self.problem
        lv, t0 = p.load_vector, float(p.time_data.t.value)
        last = None
        for t in times:
            p.time_data.set_time(float(t))
            f = np.zeros(p.V.dofmap.index_map.size_local * p.dim) if lv is None else \
                lv.at_current_time().array_r
            if lv is not None and not lv.timed and last is not None:
                break                   # the same load at every step
            last = t
            for k in range(len(self.parts)):
                self._check_part(k, f.reshape(-1, p.dim), float(t))
        p.time_data.set_time(t0)

    def _check_part(self, k: int, f: np.ndarray, t: float) -> None:
        """The cone test of part k at time t (``f``: the owned nodal loads)."""
        comm = self.problem.comm
        M = self.modes[k]
        W = comm.allreduce(np.einsum("nd,ndr->r", f, M[:len(f)]), op=MPI.SUM)
        F = comm.allreduce(f[self.parts[k].nodes[:len(f)]].sum(axis=0), op=MPI.SUM)
        A, box = self._generators(k)
        if _strictly_inside(A, box, -W):
            return
        raise CaseError(f"{self.problem.case.source}: {self._why(k, F, A, box, t)}")

    def _generators(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """(the cone's generators, the bounded tangential columns with their bounds) of
        part k on the free motions, gathered on every rank: A (free, n), box (free + 1, m)."""
        mine = self.mine[k]
        M = self.modes[k][self.nodes[mine]]                         # (n, d, free)
        nu, tau, w = self.normal[mine], self.tangents[mine], self.w[mine]
        gens, box = [-nu], []
        mu, bound = self._friction()
        if mu is not None and mu > 0:
            gens = [-nu + mu * _direction(tau, a) for a in _angles(self.problem.dim)]
        elif bound is not None:
            for j in range(tau.shape[1]):
                box.append((tau[:, j], w * bound / np.sqrt(tau.shape[1])))
        A = np.concatenate([np.einsum("nd,ndr->rn", g, M) for g in gens], axis=1)
        B = np.concatenate([np.vstack([np.einsum("nd,ndr->rn", tj, M), c[None]])
                            for tj, c in box], axis=1) if box else np.zeros((M.shape[2] + 1, 0))
        comm = self.problem.comm
        return (np.concatenate(comm.allgather(A), axis=1),
                np.concatenate(comm.allgather(B), axis=1))

    def _friction(self) -> tuple[float | None, float | None]:
        """(Coulomb's mu, else None; the friction law's bound psi'(oo) where the bound does
        not scale with p_n, else None)."""
        fr = self.problem.case.contact.friction
        if fr is None:
            return None, None
        if fr.coulomb is not None:
            return float(fr.coulomb.mu), None
        law = self.problem.contact_law().friction
        big = 1e6 * self.problem.length_scale
        return None, float(np.asarray(law.derivative(np.array([big]))).ravel()[0])

    def _why(self, k: int, F: np.ndarray, A: np.ndarray, box: np.ndarray, t: float) -> str:
        """The refusal's words for part k at time t (F: the applied force resultant)."""
        c = self.problem.comm
        nbar = c.allreduce((self.w[self.mine[k], None] * self.normal[self.mine[k]]).sum(0),
                           op=MPI.SUM)
        nbar = nbar / max(np.linalg.norm(nbar), 1e-300)
        P = float(F @ nbar)                     # the load pressing along the outward normal
        Q = float(np.linalg.norm(F - P * nbar))
        keys = "loads.traction / loads.pressure / loads.f0"
        at = (f"at t = {t:g} the applied force resultant ({', '.join(f'{v:.6g}' for v in F)})"
              " on the body held only by the contact with the foundation")
        mu, bound = self._friction()
        if P <= 0:
            return (f"{keys}: {at} does not press it onto Gamma3 (normal component "
                    f"{P:.6g} <= 0: a pull-off); clamp a group or press the body")
        if mu is None and bound is None:
            return (f"{keys} / contact.friction: {at}: frictionless contact cannot hold its "
                    f"tangential motion (tangential resultant {Q:.6g}); add friction or "
                    "prescribe a tangential component")
        if mu is not None and Q >= mu * P * (1 - 1e-9):
            return (f"{keys} / contact.friction.coulomb.mu: {at}: tangential resultant "
                    f"{Q:.6g} >= mu P = {mu:g} x {P:.6g} = {mu * P:.6g}: the body would slide "
                    "away; lower the tangential load or prescribe a tangential component")
        cap = 0.0 if bound is None else float(box[-1].sum())
        if bound is not None and Q >= cap * (1 - 1e-9):
            return (f"{keys} / contact.friction: {at}: tangential resultant {Q:.6g} >= the "
                    f"friction bound's resultant {cap:.6g} (psi'(oo) = {bound:.6g} over "
                    "Gamma3): the body would slide away")
        return (f"{keys}: {at} has a moment the contact zone cannot carry (its centre of "
                "pressure falls outside Gamma3, or the friction cannot hold it); clamp a "
                "group or change the loads")

    # ---------------------------------------------------------------- the step's start
    def close_gap(self, u) -> bool:
        """Translate each part out of contact at u along its mean inward normal until its
        nearest Gamma3 node is half-way into the gap (on the bound without a normal
        compliance, at 1e-3 of the body's size without a bound); collective.

        Args:
            u: the displacement Function (the step's start, u_{n-1}), changed in place.

        Returns:
            Whether u was changed (on every rank).
        """
        p = self.problem
        arr = u.x.array.reshape(-1, p.dim)
        changed = False
        for k, part in enumerate(self.parts):
            mine = self.mine[k]
            un = np.einsum("nd,nd->n", arr[self.nodes[mine]], self.normal[mine])
            target = self._target()[mine]
            if p.comm.allreduce(bool(np.any(un > 0)), op=MPI.LOR):
                continue                         # in contact somewhere
            nbar = p.comm.allreduce((self.w[mine, None] * self.normal[mine]).sum(0),
                                    op=MPI.SUM)
            nbar /= max(np.linalg.norm(nbar), 1e-300)
            cos = self.normal[mine] @ nbar
            ok = cos > 1e-6
            s = p.comm.allreduce(float(np.min((target - un)[ok] / cos[ok], initial=np.inf)),
                                 op=MPI.MIN)
            if not np.isfinite(s):
                continue
            arr[part.nodes[:len(arr)]] += s * nbar
            changed = True
            log.debug("part held by the foundation: start translated by %.3g along the "
                      "mean normal into contact", s)
        if changed:
            u.x.scatter_forward()
        return changed

    def _target(self) -> np.ndarray:
        """u_nu at which a Gamma3 node is in contact for the start (owned Gamma3 nodes)."""
        has_normal = self.problem.contact_law().normal is not None
        if self.g is None:
            return np.full(len(self.nodes), 1e-3 * self.problem.length_scale)
        return 0.5 * self.g if has_normal else self.g.copy()

    def pressure_start(self, f: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Coulomb's start p_n for a step: the last p_n scaled to the normal resultant P of
        the step's loads, or P spread uniformly where no node is pressed (owned Gamma3
        nodes; collective).  From the last step's p_n alone, a growing load would meet a
        friction bound mu p_(n-1) below its tangential resultant: nothing would hold the
        tangential motion in the fixed point's first solve.

        Args:
            f: the owned nodal loads (n, d) of the step.
            p: the last p_n at the owned Gamma3 nodes (``problem.gamma3``'s order).

        Returns:
            p (owned Gamma3 nodes).
        """
        c, out = self.problem.comm, p.copy()
        for k, part in enumerate(self.parts):
            mine = self.mine[k]
            nu, w = self.normal[mine], self.w[mine]
            F = c.allreduce(f[part.nodes[:len(f)]].sum(axis=0), op=MPI.SUM)
            nbar = c.allreduce((w[:, None] * nu).sum(0), op=MPI.SUM)
            area = np.linalg.norm(nbar)
            nbar = nbar / max(area, 1e-300)
            P = max(float(F @ nbar), 0.0)
            R = c.allreduce(float(((w * p[mine])[:, None] * nu).sum(0) @ nbar), op=MPI.SUM)
            out[mine] = p[mine] * (P / R) if R > 1e-12 * P else P / max(area, 1e-300)
        return out


def _angles(d: int) -> np.ndarray:
    """The directions of the friction cone's generators: +-tau in 2D, a polygon in 3D."""
    n = 2 if d == 2 else COULOMB_DIRECTIONS
    return 2 * np.pi * np.arange(n) / n


def _direction(tau: np.ndarray, a: float) -> np.ndarray:
    """cos(a) tau_1 + sin(a) tau_2 at every node (2D: +-tau_1)."""
    out = np.cos(a) * tau[:, 0]
    if tau.shape[1] > 1:
        out = out + np.sin(a) * tau[:, 1]
    return out


def _strictly_inside(A: np.ndarray, box: np.ndarray, b: np.ndarray) -> bool:
    """Whether b = A a + B t with every a_j > 0 and every |t_j| < c_j (B, c = box's rows
    and last row) and [A B] of full rank (the interior of the cone, not of a face of it):
    the largest common slack s of a linear program, load scaled to 1."""
    from scipy.optimize import linprog
    scale = np.linalg.norm(b)
    B = box[:-1]
    if scale == 0.0 or np.linalg.matrix_rank(np.hstack([A, B])) < len(b):
        return False                # no load, or a free motion no contact force resists
    r, n = A.shape
    c = box[-1] / scale
    m = B.shape[1]
    An = A / np.maximum(np.linalg.norm(A, axis=0), 1e-300)
    # unknowns (a, t, s): max s, A a + B t = b / scale, a_j >= s, |t_j| + s c_j <= c_j
    cost = np.zeros(n + m + 1)
    cost[-1] = -1.0
    eq = np.hstack([An, B, np.zeros((r, 1))])
    ub = np.vstack([np.hstack([-np.eye(n), np.zeros((n, m)), np.ones((n, 1))]),
                    np.hstack([np.zeros((m, n)), np.eye(m), c[:, None]]),
                    np.hstack([np.zeros((m, n)), -np.eye(m), c[:, None]])])
    rhs = np.concatenate([np.zeros(n), c, c])
    res = linprog(cost, A_ub=ub, b_ub=rhs, A_eq=eq, b_eq=b / scale,
                  bounds=[(None, None)] * (n + m) + [(None, 1.0)], method="highs")
    return bool(res.status == 0 and -res.fun > SLACK)
