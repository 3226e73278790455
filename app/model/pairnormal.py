"""The normal of a two-body contact pair and its coupling point, in numpy alone: the average
of the two bodies' normals (Code_Aster's DEFI_CONTACT NORMALE='MAIT_ESCL') and the point of
the target met along it.

A point x of the contact surface, with the surface's outward unit normal n_s(x), is coupled
to the target at the point where the line x + s nu meets the target facets (a ray cast, not
the closest point), with

    nu = (n_s(x) - n_t(pi)) / |n_s(x) - n_t(pi)|,      pi = x + d nu on the target,     (1)

n_t(pi) the target's outward unit normal at pi, interpolated from its vertex normals (2) with
the P1 weights of pi on its facet and normalised, and d = (pi - x) . nu the initial distance
along nu (> 0: separation).  nu and pi depend on each other: (1) is solved by a fixed point
from the closest point of x (pairgeometry.project_points): n_t at the current pi, nu from
(1), the next pi by the ray cast along nu, until nu moves by less than NORMAL_TOL (a
contraction: moving pi by e turns n_t by e / R_t, nu by e / (2 R_t) and pi by d e / (2 R_t),
R_t the target's radius of curvature).  The vertex normal of either body is

    n_k = sum_f |f| n_f / |sum_f |f| n_f|    over the body's facets f of the group at vertex k,  (2)

the area-weighted normal of app/model/frames.py (int_f phi_k ds = |f| / nv).

Why not the target's normal at the closest point: two mirror-image bodies pressed together
(u_x(x, y) = u_x(x, -y), u_y(x, y) = -u_y(x, -y)) have a vertical jump [u]; the target's
normal at the closest point is tilted by about x / R, and the closest point of x on the lower
body is not its mirror image (an offset of order x^3 / R^2), so a pure normal approach showed a
tangential jump and, with Coulomb friction, friction stresses of 0.2 p_n.  With (1) the
normals of mirror-image points are mirror images, nu is vertical and the ray meets the
mirror point: no tangential part.  Under a flat surface on a flat target (n_s = -n_t) nu is the
target's inward normal, the closest point's direction, as before.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from vpcontact.model.pairgeometry import (
    CANDIDATES,
    Projection,
    facet_measure,
    plane_coordinates,
    project_points,
    row_chunks,
)

NORMAL_TOL = 1e-14        # the fixed point of (1) stops when nu moves by less than this
NORMAL_ITERATIONS = 20    # at most this many ray casts
REACH = 4.0               # the ray is sought within REACH times the closest distance (+ h)
ROUNDOFF = 1e-12          # a normal's component below this is round-off (pair_normal)


def vertex_normals(facets: np.ndarray, normals: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """The unit normal (2) of a body's facets at each facet's vertices.

    Args:
        facets: (nf, nv, d) the vertex coordinates.
        normals: (nf, d) the facets' outward unit normals.
        nodes: (nf, nv) the vertices' global nodes (a vertex shared by facets: one node).

    Returns:
        (nf, nv, d) the vertex normal at each vertex of each facet.
    """
    nf, nv, d = np.shape(facets)
    ids, inverse = np.unique(np.asarray(nodes).ravel(), return_inverse=True)
    total = np.zeros((len(ids), d))
    np.add.at(total, inverse, np.repeat(facet_measure(facets)[:, None] * normals, nv, axis=0))
    return unit(total)[inverse].reshape(nf, nv, d)


def unit(v: np.ndarray) -> np.ndarray:
    """Each row of v divided by its length.

    Args:
        v: (n, d) vectors.

    Returns:
        (n, d) unit vectors (a zero row stays zero).
    """
    size = np.linalg.norm(v, axis=1)
    return v / np.where(size > 0.0, size, 1.0)[:, None]


def normal_at(weights: np.ndarray, vertex: np.ndarray) -> np.ndarray:
    """The interpolated unit normal sum_k w_k n_k / |...| of points on facets.

    Args:
        weights: (m, nv) the points' P1 weights on their facets.
        vertex: (m, nv, d) the vertex normals of those facets.

    Returns:
        (m, d).
    """
    return unit(np.einsum("ik,ikd->id", weights, vertex))


def pair_normal(surface: np.ndarray, target: np.ndarray) -> np.ndarray:
    """nu of (1): (n_s - n_t) / |n_s - n_t|; -n_t where n_s = n_t (the surfaces do not face
    each other: the caller refuses).  Components below ROUNDOFF are the round-off of the
    coordinates (a flat side at y = 1 has vertices at y = 1 + 2e-16): they are set to 0, so
    that a normal along an axis is that axis exactly (as the frames of app/model/frames.py
    take it; a 1e-15 component in the pairs' change of variables made K_x of a body held
    only by contact pivot otherwise).

    Args:
        surface: (m, d) n_s.
        target: (m, d) n_t.

    Returns:
        (m, d) unit normals.
    """
    diff = surface - target
    bad = np.linalg.norm(diff, axis=1) <= 1e-12
    nu = unit(np.where(bad[:, None], -target, diff))
    return unit(np.where(np.abs(nu) < ROUNDOFF, 0.0, nu))


def _hits(points, directions, facets, normals, row, cand, tie, tol):
    """Where each line x + s nu (rows ascending, every point present) meets its candidate
    facets that face it (nu . n_f < 0): the one met inside (barycentric coordinates >= -tol)
    with the smallest |s|, ties within `tie` to the smallest facet index; a line that meets
    none inside takes the facet it misses by the least (the smallest negative coordinate),
    with its clamped coordinates (so that the fixed point can walk back inside).

    Returns:
        (facet (m,), -1 where no candidate faces the line; weights (m, nv); s (m,);
        inside (m,)).
    """
    m, nf = len(points), len(facets)
    p, nu, v, n = points[row], directions[row], facets[cand], normals[cand]
    den = np.einsum("ij,ij->i", nu, n)
    facing = den < 0.0
    s = np.einsum("ij,ij->i", v[:, 0] - p, n) / np.where(facing, den, -1.0)
    lam = plane_coordinates(p + s[:, None] * nu, v)
    miss = np.maximum(-lam.min(axis=1), 0.0)
    ok = facing & (miss <= tol)
    best = np.full(m, np.inf)
    np.minimum.at(best, row[ok], np.abs(s[ok]))
    least = np.full(m, np.inf)
    np.minimum.at(least, row[facing], miss[facing])
    inside = np.isfinite(best)
    take = np.where(inside[row], ok & (np.abs(s) <= best[row] + tie),
                    facing & (miss <= least[row] * (1 + 1e-12)))
    order = np.lexsort((np.where(take, cand, nf), row))
    first = order[np.searchsorted(row[order], np.arange(m))]
    found = take[first]
    w = np.clip(lam[first], 0.0, None)
    w /= np.where(found, w.sum(axis=1), 1.0)[:, None]
    return (np.where(found, cand[first], -1), w, np.where(found, s[first], 0.0),
            inside & found)


def _index(facets: np.ndarray) -> tuple:
    """The search structure of the target facets: (KD tree of the centroids, the largest
    facet edge h, the largest facet radius)."""
    centroids = facets.mean(axis=1)
    radius = np.linalg.norm(facets - centroids[:, None], axis=2).max()
    h = np.linalg.norm(facets - np.roll(facets, 1, axis=1), axis=2).max()
    return cKDTree(centroids), h, radius


def _cast(points, directions, facets, normals, guess, reach, index, tol):
    """_hits of each point among the CANDIDATES facets whose centroids are nearest its guess
    of pi; where none of them is met inside (an end of the target, a guess far off), among
    every facet whose centroid lies within `reach` (m,) of x plus the largest facet radius,
    in chunks of bounded memory."""
    tree, h, radius = index
    m, nf = len(points), len(facets)
    k = min(CANDIDATES, nf)
    cand = tree.query(guess, k)[1].reshape(m, k)
    facet, weights, s, inside = _hits(points, directions, facets, normals,
                                      np.repeat(np.arange(m), k), cand.ravel(), tol * h, tol)
    todo = np.flatnonzero(~inside)
    if not len(todo) or k == nf:
        return facet, weights, s, inside
    reach = reach[todo] + radius + tol * h
    counts = tree.query_ball_point(points[todo], reach, return_length=True)
    for start, stop in row_chunks(np.maximum(counts, 1)):
        rows = todo[start:stop]
        near = tree.query_ball_point(points[rows], reach[start:stop])
        row = np.repeat(np.arange(len(rows)), [max(len(c), 1) for c in near])
        found = np.concatenate([c if len(c) else [0] for c in near]).astype(np.int64)
        facet[rows], weights[rows], s[rows], inside[rows] = _hits(
            points[rows], directions[rows], facets, normals, row, found, tol * h, tol)
    return facet, weights, s, inside


def pair_projection(points, surface_normals, facets, facet_normals, vertex: np.ndarray,
                    tol: float = 1e-8) -> tuple[Projection, np.ndarray]:
    """The coupling point pi and the pair's normal nu (1) of each surface point, by the
    fixed point of the module docstring (at most NORMAL_ITERATIONS ray casts, each within
    REACH times the closest distance).

    Args:
        points: (m, d) the surface points x.
        surface_normals: (m, d) n_s(x), the surface's outward unit normals there.
        facets: (nf, nv, d) the target facets.
        facet_normals: (nf, d) their outward unit normals.
        vertex: (nf, nv, d) the target's vertex normals (vertex_normals).
        tol: relative tolerance (project_points': inside a facet when every barycentric
            coordinate >= -tol; distances within tol h tie, h the largest facet edge).

    Returns:
        (the Projection along nu: closest is pi = x + d nu, weights its P1 weights, normal
        the target facet's, distance (x - pi) . n; inside False, facet -1, where the closest
        point or the ray lies past the target's free boundary), nu (m, d).
    """
    facets = np.asarray(facets, float)
    points = np.asarray(points, float).reshape(-1, facets.shape[2])
    near = project_points(points, facets, facet_normals, tol)
    facet, weights = np.maximum(near.facet, 0), near.weights
    reach = REACH * np.linalg.norm(points - near.closest, axis=1)
    nu = pair_normal(surface_normals, normal_at(weights, vertex[facet]))
    index, guess = _index(facets), near.closest.copy()
    facet, weights = np.full(len(points), -1), np.zeros_like(weights)
    s, inside = np.zeros(len(points)), np.zeros(len(points), bool)
    active = np.arange(len(points))              # the points whose nu still moves
    for it in range(NORMAL_ITERATIONS + 1):
        at = active
        facet[at], weights[at], s[at], inside[at] = _cast(
            points[at], nu[at], facets, facet_normals, guess[at], reach[at], index, tol)
        if it == NORMAL_ITERATIONS:              # the last nu's own cast
            break
        found = facet[at] >= 0
        guess[at[found]] = points[at[found]] + s[at[found], None] * nu[at[found]]
        new = pair_normal(surface_normals[at], normal_at(weights[at],
                                                         vertex[np.maximum(facet[at], 0)]))
        new = np.where(found[:, None], new, nu[at])
        moving = np.abs(new - nu[at]).max(axis=1) > NORMAL_TOL
        nu[at[moving]] = new[moving]
        active = at[moving]
        if not len(active):
            break
    inside &= near.inside
    closest = points + s[:, None] * nu
    normal = facet_normals[np.maximum(facet, 0)]
    return Projection(facet=np.where(inside, facet, -1), weights=weights, closest=closest,
                      normal=normal, distance=np.einsum("ij,ij->i", points - closest, normal),
                      inside=inside), nu
