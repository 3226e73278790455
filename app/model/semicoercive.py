"""A body held only by contact (semi-coercive: no Dirichlet data hold its rigid motions;
force control of a block pressed and sheared on the foundation, or on a second body through
contact.pairs).

The step matrix is then singular in the free rigid motions r_k, which only the contact
determines; the body is in equilibrium only if the contact forces can balance the applied
load on them: with W_k = f_n(r_k) (the loads vector of step n on the motion r_k, plus the
rigid caps' loads F . r_k(X_ref) + M . theta(r_k); the history term B^T H_n does no work on
a rigid motion), there must be nodal contact forces
-p_i nu_i + t_i at the Gamma3 nodes (two bodies: their opposite on the target's side),
p_i >= 0, |t_i| <= mu p_i (Coulomb; 0 frictionless; the friction law's bound psi'(oo) w_i
otherwise, which does not scale with p_i), with sum_i (-p_i nu_i + t_i) . r_k(x_i) = -W_k.
``ContactHold.check_loads`` refuses, before any solve, a step whose load is not strictly
inside that cone (a linear program: the slack of every generator maximised): a pull-off, a
tangential resultant at or above mu P, a moment whose centre of pressure falls outside
Gamma3, a free tangential motion of frictionless contact (Code_Aster's solver stops on such
a singular matrix, Abaqus can stabilise it by damping; we refuse, as Code_Aster).
Strictly inside, the rigid motion is determined by the contact.  Each part is checked
against its own contact forces as if the bodies it touches were held (exact for a body on
the foundation or on a held body; a chain of free bodies is checked link by link).

To solve the first step from a state out of contact (the Newton matrix is K, singular in
r_k), ``close_gap`` translates the part along its mean inward normal until its nearest
Gamma3 node is half-way into the gap (on the bound without a compliance), SNES VI takes
one Newton step with those nodes' normal dofs held (``pinned_slots``,
``SNESVISolver.press_next``: touching the bound, the body's Gamma3 residual is 0 and the VI
sees no active node), and ``pressure_start`` gives Coulomb's fixed point
(app/solvers/coulomb.py, through app/model/coulomb.py) the last p_n scaled to the step's
normal resultant, or that resultant spread uniformly (with p_n = 0 nothing holds the
tangential motion).  The
condensed solver takes S as only positive semidefinite (``reduce``,
app/solvers/condensed/condensation.py).
"""
from __future__ import annotations

import logging

import numpy as np
from mpi4py import MPI

from vpcontact.io.errors import CaseError
from vpcontact.model.dirichlet import motion_names, rigid_modes

log = logging.getLogger("vpcontact")

COULOMB_DIRECTIONS = 16     # 3D: the friction cone's inner polygon (mu cos(pi/16) = 0.98 mu)
SLACK = 1e-9                # the least slack (per generator, load scaled to 1) accepted


