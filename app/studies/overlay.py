"""The Error of the paper's Table 1 of a run on any triangle mesh of the rectangle against
the convergence study's reference (a structured grid), integrated exactly on the overlay
of the two meshes.

On a cell P of the run's mesh and a cell R of the reference grid, eps(u), sigma and kappa
of both runs are constants (P1 displacement, DG0 stress and kappa), so on P n R their
difference is a constant and

    ||f - f^ref||^2 = sum over the pairs (P, R) of |P n R| |f_P - f^ref_R|^2

exactly (Frobenius norms for tensors), |P n R| the area of the convex polygon P n R
(P clipped by R's three half-planes, Sutherland-Hodgman).  For a mesh nested in the grid
this is the Error of ``convergence.run_error`` (exact prolongation); the test checks the
two against each other on a uniform level.  The max over n runs over the run's time
points, which must all be reference time points (else there is no Error: ``None``).
"""
from __future__ import annotations

import numpy as np

from vpcontact.observers import Observer
from vpcontact.studies.grid import Grid, cell_strains, cell_vertices


class MeshSamples(Observer):
    """Samples, per owned cell, eps(u_n) (e11, e22, e12), sigma_n and kappa_n at t_0 and
    after every step, with the cells' vertices; all on rank 0 (an observer of the run).
    At the first time point that is not one of ``ref_times`` it stops and drops what it
    had (``off``): there will be no Error, and the samples would only take memory.

    Args:
        ref_times: the reference's time points (none: no samples).
    """

    def __init__(self, ref_times):
        self.ref_times = np.asarray(ref_times, dtype=float)
        self.cells, self.snaps, self.times, self.off = None, [], [], False
        self._dofs = None

    def start(self, sim) -> None:
        """The cells' vertices and P1 dofs, and the first sample (collective).

        Args:
            sim: the Simulation, set up.
        """
        p = sim.problem
        nc, V = p.disc.num_owned_cells, p.disc.V
        self._dofs = np.array([V.dofmap.cell_dofs(c) for c in range(nc)], dtype=np.int64)
        xdof = V.tabulate_dof_coordinates()[:, :2]
        self._x = xdof[self._dofs]                                  # (nc, 3, 2)
        parts = sim.comm.gather(self._x, root=0)
        if sim.comm.rank == 0:
            self.cells = np.concatenate(parts)
        self._sample(sim)

    def step(self, sim, record: dict) -> None:
        """Sample after step n (collective).

        Args:
            sim: the Simulation after step n was accepted.
            record: the step's record (unused).
        """
        self._sample(sim)

    def _sample(self, sim) -> None:
        t = float(sim.t)
        if self.off or not self.ref_times.size or \
                np.abs(self.ref_times - t).min() > 1e-12 * max(1.0, abs(t)):
            self.off, self.snaps, self.times = True, [], []     # the same on every rank
            return
        p, nc = sim.problem, sim.problem.disc.num_owned_cells
        u = p.u.x.array.reshape(-1, 2)[self._dofs]                  # (nc, 3, 2)
        eps = triangle_strains(self._x, u)
        s = p.sigma.x.array.reshape(-1, 2, 2)[:nc]
        k = sim.history.kappa.x.array[:nc] if sim.history else np.zeros(nc)
        parts = sim.comm.gather((eps, s, k), root=0)
        if sim.comm.rank == 0:
            self.snaps.append({key: np.concatenate([q[i] for q in parts])
                               for i, key in enumerate(("eps", "sigma", "kappa"))})
            self.times.append(t)


def triangle_strains(x: np.ndarray, u: np.ndarray) -> np.ndarray:
    """eps(u) of a P1 field on triangles: (e11, e22, e12) per triangle.

    Args:
        x: (m, 3, 2) the vertices.
        u: (m, 3, 2) the displacement at them.

    Returns:
        (m, 3).
    """
    e1, e2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    J = np.stack([e1, e2], axis=1)                        # rows: edge vectors
    du = np.stack([u[:, 1] - u[:, 0], u[:, 2] - u[:, 0]], axis=1)
    G = np.linalg.solve(J, du)                            # G[a, c] = d u_c / d x_a
    return np.stack([G[:, 0, 0], G[:, 1, 1], 0.5 * (G[:, 1, 0] + G[:, 0, 1])], axis=1)


