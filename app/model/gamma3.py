"""History terms on Gamma3 (the paper's memory term; slip dependence is our extension): the
memory term xi_n and the accumulated slip s_n, per Gamma3 node: the discrete sums of the step
inequality (3.4) (the memory integral of (1.7) and the total slip of (1.6), by the left
rectangle rule):

xi_n = sum_{j=1..n} k_j b(t_n - t_{j-1}) u_{j-1,nu}^+,     s_n = sum_{j=1..n} k_j |u_{j-1,tau}|.

The kernel b(t) and theta(s) are laws of app/model/contact_laws.py (no state); these
sums are their state.  For a kernel with an exact recursion (the exponential kernel
b(t) = b0 exp(-beta t): ``ExponentialKernel.recursion``) the sum costs O(1) per node and
step; a general kernel keeps the history of u_nu^+ per node and sums directly (O(n) per node
and step).  The slip obeys s_n = s_{n-1} + k_n |u_{n-1,tau}|.  Each term exists only if the
case enables it.  A kernel b(t, x) = b0(x) b(t) with b0 an expression of x (H(b)) sums
b0(x_i) u_{j-1,nu}^+ with the kernel of factor 1; theta(s) is the exponential law or a table
(``slip_law``).

With friction that has a slip variable (Coulomb's bound mu p_n, a slip law theta(s)) the
history also follows the slip path of each node (``SlipPath``): the slip increment of step n,
|u_{n,tau} - u_{n-1,tau}|, and the accumulated slip sum_{j=1..n} |u_{j,tau} - u_{j-1,tau}|,
both lengths (m), unlike s_n of (1.6), a time integral of |u_tau| (m s).
"""
from __future__ import annotations

import numpy as np
from dolfinx import fem

from vpcontact.model.contact_laws import SlipWeakening, space_field
from vpcontact.model.contactregistry import KERNELS, coulomb_law, slip_law
from vpcontact.model.coulomb import CoulombPressure
from vpcontact.model.memory_kernels import FieldKernel, MemoryKernel
from vpcontact.model.primitives import NUMPY


class MemorySum:
    """The memory term xi_n = sum_{j=1..n} k_j b(t_n - t_{j-1}) u_{j-1,nu}^+ of (3.4) at m
    nodes.

    Args:
        kernel: b(t).
        m: the number of nodes.
        recursion: the kernel's exact O(1) recursion (recursive kernels only); None: the
            recursion where the kernel has one, the direct sum otherwise.

    Raises:
        ValueError: the recursion asked for with a kernel that has none.
    """

    def __init__(self, kernel: MemoryKernel, m: int, recursion: bool | None = None):
        self.kernel = kernel
        self.recursion = kernel.recursive if recursion is None else recursion
        if self.recursion and not kernel.recursive:
            raise ValueError("the recursion is exact only for a recursive kernel "
                             "(the exponential one)")
        self.xi = np.zeros(m)
        self._t_prev: list[float] = []       # t_{j-1}
        self._k: list[float] = []            # k_j
        self._r: list[np.ndarray] = []       # u_{j-1,nu}^+

    @property
    def stored_steps(self) -> int:
        """Steps of u_nu^+ kept for the direct sum (0 with the recursion)."""
        return len(self._r)

    def state(self) -> dict:
        """xi_n and, for the direct sum, the stored t_{j-1}, k_j and u_{j-1,nu}^+.

        Returns:
            {"xi": array (m,), "t_prev": list, "k": list, "r": list of arrays (m,)}; the
            lists are copies (their arrays are never changed in place), so taking the state
            costs O(n), not O(n m).
        """
        return {"xi": self.xi.copy(), "t_prev": list(self._t_prev), "k": list(self._k),
                "r": list(self._r)}

    def load_state(self, state: dict) -> None:
        """Set xi and the stored history from ``state()`` (or a checkpoint's copy of it).

        Args:
            state: {"xi", "t_prev", "k", "r"} as returned by ``state()``.
        """
        self.xi = np.array(state["xi"], dtype=float)
        self._t_prev, self._k = list(state["t_prev"]), list(state["k"])
        self._r = [np.asarray(r, dtype=float) for r in state["r"]]

    def advance(self, r_plus: np.ndarray, t_prev: float, t_n: float) -> np.ndarray:
        """xi_n from xi_{n-1} (recursion) or from the stored history (direct sum).

        Args:
            r_plus: u_{n-1,nu}^+ at the m nodes.
            t_prev: t_{n-1}.
            t_n: t_n.

        Returns:
            xi_n (m,).
        """
        k = t_n - t_prev
        if self.recursion:
            self.xi = self.kernel.recursion(self.xi, r_plus, k)
        else:
            self._t_prev.append(t_prev)
            self._k.append(k)
            self._r.append(np.array(r_plus, dtype=float))
            w = np.asarray(self._k) * self.kernel(t_n - np.asarray(self._t_prev))
            self.xi = w @ np.asarray(self._r)
        return self.xi


