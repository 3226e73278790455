"""The split solve of the condensed solver compiled (ldl_blocks.c), and its numpy reference.

With K = L D L^T ordered interior first, Gamma3 (G) last, one step's solve is a forward sweep
over the interior columns of L (which yields the Gamma3 problem's data), the Gamma3 problem,
and a backward sweep with u_G given (app/solvers/condensed/).  ``GLastSolve`` keeps L's interior
columns in node blocks for the C sweeps; ``split_solve_numpy`` is the same solve with dense
triangular solves, the reference of the tests.
"""
from __future__ import annotations

import heapq

import numpy as np

from vpcontact.kernels.build import buf

SPLIT_MIN_BLOCKS = 100_000     # blocks of L's interior from which two threads sweep
SPLIT_MIN_SAVING = 0.1         # the least share of the blocks a split takes off the sweeps


def block_size(bs: int, ni: int) -> int:
    """The block size of L's interior columns (GLastSolve).

    Args:
        bs: the dofs per node.
        ni: the number of interior dofs.

    Returns:
        bs if the ni interior dofs are whole nodes (and bs is 1, 2 or 3), else 1.
    """
    return bs if bs in (1, 2, 3) and ni % bs == 0 else 1


def split_solve_numpy(L: np.ndarray, D: np.ndarray, perm: np.ndarray, m: int, b: np.ndarray,
                      y: np.ndarray | None = None):
    """The sweeps of ``GLastSolve`` with dense triangular solves (numpy reference).

    Args:
        L: the unit lower factor of K[perm][:, perm] = L diag(D) L^T, dense (n x n).
        D: the pivots (n).
        perm: the dof at each position (Gamma3's m dofs last).
        m: the number of Gamma3 dofs.
        b: the right-hand side (natural order).
        y: the Gamma3 values u_G, or None (forward sweep only).

    Returns:
        (r, u): r = b_G - L_GI L_II^-1 b_I (permuted order) and, if y is given, u with
        u_G = y and u_I = L_II^-T (D_I^-1 L_II^-1 b_I - L_GI^T y) (natural order), else None.
    """
    ni = len(b) - m
    x = np.asarray(b, dtype=float)[perm]
    z = np.linalg.solve(L[:ni, :ni], x[:ni])
    r = x[ni:] - L[ni:, :ni] @ z
    if y is None:
        return r, None
    uI = np.linalg.solve(L[:ni, :ni].T, z / D[:ni] - L[ni:, :ni].T @ y)
    u = np.empty(len(b))
    u[perm] = np.concatenate([uI, y])
    return r, u


def subtree_split(Bp: np.ndarray, Bi: np.ndarray, nbc: int) -> tuple[int, int] | None:
    """Two independent parts of L's interior for two threads' sweeps: the block columns
    0..s1-1 and s1..s2-1, where no column of the first has a block in the second's rows, so
    both sweeps can run the two parts at once (the columns from s2 on before or after them).

    Rows of a column are its ancestors in the elimination tree (the parent of a block
    column is its first block row), so the first row >= s1 of the columns before s1 is the
    smallest parent >= s1 among them: s2(s1), found for every s1 in one pass with a heap.
    s1 minimises the blocks swept one after the other, max(A, B) + the rest (A, B the parts'
    blocks; with nested dissection: the two halves under the top separator).

    Args:
        Bp, Bi: the block columns (GLastSolve's blocks).
        nbc: the number of interior block columns.

    Returns:
        (s1, s2), or None where no split saves SPLIT_MIN_SAVING of the blocks swept in turn.
    """
    counts = np.diff(Bp[:nbc + 1])
    parent = np.full(nbc, nbc, dtype=np.int64)         # nbc: no parent in the interior
    has = np.flatnonzero(counts > 0)
    if has.size:
        first_row = np.minimum.reduceat(Bi[:Bp[nbc]], Bp[has])
        parent[has] = np.minimum(first_row, nbc)
    W = np.concatenate([[0], np.cumsum(counts + 1)])
    heap, s2 = [], np.empty(nbc + 1, dtype=np.int64)
    for s1, p in enumerate(parent.tolist(), start=1):  # s2(s1): min parent >= s1 before s1
        heapq.heappush(heap, p)
        while heap[0] < s1:
            heapq.heappop(heap)
        s2[s1] = heap[0]
    s1 = np.arange(1, nbc)
    cost = np.maximum(W[s1], W[s2[1:nbc]] - W[s1]) + W[-1] - W[s2[1:nbc]]
    best = int(np.argmin(cost))
    if cost[best] > (1 - SPLIT_MIN_SAVING) * W[-1]:
        return None
    s1, top = int(s1[best]), int(s2[s1[best]])
    rows = Bi[:Bp[s1]]                          # checked: no block of 0..s1-1 in s1..top-1
    return (s1, top) if not np.any((rows >= s1) & (rows < top)) else None


