"""The segment-to-segment (mortar) coupling of a contact pair, by quadrature on the surface.

With the nodal rule on Gamma3 (the weight D_i = int phi_i ds of node i) the relative
displacement of node i is taken as the phi_i-weighted mean of the jump over its facets:

    [u]_i = u_i - sum_k c_ik u_k,    c_ik = M_ik / sum_l M_il,
    M_ik = int_surface phi_i(x) psi_k(pi(x)) ds(x),

phi_i the surface's and psi_k the target's P1 shape functions, pi the closest-point
projection, or the ray cast along the pairs' fixed direction (app/model/pairgeometry.py).
The contact force f_i = D_i p_i of node i then reaches the target as sum_i c_ik f_i, which
for a uniform pressure p is p int psi_k ds: the consistent nodal forces of the target (the
contact patch test), where the node-to-segment rule (c_ik = psi_k(pi(x_i))) gives a pressure
that varies with the two meshes' offset.  The rows sum to 1, so a rigid translation gives no
jump.

M is integrated by a composite rule on each surface facet (segments cut in SUB_2D pieces with
2 Gauss points, triangles in SUB_3D^2 with the 3-point edge-midpoint rule): the integrand is
piecewise polynomial with kinks where pi(x) crosses a target vertex, so the rule is not exact
there; its error falls with the number of pieces (measured in the patch test).
"""
from __future__ import annotations

import numpy as np

from vpcontact.model.pairgeometry import project_points

SUB_2D = 16       # pieces of a surface segment
SUB_3D = 6        # a surface triangle cut into SUB_3D^2 triangles


def reference_rule(dim: int) -> tuple[np.ndarray, np.ndarray]:
    """The composite rule on the reference facet, in barycentric coordinates.

    Args:
        dim: the space dimension (2: segments, 3: triangles).

    Returns:
        (points (nq, dim) barycentric coordinates, weights (nq,) summing to 1).
    """
    if dim == 2:
        g = 0.5 / np.sqrt(3.0)
        s = ((np.arange(SUB_2D)[:, None] + 0.5 + np.array([-g, g])[None, :]) / SUB_2D).ravel()
        return np.stack([1.0 - s, s], axis=1), np.full(len(s), 1.0 / len(s))
    n, pts = SUB_3D, []
    for i in range(n):
        for j in range(n - i):
            corners = [np.array([i, j]), np.array([i + 1, j]), np.array([i, j + 1])]
            pts.append(corners)
            if i + j < n - 1:
                pts.append([np.array([i + 1, j]), np.array([i + 1, j + 1]),
                            np.array([i, j + 1])])
    mids = []
    for a, b, c in pts:               # edge midpoints of each small triangle
        for p, q in ((a, b), (b, c), (c, a)):
            mids.append((p + q) / (2.0 * n))
    st = np.array(mids)
    bary = np.stack([1.0 - st.sum(axis=1), st[:, 0], st[:, 1]], axis=1)
    return bary, np.full(len(bary), 1.0 / len(bary))


def facet_measure(coords: np.ndarray) -> np.ndarray:
    """Length (2D) or area (3D) of each facet.

    Args:
        coords: (nf, nv, d) vertex coordinates.

    Returns:
        (nf,) measures.
    """
    if coords.shape[2] == 2:
        return np.linalg.norm(coords[:, 1] - coords[:, 0], axis=1)
    return 0.5 * np.linalg.norm(np.cross(coords[:, 1] - coords[:, 0],
                                         coords[:, 2] - coords[:, 0]), axis=1)


def mortar_triplets(surface: np.ndarray, surface_nodes: np.ndarray, target: np.ndarray,
                    target_normals: np.ndarray, target_nodes: np.ndarray,
                    project=project_points) -> tuple:
    """The entries of M from some surface facets (module docstring).

    Args:
        surface: (nf, nv, d) the surface facets' vertex coordinates.
        surface_nodes: (nf, nv) their global nodes.
        target: (nt, nv, d) the target facets' vertex coordinates.
        target_normals: (nt, d) their outward unit normals.
        target_nodes: (nt, nv) their global nodes.
        project: pi, ``project_points`` (the closest point) or a ray cast along the pair's
            fixed direction (``cast_points``).

    Returns:
        (rows, cols, values): surface global node i, target global node k, the
        contribution to M_ik (duplicates to be summed); quadrature points that project
        past the target's free edge contribute nothing.
    """
    nf, nv, d = surface.shape
    if nf == 0:
        empty = np.zeros(0, np.int64)
        return empty, empty, np.zeros(0)
    bary, w = reference_rule(d)
    nq = len(w)
    points = np.einsum("qa,fad->fqd", bary, surface).reshape(-1, d)
    proj = project_points(points, target, target_normals)
    weight = (facet_measure(surface)[:, None] * w[None, :]).reshape(-1)
    inside = proj.inside
    facet = np.where(inside, proj.facet, 0)
    # phi_a(x_q) psi_b(pi(x_q)) w_q |f|: (nf nq, nv_surface, nv_target)
    vals = bary[np.tile(np.arange(nq), nf)][:, :, None] * proj.weights[:, None, :] \
        * (weight * inside)[:, None, None]
    rows = np.broadcast_to(np.repeat(surface_nodes, nq, axis=0)[:, :, None], vals.shape)
    cols = np.broadcast_to(target_nodes[facet][:, None, :], vals.shape)
    keep = vals.ravel() != 0.0
    return rows.ravel()[keep], cols.ravel()[keep], vals.ravel()[keep]