class SlipSum:
    """The accumulated slip s_n = s_{n-1} + k_n |u_{n-1,tau}| of (3.4) at m nodes, and
    theta(s) of the slip-dependent friction (4.2).

    Args:
        m: the number of nodes.
        law: theta(s) (``SlipWeakening`` or ``TableSlip``).
    """

    def __init__(self, m: int, law: SlipWeakening):
        self.s = np.zeros(m)
        self.law = law

    def advance(self, abs_tau: np.ndarray, k: float) -> np.ndarray:
        """s_n = s_{n-1} + k_n |u_{n-1,tau}|.

        Args:
            abs_tau: |u_{n-1,tau}| at the m nodes.
            k: the step k_n.

        Returns:
            s_n (m,).
        """
        self.s = self.s + k * abs_tau
        return self.s

    def state(self) -> dict:
        """Returns: {"s": a copy of s_n (m,)}."""
        return {"s": self.s.copy()}

    def load_state(self, state: dict) -> None:
        """Set s from ``state()`` (or a checkpoint's copy of it).

        Args:
            state: {"s": array (m,)}.
        """
        self.s = np.array(state["s"], dtype=float)

    def theta(self) -> np.ndarray:
        """The slip-dependent friction factor of j_tau(s, xi) = theta(s) psi(|xi|) (the
        slip version of (4.2)) at the current s_n.

        Returns:
            theta(s_n) of the law, shape (m,).
        """
        return self.law.theta(self.s)


class NodewiseSlip:
    """theta(s) of pairs with different laws: each pair's slip law on its nodes, 1 on the
    nodes of pairs without one.

    Args:
        m: the number of nodes.
        parts: (rows, law) per pair with a slip law (a boolean mask over the m nodes, and
            its ``SlipWeakening``, ``TableSlip`` or ``StaticKineticSlip``).
    """

    def __init__(self, m: int, parts: list):
        self.m, self.parts = m, parts

    @property
    def theta_max(self) -> float:
        """The largest theta of the pairs' laws (1 on the nodes of pairs without one)."""
        return max([1.0] + [law.theta_max for _, law in self.parts])

    def theta(self, s):
        """theta(s) node by node.

        Args:
            s: the accumulated slip s_n at the m nodes.

        Returns:
            theta(s_n), shape (m,).
        """
        out = np.ones(self.m)
        for rows, law in self.parts:
            out[rows] = law.theta(np.asarray(s)[rows])
        return out