class GLastSolve:
    """u = K^-1 (b + E_G lambda) in one forward and one backward sweep, with the Gamma3 values
    y = u_G found in between (app/solvers/condensed/): with K = L D L^T ordered interior
    first, G last,
        forward:  z_I = L_II^-1 b_I,  r = b_G - L_GI z_I,
        Gamma3:   S u_G = r + lambda (S = L_GG D_G L_GG^T), i.e. y0 = S^-1 r without contact,
        backward: u_I = L_II^-T (D_I^-1 z_I - L_GI^T y).
    One factorisation serves the Schur complement and every step.  The interior columns of
    L are kept in bs x bs blocks (ldl_blocks; bs = 1 if the interior is not a whole number
    of blocks).  Numpy reference: ``split_solve_numpy``.

    Args:
        factor: a G-last factorisation (schur.GLastLDL with ``blocks``, or schur.GLastLU:
            ``n``, ``m``, ``perm``, ``D`` and L in CSC as ``Lp``, ``Li``, ``Lx``).
        module: the compiled kernels (kernels.load()).
        bs: the dofs per node (the block size where the interior is whole nodes).
        threads: the threads the sweeps may use: with 2 or more and from SPLIT_MIN_BLOCKS
            blocks, two threads sweep the two parts of ``subtree_split`` at once (the
            sweeps are bound by memory traffic, which one core does not saturate).
    """

    def __init__(self, factor, module, bs: int = 1, threads: int = 1):
        self.mod, self.n, self.m = module, factor.n, factor.m
        self.ni = self.n - self.m
        self.perm = factor.perm
        ffi, lib, i = module.ffi, module.lib, np.intc
        blocks = getattr(factor, "blocks", None)
        if blocks is not None:              # made by the factorisation (ldl.Factor)
            self.bs, nbc, self.Bp, self.Bi, self.Bx, self.Ld = blocks
            self._factor = factor           # Bx may live in CHOLMOD's memory
        else:                               # from L in CSC (SuperLU)
            self.bs = block_size(bs, self.ni)
            Lp, Li = np.asarray(factor.Lp, dtype=i), np.asarray(factor.Li, dtype=i)
            Lx = np.ascontiguousarray(factor.Lx, dtype=float)
            nbc, nbr = self.ni // self.bs, -(-self.n // self.bs)
            mark, slot = np.full(nbr, -1, dtype=i), np.empty(nbr, dtype=i)
            Bp = np.zeros(nbc + 1, dtype=i)
            args = (buf(ffi, Lp), buf(ffi, Li), buf(ffi, Lx))
            lib.ldl_blocks(self.bs, nbc, *args, buf(ffi, Bp), ffi.NULL, ffi.NULL, ffi.NULL,
                           buf(ffi, mark), buf(ffi, slot))
            np.cumsum(Bp, out=Bp)
            b2 = self.bs * self.bs
            self.Bp, self.Bi = Bp, np.empty(max(int(Bp[-1]), 1), dtype=i)
            self.Bx, self.Ld = np.zeros(max(int(Bp[-1]), 1) * b2), np.zeros(max(nbc, 1) * b2)
            mark.fill(-1)
            lib.ldl_blocks(self.bs, nbc, *args, buf(ffi, Bp), buf(ffi, self.Bi),
                           buf(ffi, self.Bx), buf(ffi, self.Ld), buf(ffi, mark),
                           buf(ffi, slot))
        self.nbc = nbc
        self.dinv = 1.0 / np.asarray(factor.D)[:self.ni]
        self.x = np.empty(self.n)
        self._blocks = tuple(buf(ffi, a) for a in (self.Bp, self.Bi, self.Bx, self.Ld))
        self._dinv, self._x = buf(ffi, self.dinv), buf(ffi, self.x)
        self.split = None
        if threads >= 2 and self.Bp[nbc] >= SPLIT_MIN_BLOCKS:
            self.split = subtree_split(self.Bp, self.Bi, nbc)
        if self.split is not None:
            self.y = np.empty(self.n)
            self._y = buf(ffi, self.y)

    def forward(self, b: np.ndarray) -> np.ndarray:
        """Permute b and sweep the interior columns.

        Args:
            b: the right-hand side (natural order).

        Returns:
            r = b_G - L_GI L_II^-1 b_I (a view of a work array).
        """
        np.take(b, self.perm, out=self.x)
        if self.split is not None:
            self.mod.lib.ldl_forward_split(self.bs, self.nbc, *self.split, self.n,
                                           *self._blocks, self._x, self._y)
        else:
            self.mod.lib.ldl_forward_interior(self.bs, self.nbc, *self._blocks, self._x)
        return self.x[self.ni:]

    def backward(self, y: np.ndarray, out: np.ndarray) -> None:
        """Set u_G = y, sweep back through the interior, write u (natural order) to out.

        Args:
            y: the Gamma3 values u_G (after ``forward``).
            out: the solution u (natural order), written.
        """
        self.x[self.ni:] = y
        if self.split is not None:
            self.mod.lib.ldl_backward_split(self.bs, self.nbc, *self.split, *self._blocks,
                                            self._dinv, self._x)
        else:
            self.mod.lib.ldl_backward_given_tail(self.bs, self.nbc, *self._blocks,
                                                 self._dinv, self._x)
        out[self.perm] = self.x


