"""Fields of a run on a refined level of the user's mesh (meshes/refine.py), exact
prolongation to the finest level and the error norms of the paper's Table 1 on it.

The levels are nested (every fine cell lies in one coarse cell, every coarse vertex is a fine
vertex), so the prolongation is exact: a coarse P1 function is a fine P1 function (each new
vertex takes the mean of the ends of the edge it halves) and a coarse DG0 function gives
each fine cell its ancestor's value.  Fields are arrays in the level's own numbering,
independent of the MPI partition: u (nv, dim), sigma (nc, dim, dim), kappa (nc,).  A run
reads its level from the level's ``.msh`` (node tags 1..nv in that numbering), so dolfinx's
input indices of the geometry nodes are the level's vertex indices; cells are matched by
their vertex sets.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vpcontact.meshes.refine import MeshLevel
from vpcontact.meshes.refine import prolong_dg0 as _prolong_dg0
from vpcontact.meshes.refine import prolong_p1 as _prolong_p1


@dataclass
class NestedLevel:
    """A level of the study: the user's mesh refined ``r`` times.

    Attributes:
        r: the number of refinements.
        path: its .msh file.
        h: its nominal mesh size h_0 / 2^r (h_0: the largest cell diameter of level 0).
        hierarchy: the MeshLevels of the study on rank 0 (hierarchy[r] is this level), None
            on the other ranks.
    """

    r: int
    path: Path
    h: float
    hierarchy: list | None = field(default=None, repr=False)
    _geometry: tuple | None = field(default=None, repr=False)

    @property
    def mesh(self) -> MeshLevel:
        """The level's MeshLevel (rank 0)."""
        return self.hierarchy[self.r]

    def shapes(self) -> dict:
        """The per-time-point shapes of u, sigma and kappa (rank 0).

        Returns:
            {"u": (nv, dim), "sigma": (nc, dim, dim), "kappa": (nc,)}.
        """
        m = self.mesh
        d = m.dim
        return {"u": (len(m.x), d), "sigma": (len(m.cells), d, d), "kappa": (len(m.cells),)}

    def geometry(self) -> tuple[np.ndarray, np.ndarray]:
        """The cells' volumes and the gradients of their barycentric coordinates (rank 0).

        Returns:
            (vol (nc,), grads (nc, dim + 1, dim)).
        """
        if self._geometry is None:
            m = self.mesh
            p = m.x[m.cells]                                   # (nc, d + 1, d)
            J = np.swapaxes(p[:, 1:] - p[:, :1], 1, 2)         # columns p_i - p_0
            inv = np.linalg.inv(J)                             # rows: grad lambda_i, i >= 1
            grads = np.concatenate([-inv.sum(axis=1, keepdims=True), inv], axis=1)
            vol = np.abs(np.linalg.det(J)) / math.factorial(m.dim)
            self._geometry = (vol, grads)
        return self._geometry

    def prolong_p1(self, values: np.ndarray, fine: NestedLevel) -> np.ndarray:
        """This level's P1 vertex values on a finer level of the same hierarchy (exact).

        Args:
            values: (nv, ...) vertex values on this level.
            fine: the finer level.

        Returns:
            (nv of fine, ...) vertex values.
        """
        return _prolong_p1(values, self.hierarchy, self.r, fine.r)

    def prolong_dg0(self, values: np.ndarray, fine: NestedLevel) -> np.ndarray:
        """This level's DG0 cell values on a finer level of the same hierarchy (exact).

        Args:
            values: (nc, ...) cell values on this level.
            fine: the finer level.

        Returns:
            (nc of fine, ...) cell values.
        """
        return _prolong_dg0(values, self.hierarchy, self.r, fine.r)

    def strain_norm(self, u: np.ndarray) -> float:
        """||eps(u)||_L2 (Frobenius) of a P1 vector field: the norm ||.||_V.

        Args:
            u: (nv, dim) vertex values.

        Returns:
            The norm.
        """
        vol, grads = self.geometry()
        G = np.einsum("cid,cij->cjd", grads, u[self.mesh.cells])   # G[c, j, d] = d u_j / dx_d
        eps = 0.5 * (G + np.swapaxes(G, 1, 2))
        return float(np.sqrt(vol @ np.einsum("cij,cij->c", eps, eps)))

    def cell_l2_norm(self, f: np.ndarray) -> float:
        """L2 norm (Frobenius for tensors) of a DG0 field: ||.||_Q or ||.||_Y.

        Args:
            f: (nc, ...) cell values.

        Returns:
            The norm.
        """
        vol, _ = self.geometry()
        return float(np.sqrt(vol @ (f.reshape(len(vol), -1) ** 2).sum(axis=1)))


