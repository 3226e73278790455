"""Fields of a structured-mesh run on its canonical grid, exact prolongation between nested
meshes, and the error norms of the paper's Table 1 computed on the fine mesh.

A structured mesh (``mesh.kind: structured``) has vertices (I, J) at (I hx, J hy) and, per
square (i, j), two triangles t = 0, 1: with diagonal "right" t = 0 is the triangle below the
diagonal (x0,y0)-(x1,y1); with "left" t = 0 is the one below (x0,y1)-(x1,y0).  Fields are
stored as arrays indexed by these integers, independent of the MPI partition:
u (n+1, n+1, 2), sigma (n, n, 2, 2, 2), kappa (n, n, 2).

Prolongation from n_c to n_f = r n_c (same diagonal: nested meshes) is exact: a coarse P1
function is a fine P1 function, so it is evaluated at the fine vertices with the coarse
triangle's barycentric formula; a coarse DG0 function takes, on each fine cell, the value of
the coarse cell that contains it (located by the fine cell's centroid).  dolfinx 0.5.2 cannot
interpolate between meshes; this uses only the grid geometry.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Grid:
    """A structured n x n grid on (0, L1) x (0, L2) with a diagonal direction.

    Cells are indexed (i, j, t): square (i, j) and its triangle t (0 below the diagonal).

    Attributes:
        n: squares per side.
        L1, L2: the sides.
        diagonal: "right" or "left" (meshes/rectangle.py).
    """

    n: int
    L1: float
    L2: float
    diagonal: str

    @property
    def hx(self) -> float:
        """The squares' width L1 / n."""
        return self.L1 / self.n

    @property
    def hy(self) -> float:
        """The squares' height L2 / n."""
        return self.L2 / self.n

    def vertex_index(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Grid indices of vertices.

        Args:
            x: (m, >= 2) vertex coordinates.

        Returns:
            (I, J), each (m,).

        Raises:
            ValueError: if a vertex is not on the grid.
        """
        I = np.rint(x[:, 0] / self.hx).astype(int)
        J = np.rint(x[:, 1] / self.hy).astype(int)
        if np.abs(x[:, 0] - I * self.hx).max(initial=0) > 1e-6 * self.hx or \
           np.abs(x[:, 1] - J * self.hy).max(initial=0) > 1e-6 * self.hy:
            raise ValueError("mesh vertices are not on the structured grid")
        return I, J

    def cell_index(self, c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Grid indices of cells.

        Args:
            c: (m, >= 2) centroids (or other interior points) of the cells.

        Returns:
            (i, j, t), each (m,).
        """
        fx, fy = c[:, 0] / self.hx, c[:, 1] / self.hy
        i = np.clip(np.floor(fx).astype(int), 0, self.n - 1)
        j = np.clip(np.floor(fy).astype(int), 0, self.n - 1)
        a, b = fx - i, fy - j
        t = (b > a) if self.diagonal == "right" else (a + b > 1.0)
        return i, j, t.astype(int)


# ----------------------------------------------------------------------------- prolongation
def prolong_p1(u: np.ndarray, coarse: Grid, fine: Grid) -> np.ndarray:
    """Prolong a P1 field to the vertices of a nested finer grid (exact).

    Args:
        u: coarse vertex values (n_c+1, n_c+1, ...).
        coarse: the coarse grid.
        fine: the fine grid (n_f a multiple of n_c).

    Returns:
        Fine vertex values (n_f+1, n_f+1, ...).

    Raises:
        ValueError: if the grids are not nested.
    """
    r = _ratio(coarse, fine)
    I = np.arange(fine.n + 1)
    i = np.minimum(I // r, coarse.n - 1)
    a = I / r - i                                   # local coordinate in [0, 1]
    ii, jj = np.meshgrid(i, i, indexing="ij")
    A, B = np.meshgrid(a, a, indexing="ij")
    u00, u10 = u[ii, jj], u[ii + 1, jj]
    u01, u11 = u[ii, jj + 1], u[ii + 1, jj + 1]
    A = A.reshape(A.shape + (1,) * (u.ndim - 2))
    B = B.reshape(B.shape + (1,) * (u.ndim - 2))
    if coarse.diagonal == "right":
        lower = u00 + A * (u10 - u00) + B * (u11 - u10)     # (0,0),(1,0),(1,1)
        upper = u00 + A * (u11 - u01) + B * (u01 - u00)     # (0,0),(1,1),(0,1)
        in_lower = B <= A
    else:
        lower = u00 + A * (u10 - u00) + B * (u01 - u00)     # (0,0),(1,0),(0,1)
        upper = u11 + (1 - A) * (u01 - u11) + (1 - B) * (u10 - u11)  # (1,0),(1,1),(0,1)
        in_lower = A + B <= 1.0
    return np.where(in_lower, lower, upper)


def prolong_dg0(f: np.ndarray, coarse: Grid, fine: Grid) -> np.ndarray:
    """Prolong a DG0 field to the cells of a nested finer grid (exact).

    Args:
        f: coarse cell values (n_c, n_c, 2, ...).
        coarse: the coarse grid.
        fine: the fine grid (n_f a multiple of n_c).

    Returns:
        Fine cell values (n_f, n_f, 2, ...).

    Raises:
        ValueError: if the grids are not nested.
    """
    _ratio(coarse, fine)
    c = cell_centroids(fine).reshape(-1, 2)
    i, j, t = coarse.cell_index(c)
    return f[i, j, t].reshape((fine.n, fine.n, 2) + f.shape[3:])


def cell_centroids(grid: Grid) -> np.ndarray:
    """The centroids of a grid's cells.

    Args:
        grid: the grid.

    Returns:
        (n, n, 2, 2): the centroid (x, y) of cell (i, j, t).
    """
    i, j = np.meshgrid(np.arange(grid.n), np.arange(grid.n), indexing="ij")
    if grid.diagonal == "right":
        local = np.array([[2 / 3, 1 / 3], [1 / 3, 2 / 3]])   # t = 0 below the diagonal
    else:
        local = np.array([[1 / 3, 1 / 3], [2 / 3, 2 / 3]])
    out = np.empty((grid.n, grid.n, 2, 2))
    for t in range(2):
        out[:, :, t, 0] = (i + local[t, 0]) * grid.hx
        out[:, :, t, 1] = (j + local[t, 1]) * grid.hy
    return out


def _ratio(coarse: Grid, fine: Grid) -> int:
    if (coarse.L1, coarse.L2, coarse.diagonal) != (fine.L1, fine.L2, fine.diagonal) \
            or fine.n % coarse.n:
        raise ValueError(f"meshes are not nested: n = {coarse.n} ({coarse.diagonal}) and "
                         f"n = {fine.n} ({fine.diagonal}) on {coarse.L1} x {coarse.L2}")
    return fine.n // coarse.n


# ----------------------------------------------------------------------------- norms
def cell_strains(d: np.ndarray, grid: Grid) -> np.ndarray:
    """eps(d) of a P1 vector field on every cell: (e11, e22, e12).

    Args:
        d: vertex values (n+1, n+1, 2).
        grid: the grid.

    Returns:
        (n, n, 2, 3): the constant strain of cell (i, j, t).
    """
    hx, hy = grid.hx, grid.hy
    d00, d10, d01, d11 = d[:-1, :-1], d[1:, :-1], d[:-1, 1:], d[1:, 1:]
    if grid.diagonal == "right":
        grads = [((d10 - d00) / hx, (d11 - d10) / hy),       # t = 0: (0,0),(1,0),(1,1)
                 ((d11 - d01) / hx, (d01 - d00) / hy)]       # t = 1: (0,0),(1,1),(0,1)
    else:
        grads = [((d10 - d00) / hx, (d01 - d00) / hy),       # t = 0: (0,0),(1,0),(0,1)
                 ((d11 - d01) / hx, (d11 - d10) / hy)]       # t = 1: (1,0),(1,1),(0,1)
    out = np.empty(d00.shape[:2] + (2, 3))
    for t, (gx, gy) in enumerate(grads):   # gx[..., c] = d d_c / dx
        out[:, :, t] = np.stack([gx[..., 0], gy[..., 1], 0.5 * (gy[..., 0] + gx[..., 1])],
                                axis=-1)
    return out


def cell_vertices(grid: Grid) -> np.ndarray:
    """The vertices of every cell, in the order of ``cell_strains``'s comments.

    Args:
        grid: the grid.

    Returns:
        (n, n, 2, 3, 2): the (x, y) of the three vertices of cell (i, j, t).
    """
    local = ([[(0, 0), (1, 0), (1, 1)], [(0, 0), (1, 1), (0, 1)]] if grid.diagonal == "right"
             else [[(0, 0), (1, 0), (0, 1)], [(1, 0), (1, 1), (0, 1)]])
    i, j = np.meshgrid(np.arange(grid.n), np.arange(grid.n), indexing="ij")
    out = np.empty((grid.n, grid.n, 2, 3, 2))
    for t in range(2):
        for v, (a, b) in enumerate(local[t]):
            out[:, :, t, v, 0] = (i + a) * grid.hx
            out[:, :, t, v, 1] = (j + b) * grid.hy
    return out


def strain_norm(d: np.ndarray, grid: Grid) -> float:
    """||eps(d)||_L2 (Frobenius), the norm ||.||_V of a P1 vector field.

    Args:
        d: vertex values (n+1, n+1, 2).
        grid: the grid.

    Returns:
        The norm.
    """
    e = cell_strains(d, grid)
    total = np.sum(e[..., 0] ** 2 + e[..., 1] ** 2 + 2 * e[..., 2] ** 2)
    return float(np.sqrt(total * grid.hx * grid.hy / 2))


def cell_l2_norm(f: np.ndarray, grid: Grid) -> float:
    """L2 norm (Frobenius for tensors) of a DG0 field: ||.||_Q or ||.||_Y.

    Args:
        f: cell values (n, n, 2, ...).
        grid: the grid.

    Returns:
        The norm.
    """
    return float(np.sqrt(np.sum(f**2) * grid.hx * grid.hy / 2))


# ----------------------------------------------------------------------------- extraction
class GridSampler:
    """Extracts u, sigma, kappa of a dolfinx run into grid arrays on rank 0.

    Args:
        problem: the ContactProblem on a structured rectangle mesh.
        grid: its grid.
    """

    def __init__(self, problem, grid: Grid):
        disc = problem.disc
        self.grid, self.comm = grid, disc.comm
        V = disc.V
        nv = V.dofmap.index_map.size_local
        self._vI, self._vJ = grid.vertex_index(V.tabulate_dof_coordinates()[:nv])
        self._nv = nv
        msh = disc.mesh
        nc = disc.num_owned_cells
        x = msh.geometry.x
        dm = msh.geometry.dofmap
        cent = np.array([x[dm.links(c)].mean(axis=0) for c in range(nc)]).reshape(-1, 3)
        self._ci, self._cj, self._ct = grid.cell_index(cent)
        self._nc = nc

    def sample(self, problem, history) -> dict | None:
        """Gather the current state; collective.

        Args:
            problem: the ContactProblem.
            history: the viscoplastic history (its kappa), or None.

        Returns:
            dict(u, sigma, kappa) of grid arrays on rank 0, None elsewhere.

        Raises:
            RuntimeError: if a vertex or cell of the grid was not found.
        """
        g = self.grid
        u = problem.u.x.array.reshape(-1, 2)[:self._nv]
        s = problem.sigma.x.array.reshape(-1, 2, 2)[:self._nc]
        k = history.kappa.x.array[:self._nc] if history else np.zeros(self._nc)
        parts = self.comm.gather((self._vI, self._vJ, u, self._ci, self._cj, self._ct, s, k),
                                 root=0)
        if self.comm.rank != 0:
            return None
        U = np.full((g.n + 1, g.n + 1, 2), np.nan)
        S = np.full((g.n, g.n, 2, 2, 2), np.nan)
        K = np.full((g.n, g.n, 2), np.nan)
        for vI, vJ, uu, ci, cj, ct, ss, kk in parts:
            U[vI, vJ] = uu
            S[ci, cj, ct] = ss
            K[ci, cj, ct] = kk
        if np.isnan(U).any() or np.isnan(S).any():
            raise RuntimeError("grid sampling missed vertices or cells")
        return {"u": U, "sigma": S, "kappa": K}
