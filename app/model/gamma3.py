"""History terms on Gamma3 (the paper's memory term; slip dependence is our extension): the
memory term xi_n and the accumulated slip s_n, per Gamma3 node: the discrete sums of the step
inequality (3.4) (the memory integral of (1.7) and the total slip of (1.6), by the left
rectangle rule):

xi_n = sum_{j=1..n} k_j b(t_n - t_{j-1}) u_{j-1,nu}^+,     s_n = sum_{j=1..n} k_j |u_{j-1,tau}|.

For the exponential kernel b(t) = b0 exp(-beta t) the sum obeys the exact recursion
    xi_n = exp(-beta k_n) (xi_{n-1} + k_n b0 u_{n-1,nu}^+)
(split off the j = n term and factor exp(-beta (t_n - t_{n-1})) out of the rest; exact for
non-uniform steps), so it costs O(1) per node and step.  A general kernel keeps the history
of u_nu^+ per node and sums directly (O(n) per node and step).  The slip obeys
s_n = s_{n-1} + k_n |u_{n-1,tau}|.  Each term exists only if the case enables it.
"""
from __future__ import annotations

import numpy as np
from dolfinx import fem


# ----------------------------------------------------------------------------- kernels
class Kernel:
    """b(t) of the memory term: exponential b0 exp(-beta t), power law
    b0 (1 + t / tau)^-alpha, or b0 times a piecewise-linear table.

    Args:
        kind: "exponential", "power" or "table".
        b0: the factor b0.
        beta: the exponential kernel's rate.
        alpha: the power law's exponent.
        tau: the power law's time scale.
        table: (t, b) points of the table kernel.

    Raises:
        ValueError: an unknown ``kind``.
    """

    def __init__(self, kind: str, b0: float, beta: float = 0.0, alpha: float = 1.0,
                 tau: float = 1.0, table=None):
        self.kind, self.b0, self.beta, self.alpha, self.tau = kind, b0, beta, alpha, tau
        if kind == "table":
            pts = np.asarray(table, dtype=float)
            self._ts, self._bs = pts[:, 0], pts[:, 1]
        elif kind not in ("exponential", "power"):
            raise ValueError(f"unknown kernel {kind!r}")

    def __call__(self, t):
        """Evaluate the kernel.

        Args:
            t: time(s) since the contribution, >= 0 (a number or an array).

        Returns:
            b(t), elementwise (an array of t's shape).
        """
        t = np.asarray(t, dtype=float)
        if self.kind == "exponential":
            return self.b0 * np.exp(-self.beta * t)
        if self.kind == "power":
            return self.b0 * (1.0 + t / self.tau) ** (-self.alpha)
        return self.b0 * np.interp(t, self._ts, self._bs)


class MemorySum:
    """The memory term xi_n = sum_{j=1..n} k_j b(t_n - t_{j-1}) u_{j-1,nu}^+ of (3.4) at m
    nodes.

    Args:
        kernel: b(t).
        m: the number of nodes.
        recursion: the exact O(1) recursion (exponential kernel only); None: the recursion
            for the exponential kernel, the direct sum otherwise.

    Raises:
        ValueError: the recursion asked for with a kernel that is not exponential.
    """

    def __init__(self, kernel: Kernel, m: int, recursion: bool | None = None):
        self.kernel = kernel
        self.recursion = kernel.kind == "exponential" if recursion is None else recursion
        if self.recursion and kernel.kind != "exponential":
            raise ValueError("the recursion is exact only for the exponential kernel")
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
            decay = np.exp(-self.kernel.beta * k)
            self.xi = decay * (self.xi + k * self.kernel.b0 * r_plus)
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
        theta_inf: theta(s) for s -> infinity.
        s0: the slip scale of theta.
    """

    def __init__(self, m: int, theta_inf: float, s0: float):
        self.s = np.zeros(m)
        self.theta_inf, self.s0 = theta_inf, s0

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
            theta(s_n) = theta_inf + (1 - theta_inf) exp(-s_n / s0), shape (m,).
        """
        return self.theta_inf + (1.0 - self.theta_inf) * np.exp(-self.s / self.s0)


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
        memory: {"kernel": Kernel, "recursion": bool | None}, or None: no memory term.
        slip: {"theta_inf": ..., "s0": ...}, or None: no slip dependence.
    """

    def __init__(self, problem, memory=None, slip=None):
        self.u = problem.u
        self.nodes = problem.gamma3_local_nodes
        self.normal = problem.frames.normal          # (m, d): nu_i at the nodes
        self.dim = problem.dim
        m = len(self.nodes)
        self.memory = self.slip = None
        if memory is not None:
            self.memory = MemorySum(memory["kernel"], m, memory.get("recursion"))
            self.xi = problem.xi
            self.xi.set(self.memory.xi)
        if slip is not None:
            self.slip = SlipSum(m, slip["theta_inf"], slip["s0"])
            self.theta = problem.theta
            self.theta.set(self.slip.theta())

    def state(self) -> dict:
        """The history at the local Gamma3 nodes (owned and ghost).

        Returns:
            {"memory": MemorySum.state() or None, "slip": SlipSum.state() or None}.
        """
        return {"memory": self.memory.state() if self.memory else None,
                "slip": self.slip.state() if self.slip else None}

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

    def advance(self, t_prev: float, t_n: float) -> None:
        """xi_n, s_n from u_{n-1} (the current u), before solving step n.

        Args:
            t_prev: t_{n-1}.
            t_n: t_n.
        """
        u = self.u.x.array.reshape(-1, self.dim)[self.nodes]
        u_nu = np.einsum("ij,ij->i", u, self.normal)
        if self.memory is not None:
            self.xi.set(self.memory.advance(np.maximum(u_nu, 0.0), t_prev, t_n))
        if self.slip is not None:
            u_tau = u - u_nu[:, None] * self.normal
            self.slip.advance(np.linalg.norm(u_tau, axis=1), t_n - t_prev)
            self.theta.set(self.slip.theta())