class SlipPath:
    """The slip path of m nodes: the tangential displacement u_{n-1,tau} of the last accepted
    step (before step n), and the accumulated slip l_{n-1} = sum_{j=1..n-1} |u_{j,tau} -
    u_{j-1,tau}| (the path length of u_tau, in m; the first increment is measured from
    u_0). After step n the slip increment is |u_{n,tau} - u_{n-1,tau}| and the accumulated
    slip l_{n-1} + that increment (``increment``, ``accumulated``).  Not s_n of (1.6)
    (SlipSum: sum k_j |u_{j-1,tau}|, a time integral in m s, the argument of theta(s)).

    Args:
        m: the number of nodes.
    """

    def __init__(self, m: int):
        self.prev: np.ndarray | None = None     # u_{n-1,tau} (m, d); None before step 1
        self.length = np.zeros(m)

    def advance(self, u_tau: np.ndarray) -> None:
        """Before step n: l_{n-1} = l_{n-2} + |u_{n-1,tau} - u_{n-2,tau}|, then keep
        u_{n-1,tau}.

        Args:
            u_tau: u_{n-1,tau} at the m nodes (m, d), the current u's.
        """
        if self.prev is not None:
            self.length = self.length + np.linalg.norm(u_tau - self.prev, axis=1)
        self.prev = np.array(u_tau, dtype=float)

    def increment(self, u_tau: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """The slip increment |u_{n,tau} - u_{n-1,tau}| of the current step (0 before step 1).

        Args:
            u_tau: u_{n,tau} at the m nodes, or at ``rows`` of them ((m, d) or (rows, d)).
            rows: a selection of the m nodes (an index array), or None: all.

        Returns:
            Lengths, one per row of u_tau.
        """
        if self.prev is None:
            return np.zeros(len(u_tau))
        prev = self.prev if rows is None else self.prev[rows]
        return np.linalg.norm(u_tau - prev, axis=1)

    def accumulated(self, u_tau: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """The accumulated slip l_n = l_{n-1} + |u_{n,tau} - u_{n-1,tau}|.

        Args:
            u_tau: u_{n,tau} at the m nodes, or at ``rows`` of them.
            rows: a selection of the m nodes (an index array), or None: all.

        Returns:
            Lengths, one per row of u_tau.
        """
        length = self.length if rows is None else self.length[rows]
        return length + self.increment(u_tau, rows)

    def state(self) -> dict:
        """Returns: {"prev": a copy of u_{n-1,tau} (m, d) or None, "length": l_{n-1} (m,)}."""
        return {"prev": None if self.prev is None else self.prev.copy(),
                "length": self.length.copy()}

    def load_state(self, state: dict | None) -> None:
        """Set the path from ``state()`` or a checkpoint's copy (None: from the start).

        Args:
            state: {"prev", "length"} or None.
        """
        if state is None:
            self.prev, self.length = None, np.zeros(len(self.length))
            return
        self.prev = None if state["prev"] is None else np.array(state["prev"], dtype=float)
        self.length = np.array(state["length"], dtype=float)


# ----------------------------------------------------------------------------- wiring
class NodalField:
    """A P1 scalar Function whose values at the Gamma3 nodes (given as nodes of the vector
    space V, owned and ghost) are set from numpy arrays.

    Args:
        V: the P1 vector space of u.
        nodes: the local Gamma3 nodes (owned and ghost) as nodes of V.
        name: the Function's name.
    """

    def __init__(self, V, nodes: np.ndarray, name: str):
        W, parent = V.sub(0).collapse()
        bs = V.dofmap.index_map_bs
        node_to_w = np.empty(V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts,
                             dtype=np.int64)
        node_to_w[np.asarray(parent) // bs] = np.arange(len(parent))
        self.function = fem.Function(W, name=name)
        self.dofs = node_to_w[nodes]

    def set(self, values: np.ndarray) -> None:
        """Set the Function's values at the nodes.

        Args:
            values: one value per node of ``nodes``, shape (len(nodes),).
        """
        self.function.x.array[self.dofs] = values


class Gamma3History:
    """The history terms on Gamma3: xi_n (memory) and s_n (slip), with xi_n and theta(s_n)
    as P1 Functions of the step forms, advanced from u_{n-1} before step n.

    Args:
        problem: the ContactProblem (u, the Gamma3 nodes and normal, the Functions xi and
            theta).
        kernel: b(t) of the memory term, or None: no memory term.
        slip: theta(s) of the slip dependence, or None: none.
        recursion: the memory sum by the kernel's recursion (True), directly (False) or
            the recursion where the kernel has one (None).
        b0: b0(x) at the local Gamma3 nodes for a kernel b(t, x) = b0(x) b(t) whose own
            factor is 1 (xi_n sums k_j b(t_n - t_{j-1}) b0(x) u_{j-1,nu}^+), or None.
        mu: the Coulomb friction coefficient (the factor theta is then mu p_n, times
            theta(s_n) with slip; app/model/coulomb.py), or None; with laws per pair, mu
            at the local Gamma3 nodes.
        coulomb_rows: with laws per pair, the nodes whose pair has Coulomb friction (a
            boolean mask; theta is theta(s_n) or 1 at the others), or None: all.
    """

    def __init__(self, problem, kernel: MemoryKernel | None = None,
                 slip: SlipWeakening | None = None, recursion: bool | None = None,
                 b0: np.ndarray | None = None, mu: float | np.ndarray | None = None,
                 coulomb_rows: np.ndarray | None = None):
        self.b0, self.coulomb_rows = b0, coulomb_rows
        self.problem = problem
        disc = problem.disc
        self.nodes = disc.gamma3_local_nodes
        self.normal = disc.frames.normal          # (m, d): nu_i at the nodes
        self.dim = disc.dim
        m = len(self.nodes)
        self.memory = self.slip = None
        if kernel is not None:
            self.memory = MemorySum(kernel, m, recursion)
            self.xi = problem.xi
            self.xi.set(self.memory.xi)
        if slip is not None:
            self.slip = SlipSum(m, slip)
            self.theta = problem.theta
            self.theta.set(self.slip.theta())
        self.coulomb = None
        if mu is not None:
            self.theta = problem.theta
            self.coulomb = CoulombPressure(problem, mu, NodalField(disc.V, self.nodes,
                                                                   "p_n"), problem.hold)
            self.set_coulomb_bound(mu * self.coulomb.p)
        self.path = SlipPath(m) if slip is not None or mu is not None else None

    def set_coulomb_bound(self, mu_p: np.ndarray) -> None:
        """theta = mu p_n (times theta(s_n) with slip) at the nodes (with laws per pair:
        at the nodes of Coulomb's pairs; theta(s_n) or 1 at the others).

        Args:
            mu_p: mu p_n at the local Gamma3 nodes (owned and ghost), shape (m,).
        """
        theta = None if self.slip is None else self.slip.theta()
        bound = mu_p if theta is None else mu_p * theta
        if self.coulomb_rows is not None:
            bound = np.where(self.coulomb_rows, bound, 1.0 if theta is None else theta)
        self.theta.set(bound)

    def state(self) -> dict:
        """The history at the local Gamma3 nodes (owned and ghost).

        Returns:
            {"memory": MemorySum.state() or None, "slip": SlipSum.state() or None}.
        """
        out = {"memory": self.memory.state() if self.memory else None,
               "slip": self.slip.state() if self.slip else None}
        if self.coulomb is not None:
            out["coulomb"] = self.coulomb.state()
        if self.path is not None:
            out["path"] = self.path.state()
        return out

    def load_state(self, state: dict) -> None:
        """Set the history from ``state()`` and the Functions xi, theta(s) from it.

        Args:
            state: {"memory": ..., "slip": ...} as returned by ``state()``.
        """
        if self.memory is not None:
            self.memory.load_state(state["memory"])
            self.xi.set(self.memory.xi)
        if self.slip is not None:
            self.slip.load_state(state["slip"])
            self.theta.set(self.slip.theta())
        if self.coulomb is not None:
            self.coulomb.load_state(state.get("coulomb"))
            self.set_coulomb_bound(self.coulomb.mu * self.coulomb.p)
        if self.path is not None:
            self.path.load_state(state.get("path"))

    def components(self) -> tuple[np.ndarray, np.ndarray]:
        """The normal and tangential parts of the current u (two bodies: w) at the nodes.

        Returns:
            u_nu (m,) and u_tau (m, d).
        """
        u = self.problem.contact_u()      # u, or w = [u] - d nu of two bodies
        u_nu = np.einsum("ij,ij->i", u, self.normal)
        return u_nu, u - u_nu[:, None] * self.normal

    def advance(self, t_prev: float, t_n: float) -> None:
        """xi_n, s_n (and the slip path) from u_{n-1} (the current u), before solving step n.

        Args:
            t_prev: t_{n-1}.
            t_n: t_n.
        """
        u_nu, u_tau = self.components()
        if self.memory is not None:
            r_plus = NUMPY.pos(u_nu) if self.b0 is None else self.b0 * NUMPY.pos(u_nu)
            self.xi.set(self.memory.advance(r_plus, t_prev, t_n))
        if self.slip is not None:
            self.slip.advance(np.linalg.norm(u_tau, axis=1), t_n - t_prev)
            self.theta.set(self.slip.theta())
        if self.path is not None:
            self.path.advance(u_tau)


def build_gamma3_history(case, problem) -> Gamma3History | None:
    """The memory term xi_n, the accumulated slip s_n and the Coulomb pressure p_n, only if
    the case enables them.

    Args:
        case: the validated Case (contact.memory, contact.friction.slip and coulomb).
        problem: the ContactProblem.

    Returns:
        A Gamma3History, or None.
    """
    c = case.contact
    if len(c.sections) > 1:
        return _pair_history(c, problem)
    kernel = recursion = b0 = None
    if c.memory is not None:
        mk = c.memory
        if isinstance(mk.b0, str):          # b(t, x) = b0(x) times the kernel of factor 1
            disc = problem.disc
            x = disc.V.tabulate_dof_coordinates()[disc.gamma3_local_nodes, :disc.dim]
            b0 = space_field(mk.b0, x)
        kernel = section_kernel(mk)
        recursion = None if mk.sum == "auto" else mk.sum == "recursion"
    slip = section_slip(c.friction)
    coulomb = getattr(c.friction, "coulomb", None)
    mu = coulomb.mu if coulomb is not None else None
    if kernel is None and slip is None and mu is None:
        return None
    return Gamma3History(problem, kernel, slip, recursion, b0, mu)


def section_kernel(mk) -> MemoryKernel:
    """The kernel b(t) of a memory section: b0 b(t), or for b0(x) the kernel of factor 1
    describing itself with the expression (``FieldKernel``).

    Args:
        mk: the case's Memory (contact.memory, or a pair's): its kernel of ``KERNELS``
            (app/model/contactregistry.py) and constants.

    Returns:
        The kernel.
    """
    field = isinstance(mk.b0, str)
    kernel = KERNELS[mk.kernel].build(mk.constants, 1.0 if field else mk.b0)
    return FieldKernel(kernel, mk.b0) if field else kernel


def section_slip(fr):
    """theta(s) of a friction section: its slip law, mu(s) / mu_s of Coulomb's
    static/kinetic law, or None.

    Args:
        fr: the case's Friction (contact.friction, or a pair's), or None.

    Returns:
        A SlipWeakening, TableSlip or StaticKineticSlip, or None.
    """
    coulomb = getattr(fr, "coulomb", None)
    law = coulomb_law(coulomb) if coulomb is not None else None
    if law is not None and law.slip is not None:    # mu(s) = mu_s theta(s)
        return law.slip
    if fr is not None and fr.slip is not None:
        return slip_law(fr.slip)
    return None


def _pair_history(c, problem) -> Gamma3History | None:
    """The history terms of pairs with different laws (``Contact.sections``), node by node:
    xi_n with one kernel of factor 1 and b0 of each pair's memory term at its nodes (0
    without), theta(s_n) of each pair's slip law (``NodewiseSlip``), mu of each pair's
    Coulomb friction (mu_s of the static/kinetic law)."""
    disc = problem.disc
    pair = disc.pairs.pair                  # the pair of each local Gamma3 node
    m = len(pair)
    x = disc.V.tabulate_dof_coordinates()[disc.gamma3_local_nodes, :disc.dim]
    kernel = recursion = None
    b0, mu, coulomb_rows, slips = np.zeros(m), np.zeros(m), np.zeros(m, dtype=bool), []
    for i, section in enumerate(c.sections):
        rows = pair == i
        mk, fr = section.memory, section.friction
        if mk is not None:
            b0[rows] = space_field(mk.b0, x[rows]) if isinstance(mk.b0, str) else mk.b0
            kernel = KERNELS[mk.kernel].build(mk.constants, 1.0)
            recursion = None if mk.sum == "auto" else mk.sum == "recursion"
        if fr is not None and fr.coulomb is not None:
            mu[rows], coulomb_rows[rows] = fr.coulomb.mu, True
        slip = section_slip(fr)
        if slip is not None:
            slips.append((rows, slip))
    slip = NodewiseSlip(m, slips) if slips else None
    if kernel is None and slip is None and not coulomb_rows.any():
        return None
    return Gamma3History(problem, kernel, slip, recursion, b0 if kernel is not None else None,
                         mu if coulomb_rows.any() else None, coulomb_rows)