def row_positions(reference: np.ndarray, query: np.ndarray) -> np.ndarray:
    """Where each row of ``query`` is in ``reference``, rows compared as sets of integers.

    Args:
        reference: (m, k) integer rows, distinct as sets.
        query: (q, k) integer rows.

    Returns:
        (q,) indices into ``reference``.

    Raises:
        ValueError: a query row is not in ``reference``.
    """
    both = np.sort(np.vstack([reference, query]), axis=1)
    order = np.lexsort(both.T[::-1])
    s = both[order]
    new = np.r_[True, np.any(s[1:] != s[:-1], axis=1)] if len(s) else np.zeros(0, bool)
    group = np.empty(len(both), dtype=np.int64)
    group[order] = np.cumsum(new) - 1
    owner = np.full(int(new.sum()), -1, dtype=np.int64)
    owner[group[:len(reference)]] = np.arange(len(reference))
    out = owner[group[len(reference):]]
    if np.any(out < 0):
        raise ValueError(f"{int(np.sum(out < 0))} rows are not in the reference")
    return out


class LevelSampler:
    """Extracts u, sigma, kappa of a run on a level into the level's numbering on rank 0.

    Args:
        problem: the ContactProblem on the level's mesh (read from ``level.path``).
        level: the NestedLevel (its MeshLevel on rank 0).

    Raises:
        RuntimeError: on rank 0, if the run's mesh is not the level's (vertices or cells
            not found).
    """

    def __init__(self, problem, level: NestedLevel):
        disc = problem.disc
        self.level, self.comm = level, disc.comm
        msh, V = disc.mesh, disc.V
        d = msh.geometry.dim
        nv = V.dofmap.index_map.size_local
        geo = msh.geometry.dofmap.array.reshape(-1, d + 1)
        dofs = V.dofmap.list.array.reshape(-1, d + 1)
        node_of_dof = np.empty(int(dofs.max(initial=-1)) + 1, dtype=np.int64)
        node_of_dof[dofs.ravel()] = geo.ravel()
        original = np.asarray(msh.geometry.input_global_indices, dtype=np.int64)
        vidx = original[node_of_dof[:nv]]
        nc = disc.num_owned_cells
        cverts = original[geo[:nc]]
        xv = msh.geometry.x[node_of_dof[:nv], :d]
        parts = self.comm.gather((vidx, xv, cverts), root=0)
        self._index = None
        if self.comm.rank == 0:
            self._index = self._match(parts)
        self._nv, self._nc, self._d = nv, nc, d

    def _match(self, parts) -> list:
        m = self.level.mesh
        scale = max(float(np.ptp(m.x, axis=0).max()), np.finfo(float).tiny)
        out = []
        for vidx, xv, cverts in parts:
            if len(vidx) and (vidx.max() >= len(m.x) or np.abs(xv - m.x[vidx]).max()
                              > 1e-9 * scale):
                raise RuntimeError(f"the run's mesh is not level {self.level.r} of the study "
                                   "(its vertices differ)")
            try:
                cpos = row_positions(m.cells, cverts)
            except ValueError as exc:
                raise RuntimeError(f"the run's mesh is not level {self.level.r} of the study "
                                   f"(cells: {exc})") from None
            out.append((vidx, cpos))
        return out

    def sample(self, problem, history) -> dict | None:
        """Gather the current state; collective.

        Args:
            problem: the ContactProblem.
            history: the viscoplastic history (its kappa), or None.

        Returns:
            dict(u, sigma, kappa) in the level's numbering on rank 0, None elsewhere.

        Raises:
            RuntimeError: if a vertex or cell of the level was not sampled.
        """
        d, nc = self._d, self._nc
        u = problem.u.x.array.reshape(-1, d)[:self._nv]
        s = problem.sigma.x.array.reshape(-1, d, d)[:nc]
        k = history.kappa.x.array[:nc] if history else np.zeros(nc)
        parts = self.comm.gather((u, s, k), root=0)
        if self.comm.rank != 0:
            return None
        shapes = self.level.shapes()
        U, S, K = (np.full(shapes[n], np.nan) for n in ("u", "sigma", "kappa"))
        for (vidx, cpos), (uu, ss, kk) in zip(self._index, parts):
            U[vidx], S[cpos], K[cpos] = uu, ss, kk
        if np.isnan(U).any() or np.isnan(S).any():
            raise RuntimeError("sampling missed vertices or cells of the level")
        return {"u": U, "sigma": S, "kappa": K}