def clip_area(tri: np.ndarray, clip: np.ndarray) -> float:
    """The area of the intersection of two triangles (Sutherland-Hodgman).

    Args:
        tri: (3, 2) a triangle.
        clip: (3, 2) a triangle (any orientation).

    Returns:
        The area of tri n clip (0 if they do not overlap).
    """
    poly = [tuple(p) for p in tri]
    c = clip if _signed_area(clip) > 0 else clip[::-1]
    for k in range(3):
        a, b = c[k], c[(k + 1) % 3]
        side = [(b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) for p in poly]
        out = []
        for i, p in enumerate(poly):
            q, sp, sq = poly[(i + 1) % len(poly)], side[i], side[(i + 1) % len(poly)]
            if sp >= 0:
                out.append(p)
            if (sp >= 0) != (sq >= 0):
                w = sp / (sp - sq)
                out.append((p[0] + w * (q[0] - p[0]), p[1] + w * (q[1] - p[1])))
        poly = out
        if len(poly) < 3:
            return 0.0
    return abs(_signed_area(np.array(poly)))


def _signed_area(p: np.ndarray) -> float:
    """The signed area of a polygon (positive counter-clockwise)."""
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def overlay(cells: np.ndarray, grid: Grid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pairs (run cell, grid cell) that overlap, with the areas of their intersections.

    Args:
        cells: (m, 3, 2) the run's triangles.
        grid: the reference grid.

    Returns:
        (run cell index, flat grid cell index into (n, n, 2), area), each (pairs,).
    """
    verts = cell_vertices(grid)                                     # (n, n, 2, 3, 2)
    P, R, A = [], [], []
    for c, tri in enumerate(cells):
        lo, hi = tri.min(axis=0), tri.max(axis=0)
        i0, i1 = _span(lo[0], hi[0], grid.hx, grid.n)
        j0, j1 = _span(lo[1], hi[1], grid.hy, grid.n)
        for i in range(i0, i1):
            for j in range(j0, j1):
                for t in range(2):
                    a = clip_area(tri, verts[i, j, t])
                    if a > 0:
                        P.append(c)
                        R.append((i * grid.n + j) * 2 + t)
                        A.append(a)
    return np.array(P), np.array(R), np.array(A)


def _span(lo: float, hi: float, h: float, n: int) -> tuple[int, int]:
    """The grid squares [i0, i1) a bounding interval [lo, hi] meets."""
    return max(int(np.floor(lo / h + 1e-9)), 0), min(int(np.ceil(hi / h - 1e-9)), n)


def overlay_error(samples: MeshSamples, ref, grid: Grid) -> dict | None:
    """The Error of a run against the reference on the overlay (module docstring).

    Args:
        samples: the run's MeshSamples (rank 0).
        ref: the reference's RunRecord (times, snaps on ``grid``).
        grid: the reference grid.

    Returns:
        {"error", "e_sigma", "e_u", "e_kappa", "n_max", "t_max"}, or None if a time point
        of the run is not a reference time point.
    """
    index = []
    for t in samples.times:
        m = int(np.argmin(np.abs(ref.times - t)))
        if abs(ref.times[m] - t) > 1e-12 * max(1.0, abs(t)):
            return None
        index.append(m)
    P, R, A = overlay(samples.cells, grid)
    best = None
    for n, (snap, m) in enumerate(zip(samples.snaps, index)):
        b = ref.snaps[m]
        e_u = _pair_norm(snap["eps"][P], cell_strains(b["u"], grid).reshape(-1, 3)[R], A,
                         weights=np.array([1.0, 1.0, 2.0]))
        e_s = _pair_norm(snap["sigma"][P].reshape(-1, 4), b["sigma"].reshape(-1, 4)[R], A)
        e_k = _pair_norm(snap["kappa"][P].reshape(-1, 1), b["kappa"].reshape(-1, 1)[R], A)
        total = e_s + e_u + e_k
        if best is None or total > best["error"]:
            best = {"error": total, "e_sigma": e_s, "e_u": e_u, "e_kappa": e_k, "n_max": n,
                    "t_max": samples.times[n]}
    return best


def _pair_norm(a: np.ndarray, b: np.ndarray, area: np.ndarray, weights=None) -> float:
    """sqrt(sum over the pairs of area |a - b|^2), the components weighted."""
    d2 = (a - b) ** 2
    if weights is not None:
        d2 = d2 * weights
    return float(np.sqrt(np.sum(area * d2.sum(axis=1))))