class ContactHold:
    """The parts of the body held only by contact (collective to build): by the foundation
    (Gamma3 = boundaries.contact) or by contact pairs.

    Each owned Gamma3 node i acts on part k with the sign sigma_ik: +1 where the node is
    the part's own (the foundation's Gamma3, a pair's surface), -1 where the part carries
    the pair's target (the force on the target is the opposite of the surface node's, at
    the node's projection: taken at the node, which misplaces it by the initial distance
    d_i in the moments only), 0 elsewhere.

    Args:
        problem: the ContactProblem (its Gamma3 nodes, frames, loads vector, pairs).
        parts: the HeldParts of ``check_rigid_motions`` (app/model/dirichlet.py).
    """

    def __init__(self, problem, parts: list):
        self.problem, self.parts = problem, parts
        disc = problem.disc
        gm, fr, d = disc.gamma3, disc.frames, disc.dim
        owned = disc.V.dofmap.index_map.size_local
        x = disc.V.tabulate_dof_coordinates()[:owned, :d]
        self.modes = [p.modes(x) * p.nodes[:owned, None, None] for p in parts]
        self.pos = np.searchsorted(fr.nodes, gm.nodes)   # owned Gamma3 nodes in frames
        self.normal, self.tangents = fr.normal[self.pos], fr.tangents[self.pos]
        self.g = None if fr.g is None else fr.g[self.pos]
        self.nodes, self.w, self.x = gm.nodes, gm.weight, x[gm.nodes]
        pair = None if disc.pairs is None else disc.pairs.pair[self.pos]
        self.sign = [_signs(p, gm.nodes, pair) for p in parts]
        self.mine = [s != 0 for s in self.sign]
        self.mu, self.bound, self.compliance = self._laws(pair)

    def _laws(self, pair) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per owned Gamma3 node: Coulomb's mu (nan: not Coulomb), the friction bound
        psi'(oo) of a law whose bound does not scale with p_n (nan: none), whether a normal
        compliance acts (else the bound alone)."""
        c = self.problem.case.contact
        sections = c.sections
        index = np.zeros(len(self.nodes), dtype=int) if pair is None or len(sections) == 1 \
            else pair
        mu, bound, comp = (np.full(len(self.nodes), np.nan), np.full(len(self.nodes), np.nan),
                           np.zeros(len(self.nodes), dtype=bool))
        big = 1e6 * self.problem.disc.length_scale
        for i, section in enumerate(sections):
            at = index == i
            law = self.problem.contact_law(section=section)
            comp[at] = law.normal is not None
            fr = section.friction
            if fr is not None and fr.coulomb is not None:
                mu[at] = float(fr.coulomb.mu)
            elif law.friction is not None:
                bound[at] = float(np.asarray(law.friction.derivative(np.array([big]))).ravel()[0])
        return mu, bound, comp

    # ---------------------------------------------------------------- the loads' check
    def check_loads(self, times) -> None:
        """Refuse a step whose load the contact cannot balance (collective).  The cone of
        each part is built once; a load whose direction on the free motions was found
        inside already (a proportional ramp: every step) is not tested again.

        Args:
            times: the step times t_1..t_N.

        Raises:
            CaseError: one line naming the loads' keys, the time and the numbers.
        """
        p = self.problem
        lv, t0 = p.load_vector, float(p.time_data.t.value)
        cones = [self._generators(k) for k in range(len(self.parts))]
        inside = [[] for _ in self.parts]       # the load directions found inside
        disc = p.disc
        for i, t in enumerate(times):
            if lv is not None and not lv.timed and i > 0:
                break                           # the same load at every step
            p.time_data.set_time(float(t))
            f = np.zeros(disc.V.dofmap.index_map.size_local * disc.dim) if lv is None else \
                lv.at_current_time().array_r
            for k in range(len(self.parts)):
                self._check_part(k, f.reshape(-1, disc.dim), float(t), cones[k], inside[k])
        p.time_data.set_time(t0)

    def _check_part(self, k: int, f: np.ndarray, t: float, cone: tuple,
                    inside: list) -> None:
        """The cone test of part k at time t (``f``: the owned nodal loads; ``cone``: its
        generators; ``inside``: the unit loads found inside so far, extended)."""
        comm = self.problem.disc.comm
        cap_work, cap_force = self._cap_loads(k, t)
        W = comm.allreduce(np.einsum("nd,ndr->r", f, self.modes[k][:len(f)]), op=MPI.SUM) \
            + cap_work
        unit = W / max(np.linalg.norm(W), 1e-300)
        if any(np.abs(unit - u).max() <= 1e-12 for u in inside):
            return
        A, box = cone
        ok = comm.bcast(_strictly_inside(A, box, -W) if comm.rank == 0 else None, root=0)
        if ok:
            inside.append(unit)
            return
        F = comm.allreduce(f[self.parts[k].nodes[:len(f)]].sum(axis=0), op=MPI.SUM) \
            + cap_force
        raise CaseError(f"{self.problem.case.source}: {self._why(k, F, W, box, t)}")

    def _cap_loads(self, k: int, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(the work of the rigid caps' loads (loads.rigid: force F, moment M about X_ref)
        on part k's free motions at t, F . r(X_ref) + M . theta(r); their force F summed)
        (collective)."""
        from vpcontact.case.caprules import component_value
        from vpcontact.model.rigidcap import _ORDER
        disc = self.problem.disc
        caps, part = disc.caps, self.parts[k]
        W, F = np.zeros(part.free.shape[1]), np.zeros(disc.dim)
        for c in () if caps is None else caps.caps:
            if not disc.comm.allreduce(bool(part.nodes[c.nodes].any()), op=MPI.LOR):
                continue
            d = len(c.reference)
            at = rigid_modes(((c.reference - part.centre) / part.scale)[None, :])[0]
            amp = np.vstack([at, np.eye(at.shape[1])[_ORDER[d][d:]] / part.scale])
            load = np.array([0.0 if v is None else component_value(v, t)
                             for v in c.spec.load])
            W += load @ amp @ part.free
            F += load[:d]
        return W, F

    def _generators(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """(the cone's generators, the bounded tangential columns with their bounds) of
        part k on the free motions, gathered on every rank: A (free, n), box (free + 1, m)."""
        mine = self.mine[k]
        M = self.parts[k].modes(self.x[mine])       # (n, d, free): at the node, either side
        sign = self.sign[k][mine][:, None]
        nu, tau, w = sign * self.normal[mine], self.tangents[mine], self.w[mine]
        mu, bound = self.mu[mine], self.bound[mine]
        coulomb = ~np.isnan(mu) & (mu > 0)
        gens = [(-nu)[~coulomb]] + [(-nu + mu[:, None] * _direction(tau, a))[coulomb]
                                    for a in _angles(self.problem.disc.dim)]
        sel = [~coulomb] + [coulomb] * (len(gens) - 1)
        A = np.concatenate([np.einsum("nd,ndr->rn", g, M[m]) for g, m in zip(gens, sel)],
                           axis=1)
        tb, j = ~np.isnan(bound), tau.shape[1]
        B = np.concatenate([np.vstack([np.einsum("nd,ndr->rn", tau[tb, i], M[tb]),
                                       (w * bound)[tb][None] / np.sqrt(j)])
                            for i in range(j)], axis=1)
        comm = self.problem.disc.comm
        return (np.concatenate(comm.allgather(A), axis=1),
                np.concatenate(comm.allgather(B), axis=1))

    def _why(self, k: int, F: np.ndarray, W: np.ndarray, box: np.ndarray, t: float) -> str:
        """The refusal's words for part k at time t (F: the applied force resultant, W: the
        loads' work on the free motions)."""
        disc = self.problem.disc
        c, mine = disc.comm, self.mine[k]
        nbar = self._mean_normal(k)
        P = float(F @ nbar)                     # the load pressing along the outward normal
        Q = float(np.linalg.norm(F - P * nbar))
        mu = c.allreduce(float(np.nanmax(self.mu[mine], initial=-1.0)), op=MPI.MAX)
        bounded = c.allreduce(bool(np.any(~np.isnan(self.bound[mine]))), op=MPI.LOR)
        pairs = self.parts[k].surface_of + self.parts[k].target_of
        held = ("the contact with the foundation" if not pairs else
                "contact pair(s) " + ", ".join(f"contact.pairs[{i}]" for i in pairs))
        keys = "loads.traction / loads.pressure / loads.f0"
        fkey = "contact.friction" if not pairs else "the pair's friction"
        at = (f"at t = {t:g} the applied force resultant ({', '.join(f'{v:.6g}' for v in F)})"
              f" on the {'body' if len(self.parts) == 1 else f'part {k + 1}'} held only by "
              f"{held}")
        if not np.any(W):                       # no load: nothing to hold, the motion free
            return self._unloaded(k, t, keys)
        if P <= 0:
            return (f"{keys}: {at} does not press it onto Gamma3 (normal component "
                    f"{P:.6g} <= 0: a pull-off); clamp a group or press the body")
        if mu <= 0 and not bounded:
            return (f"{keys} / {fkey}: {at}: frictionless contact cannot hold its "
                    f"tangential motion (tangential resultant {Q:.6g}); add friction or "
                    "prescribe a tangential component")
        # 3D: the cone is its inscribed polygon of COULOMB_DIRECTIONS sides (mu cos(pi/16))
        inner = 1.0 if disc.dim == 2 else float(np.cos(np.pi / COULOMB_DIRECTIONS))
        if mu > 0 and Q >= mu * P * (1 - 1e-9):
            return (f"{keys} / {fkey}.coulomb.mu: {at}: tangential resultant "
                    f"{Q:.6g} >= mu P = {mu:g} x {P:.6g} = {mu * P:.6g}: the body would slide "
                    "away; lower the tangential load or prescribe a tangential component")
        if mu > 0 and Q >= inner * mu * P * (1 - 1e-9):
            return (f"{keys} / {fkey}.coulomb.mu: {at}: tangential resultant {Q:.6g} is "
                    f"within {100 * (1 - inner):.1f} % below mu P = {mu * P:.6g}: in 3D the "
                    f"check takes the friction cone as its inscribed {COULOMB_DIRECTIONS}-gon "
                    f"({inner:.4f} mu), so this load is refused as at the onset of sliding; "
                    "lower the tangential load or prescribe a tangential component")
        cap = float(box[-1].sum()) / np.sqrt(disc.dim - 1)   # sum_i w_i psi'(oo)
        if bounded and Q >= cap * (1 - 1e-9):
            return (f"{keys} / {fkey}: {at}: tangential resultant {Q:.6g} >= the friction "
                    f"bound's resultant {cap:.6g} (psi'(oo) w_i over Gamma3): the body would "
                    "slide away")
        return (f"{keys}: {at} has a moment the contact zone cannot carry (its centre of "
                "pressure falls outside Gamma3, or the friction cannot hold it); clamp a "
                "group or change the loads")

    def _unloaded(self, k: int, t: float, keys: str) -> str:
        """The refusal of part k without any load on its free motions at t: as the
        rigid-motion check's (app/model/dirichlet.py), the loads named."""
        free = self.parts[k].free
        return (f"boundaries.clamped / loads.displacement: the prescribed displacements leave "
                f"{free.shape[1]} rigid motion(s) of the "
                f"{'body' if len(self.parts) == 1 else f'part {k + 1}'} free (like "
                f"{motion_names(free, self.problem.disc.dim)}), and at t = {t:g} no load ({keys}) "
                "presses it onto Gamma3; clamp a group, prescribe more components or press "
                "the body")

    def _mean_normal(self, k: int) -> np.ndarray:
        """The unit mean of sigma_ik w_i nu_i over part k's Gamma3 nodes (collective): the
        direction in which the contact presses the part outward."""
        mine = self.mine[k]
        n = self.problem.disc.comm.allreduce(
            ((self.sign[k][mine] * self.w[mine])[:, None] * self.normal[mine]).sum(0),
            op=MPI.SUM)
        return n / max(np.linalg.norm(n), 1e-300)

    # ---------------------------------------------------------------- the step's start
    def close_gap(self, u) -> bool:
        """Translate each part out of contact at u (no Gamma3 node of it with u_nu > 0; two
        bodies: w_nu) towards the contact until its nearest Gamma3 node is half-way into
        the gap (on the bound without a normal compliance, 1e-3 of the body's size without
        a bound); collective.

        Args:
            u: the displacement Function (the step's start, u_{n-1}), changed in place.

        Returns:
            Whether u was changed (on every rank).
        """
        p = self.problem
        r = np.einsum("nd,nd->n", p.contact_u()[self.pos], self.normal)
        target = self._target()
        disc = p.disc
        arr, changed = u.x.array.reshape(-1, disc.dim), False
        for k, part in enumerate(self.parts):
            mine = self.mine[k]
            if disc.comm.allreduce(bool(np.any(r[mine] > 0)), op=MPI.LOR):
                continue                         # in contact somewhere
            nbar = self._mean_normal(k)
            cos = self.sign[k][mine] * (self.normal[mine] @ nbar)
            ok = cos > 1e-6
            s = disc.comm.allreduce(float(np.min(((target - r)[mine] / np.where(ok, cos, 1))[ok],
                                              initial=np.inf)), op=MPI.MIN)
            if not np.isfinite(s) or s == 0.0:
                continue
            arr[part.nodes[:len(arr)]] += s * nbar
            changed = True
            log.debug("part %d held by contact: the step starts from it translated by %.3g "
                      "into contact", k + 1, s)
        if changed:
            u.x.scatter_forward()
        return changed

    def pinned_slots(self) -> np.ndarray:
        """The normal dofs (d node + slot, in the nodal frames) of the held parts' owned
        Gamma3 nodes that are in contact at u (u_nu, two bodies w_nu, at least the start's
        target): those SNES VI's first solve holds (``SNESVISolver.press_next``);
        collective with pairs.

        Returns:
            Local dof indices.
        """
        p, fr = self.problem, self.problem.disc.frames
        r = np.einsum("nd,nd->n", p.contact_u()[self.pos], self.normal)
        tol = 1e-9 * max(float(np.max(np.abs(self._target()), initial=0.0)),
                         1e-12 * p.disc.length_scale)
        on = np.any(self.mine, axis=0) & (r >= self._target() - tol) & fr.bounded[self.pos]
        return (p.disc.dim * self.nodes[on] + fr.slot[self.pos][on]).astype(np.int32)

    def _target(self) -> np.ndarray:
        """u_nu (w_nu) at which a Gamma3 node is in contact for the start (owned nodes)."""
        if self.g is None:
            return np.full(len(self.nodes), 1e-3 * self.problem.disc.length_scale)
        return np.where(self.compliance, 0.5 * self.g, self.g)

    def pressure_start(self, f: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Coulomb's start p_n for a step: the last p_n scaled to the normal resultant P of
        the step's loads on each part, or P spread uniformly where none of its nodes is
        pressed (owned Gamma3 nodes; collective).  From the last step's p_n alone, a growing
        load would meet a friction bound mu p_(n-1) below its tangential resultant: nothing
        would hold the tangential motion in the fixed point's first solve.

        Args:
            f: the owned nodal loads (n, d) of the step (the rigid caps' loads are added).
            p: the last p_n at the owned Gamma3 nodes (``problem.disc.gamma3``'s order).

        Returns:
            p (owned Gamma3 nodes).
        """
        c, out = self.problem.disc.comm, p.copy()
        for k, part in enumerate(self.parts):
            mine = self.mine[k]
            t = float(self.problem.time_data.t.value)
            F = c.allreduce(f[part.nodes[:len(f)]].sum(axis=0), op=MPI.SUM) + \
                self._cap_loads(k, t)[1]
            nbar = self._mean_normal(k)
            cos = self.sign[k][mine] * (self.normal[mine] @ nbar)
            area = c.allreduce(float((self.w[mine] * cos).sum()), op=MPI.SUM)
            P = max(float(F @ nbar), 0.0)
            R = c.allreduce(float((self.w[mine] * p[mine] * cos).sum()), op=MPI.SUM)
            out[mine] = p[mine] * (P / R) if R > 1e-12 * P else P / max(area, 1e-300)
        return out


def _signs(part, nodes: np.ndarray, pair: np.ndarray | None) -> np.ndarray:
    """sigma_i of the owned Gamma3 nodes for a part: +1 its own (the foundation's Gamma3, a
    pair's surface), -1 where it carries the node's pair's target, else 0."""
    own = part.nodes[nodes]
    if pair is None:
        return own.astype(float)
    return np.where(own & np.isin(pair, part.surface_of), 1.0,
                    np.where(np.isin(pair, part.target_of), -1.0, 0.0))


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
    from scipy.sparse import diags, hstack, vstack
    scale = np.linalg.norm(b)
    B = box[:-1]
    if scale == 0.0 or np.linalg.matrix_rank(np.hstack([A, B])) < len(b):
        return False                # no load, or a free motion no contact force resists
    n, m = A.shape[1], B.shape[1]
    c = box[-1] / scale
    An = A / np.maximum(np.linalg.norm(A, axis=0), 1e-300)
    # unknowns (e, t, s) with a = s + e, e >= 0: max s, An e + B t + (An 1) s = b / scale,
    # |t_j| + s c_j <= c_j, s <= 1
    cost = np.zeros(n + m + 1)
    cost[-1] = -1.0
    eq = np.hstack([An, B, An.sum(axis=1, keepdims=True)])
    ub = vstack([hstack([diags(sign * np.ones(m)), c[:, None]]) for sign in (1.0, -1.0)])
    ub = hstack([np.zeros((2 * m, n)), ub]).tocsr() if m else None
    res = linprog(cost, A_ub=ub, b_ub=np.concatenate([c, c]) if m else None, A_eq=eq,
                  b_eq=b / scale, bounds=[(0, None)] * n + [(None, None)] * m + [(None, 1.0)],
                  method="highs")
    return bool(res.status == 0 and -res.fun > SLACK)
