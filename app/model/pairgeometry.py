"""The geometry of a two-body contact pair by the node-to-segment rule, in numpy alone.

Each point x of the contact surface is projected onto the target surface, a set of facets
(2D: segments, nv = 2; 3D: triangles, nv = 3): pi(x) is the closest point of the facets in
the Euclidean distance, the facet's outward unit normal n is the target's normal there, and
the signed gap is

    d(x) = (x - pi(x)) . n,

> 0 when x lies outside the target body (separation), < 0 when inside it (penetration).
The closest point of one facet is its clamped projection: on a segment the projection
parameter clipped to [0, 1], on a triangle the Voronoi-region algorithm of Ericson,
"Real-Time Collision Detection" (2005), Sec. 5.1.5.  Its P1 shape-function values at pi(x)
(barycentric coordinates, >= 0, summing to 1) are the nodal weights of the node-to-segment
rule.

Ties (facets whose distances differ by at most tol * h, h the largest edge of the target)
prefer a facet onto whose plane the point projects inside the facet (every unclamped
barycentric coordinate >= -tol), then the smallest facet index: the same choice on every
rank.  The candidate facets of a point are the k nearest facet centroids (a KD tree); the
set is sufficient when the best distance plus the tie band is below the k-th centroid's
distance minus the largest facet circumradius (no other facet can be as near); else the
candidates are all facets whose centroid lies within that best distance plus the tie band
plus the circumradius (a ball query), in chunks of bounded memory.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

# the nearest facet centroids tried first, and the (point, facet) pairs of one chunk
CANDIDATES = 8
CHUNK_PAIRS = 1 << 17


@dataclass
class Projection:
    """The projection of m points onto a target surface of nf facets with nv vertices.

    Attributes:
        facet: (m,) int, the target facet of each point's closest point (-1: outside).
        weights: (m, nv) the facet's P1 shape-function values at the closest point (>= 0,
            summing to 1).
        closest: (m, d) the closest point pi(x).
        normal: (m, d) the facet's outward unit normal (the target's).
        distance: (m,) the signed gap d = (x - pi(x)) . normal: > 0 outside the target body
            (separation), < 0 inside it (penetration).
        inside: (m,) bool, False where the closest point lies on the target's free boundary
            and the point projects past it (facet is -1 there; the other fields are those
            of the clamped closest point).
    """

    facet: np.ndarray
    weights: np.ndarray
    closest: np.ndarray
    normal: np.ndarray
    distance: np.ndarray
    inside: np.ndarray


def _checked_facets(facets) -> np.ndarray:
    """The facets as a float array (nf, nv, d) with nv = d = 2 or 3, else ValueError."""
    facets = np.asarray(facets, dtype=float)
    if facets.ndim != 3 or facets.shape[2] not in (2, 3) or facets.shape[1] != facets.shape[2]:
        raise ValueError(f"facets must have the shape (nf, d, d) with d = 2 or 3 (segments or "
                         f"triangles), not {facets.shape}")
    return facets


def facet_normals(facets, interior_points) -> np.ndarray:
    """The outward unit normal of each facet of a body's boundary.

    Args:
        facets: (nf, nv, d) the vertex coordinates of the facets (2D: segments, nv = 2;
            3D: triangles, nv = 3).
        interior_points: (nf, d) a point inside the body's cell adjacent to each facet (the
            cell's opposite vertex or its midpoint).

    Returns:
        (nf, d) unit vectors perpendicular to the facets, pointing away from the interior
        points.

    Raises:
        ValueError: on a wrong shape, or an interior point on its facet's line or plane.
    """
    facets = _checked_facets(facets)
    interior = np.asarray(interior_points, dtype=float).reshape(len(facets), facets.shape[2])
    a = facets[:, 0]
    if facets.shape[2] == 2:
        t = facets[:, 1] - a
        n = np.stack([t[:, 1], -t[:, 0]], axis=1)
    else:
        n = np.cross(facets[:, 1] - a, facets[:, 2] - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    side = np.einsum("ij,ij->i", interior - a, n)
    flat = np.abs(side) <= 1e-12 * np.linalg.norm(interior - a, axis=1)
    if flat.any():
        raise ValueError(f"the interior point of facet {int(np.argmax(flat))} lies on the "
                         f"facet's line or plane: its outward side is undefined")
    return np.where((side > 0)[:, None], -n, n)


def _on_segments(p: np.ndarray, v: np.ndarray):
    """The clamped and unclamped barycentric coordinates of p (n, d) on segments v (n, 2, d)."""
    a, ab = v[:, 0], v[:, 1] - v[:, 0]
    t = np.einsum("ij,ij->i", p - a, ab) / np.einsum("ij,ij->i", ab, ab)
    s = np.clip(t, 0.0, 1.0)
    return np.stack([1.0 - s, s], axis=1), np.stack([1.0 - t, t], axis=1)


def _dot(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The row-wise dot products of x and y (n, d)."""
    return np.einsum("ij,ij->i", x, y)


def _ratio(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    """num / den where den != 0, else 0 (the entries of a region not taken)."""
    safe = np.where(den == 0.0, 1.0, den)
    return np.where(den == 0.0, 0.0, num / safe)


def _on_triangles(p: np.ndarray, v: np.ndarray):
    """The clamped (Ericson, Sec. 5.1.5) and unclamped (the projection onto the plane)
    barycentric coordinates of p (n, 3) on triangles v (n, 3, 3)."""
    a, b, c = v[:, 0], v[:, 1], v[:, 2]
    ab, ac = b - a, c - a
    d1, d2 = _dot(ab, p - a), _dot(ac, p - a)
    d3, d4 = _dot(ab, p - b), _dot(ac, p - b)
    d5, d6 = _dot(ab, p - c), _dot(ac, p - c)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    total = va + vb + vc
    lam = np.stack([_ratio(va, total), _ratio(vb, total), _ratio(vc, total)], axis=1)
    v_ab, w_ac = _ratio(d1, d1 - d3), _ratio(d2, d2 - d6)
    w_bc = _ratio(d4 - d3, (d4 - d3) + (d5 - d6))
    zero, one = np.zeros_like(d1), np.ones_like(d1)
    # Ericson's regions in his order of tests: the first that holds is taken
    regions = [
        (d1 <= 0) & (d2 <= 0), (d3 >= 0) & (d4 <= d3),
        (vc <= 0) & (d1 >= 0) & (d3 <= 0), (d6 >= 0) & (d5 <= d6),
        (vb <= 0) & (d2 >= 0) & (d6 <= 0), (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)]
    values = [(one, zero, zero), (zero, one, zero), (1 - v_ab, v_ab, zero),
              (zero, zero, one), (1 - w_ac, zero, w_ac), (zero, 1 - w_bc, w_bc)]
    inner = np.clip(lam, 0.0, None)
    w = [inner[:, 0], inner[:, 1], inner[:, 2]]
    for region, value in zip(reversed(regions), reversed(values)):
        w = [np.where(region, vk, wk) for vk, wk in zip(value, w)]
    return np.stack(w, axis=1), lam


def _best(points: np.ndarray, facets: np.ndarray, row: np.ndarray, cand: np.ndarray,
          tie: float, tol: float):
    """The chosen facet of each point among its candidates: the pairs (row, cand), row
    ascending and every point 0..m-1 present; by distance, then a projection inside the
    facet, then the smallest index (ties within `tie`).

    Returns:
        (facet (m,), weights (m, nv), unclamped barycentrics (m, nv), distance (m,)).
    """
    m, nf = len(points), len(facets)
    p, v = points[row], facets[cand]
    w, lam = (_on_segments if facets.shape[1] == 2 else _on_triangles)(p, v)
    dist = np.linalg.norm(p - np.einsum("ik,ikd->id", w, v), axis=1)
    first = np.searchsorted(row, np.arange(m))
    dmin = np.minimum.reduceat(dist, first)
    outside = lam.min(axis=1) < -tol
    key = np.where(dist <= dmin[row] + tie, outside * nf + cand, 2 * nf)
    order = np.lexsort((key, row))
    pick = order[first]
    return cand[pick], w[pick], lam[pick], dist[pick]


def _row_chunks(counts: np.ndarray):
    """Consecutive ranges of rows whose candidate counts sum to about CHUNK_PAIRS.

    Yields:
        (start, stop) of each range (at least one row).
    """
    ends = np.cumsum(counts)
    start = 0
    while start < len(counts):
        base = ends[start - 1] if start else 0
        stop = max(start + 1, int(np.searchsorted(ends, base + CHUNK_PAIRS, side="right")))
        yield start, stop
        start = stop


def _nearest(points: np.ndarray, facets: np.ndarray, tie: float, tol: float):
    """`_best` over all facets of each point: first the k = CANDIDATES nearest centroids,
    sufficient where the best distance + tie < the k-th centroid distance - the largest
    circumradius; the other points take every facet whose centroid lies within their best
    distance + tie + that circumradius (a ball query), in chunks of bounded memory.

    Returns:
        (facet (m,), weights (m, nv), unclamped barycentrics (m, nv)).
    """
    m, nf = len(points), len(facets)
    centroids = facets.mean(axis=1)
    radius = np.linalg.norm(facets - centroids[:, None], axis=2).max()
    tree = cKDTree(centroids)
    k = min(CANDIDATES, nf)
    found = []
    for start in range(0, max(m, 1), CHUNK_PAIRS // k):
        x = points[start:start + CHUNK_PAIRS // k]
        r, cand = tree.query(x, k)
        row = np.repeat(np.arange(len(x)), k)
        found.append(_best(x, facets, row, cand.ravel(), tie, tol) + (r.reshape(-1, k),))
    facet, weights, lam, dist, r = (np.concatenate(a) for a in zip(*found))
    todo = np.flatnonzero(dist + tie >= r[:, -1] - radius) if k < nf else np.arange(0)
    reach = (dist[todo] + tie + radius) * (1 + 1e-12) + 1e-300
    counts = tree.query_ball_point(points[todo], reach, return_length=True)
    for start, stop in _row_chunks(counts):
        rows = todo[start:stop]
        near = tree.query_ball_point(points[rows], reach[start:stop])
        cand = np.fromiter(itertools.chain.from_iterable(near), dtype=np.int64,
                           count=int(counts[start:stop].sum()))
        row = np.repeat(np.arange(len(rows)), counts[start:stop])
        facet[rows], weights[rows], lam[rows], _ = _best(points[rows], facets, row, cand,
                                                         tie, tol)
    return facet, weights, lam


def _vertex_labels(vertices: np.ndarray, radius: float) -> np.ndarray:
    """One label per vertex (n, d), shared by vertices within `radius` of each other (the
    copies of one mesh vertex in several facets): the smallest index of its cluster."""
    label = np.arange(len(vertices))
    pairs = cKDTree(vertices).query_pairs(radius, output_type="ndarray")
    if not len(pairs):
        return label
    i, j = pairs[:, 0], pairs[:, 1]
    while True:
        new = label.copy()
        low = np.minimum(label[i], label[j])
        np.minimum.at(new, i, low)
        np.minimum.at(new, j, low)
        if np.array_equal(new, label):
            return label
        label = new


def free_boundary(facets, radius: float):
    """The free boundary of the target surface: its sub-facets (2D: vertices, 3D: edges)
    that belong to one facet alone, and the vertices on them.

    Args:
        facets: (nf, nv, d) the vertex coordinates of the target facets.
        radius: vertices of different facets closer than this are one mesh vertex.

    Returns:
        (opposite, vertex), both (nf, nv) bool: opposite[f, k] when the sub-facet of facet
        f opposite its vertex k is free, vertex[f, k] when the vertex k of facet f lies on
        a free sub-facet.
    """
    facets = _checked_facets(facets)
    nf, nv, d = facets.shape
    label = _vertex_labels(facets.reshape(-1, d), radius).reshape(nf, nv)
    opposite = np.stack([label[:, [(k + j) % nv for j in range(1, nv)]] for k in range(nv)],
                        axis=1)
    keys = np.sort(opposite, axis=2).reshape(nf * nv, nv - 1)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    free = counts[inverse.ravel()] == 1
    return free.reshape(nf, nv), np.isin(label, keys[free])


def _outside(facet: np.ndarray, weights: np.ndarray, lam: np.ndarray, facets: np.ndarray,
             radius: float, tol: float) -> np.ndarray:
    """Which points lie past the free boundary: the closest point on it (on a free
    sub-facet of its facet, or at a vertex on the free boundary) and the unclamped
    projection outside the facet (a barycentric coordinate < -tol)."""
    past = (lam < -tol).any(axis=1)
    if not past.any():
        return past
    opposite, vertex = free_boundary(facets, radius)
    zero = weights <= 0.0
    on_edge = (zero & opposite[facet]).any(axis=1)
    at_vertex = ((zero.sum(axis=1) == facets.shape[1] - 1)
                 & vertex[facet, np.argmax(weights, axis=1)])
    return past & (on_edge | at_vertex)


def project_points(points, facets, facet_normals, tol: float = 1e-8) -> Projection:
    """Project points onto a target surface: the closest point pi(x), its facet, P1 weights
    and normal, and the signed gap d = (x - pi(x)) . n of the node-to-segment rule.

    Args:
        points: (m, d) the points x (d = 2 or 3).
        facets: (nf, nv, d) the vertex coordinates of the target facets (2D: segments,
            nv = 2; 3D: triangles, nv = 3).
        facet_normals: (nf, d) the target body's outward unit normal on each facet.
        tol: relative tolerance: distances within tol * h tie (h the largest facet edge),
            a projection is inside a facet when its barycentric coordinates are >= -tol.

    Returns:
        The Projection: a point whose closest point lies on the target's free boundary (a
        vertex of one segment; an edge of one triangle, or a vertex on such an edge) and
        whose unclamped projection onto the chosen facet's plane lies outside that facet
        (a barycentric coordinate < -tol) is outside: inside False, facet -1, the other
        fields of its clamped closest point.  A point above a kink between two facets is
        inside.
    """
    facets = _checked_facets(facets)
    nf, nv, d = facets.shape
    points = np.asarray(points, dtype=float).reshape(-1, d)
    normals = np.asarray(facet_normals, dtype=float).reshape(nf, d)
    edges = facets - np.roll(facets, 1, axis=1)
    h = np.linalg.norm(edges, axis=2).max()
    facet, weights, lam = _nearest(points, facets, tol * h, tol)
    closest = np.einsum("ik,ikd->id", weights, facets[facet])
    normal = normals[facet]
    distance = np.einsum("ij,ij->i", points - closest, normal)
    outside = _outside(facet, weights, lam, facets, tol * h, tol)
    return Projection(facet=np.where(outside, -1, facet), weights=weights, closest=closest,
                      normal=normal, distance=distance, inside=~outside)


def _plane_basis(direction: np.ndarray) -> np.ndarray:
    """(d, d - 1) an orthonormal basis of the plane (2D: the line) orthogonal to a unit
    direction."""
    d = len(direction)
    q, _ = np.linalg.qr(np.column_stack([direction, np.eye(d)]))
    return q[:, 1:d]


def _cast_hits(p: np.ndarray, v: np.ndarray, tol: float) -> np.ndarray:
    """The barycentric coordinates (n, nv) of the projected points p (n, d - 1) in the
    projected facets v (n, nv, d - 1): NaN rows where a projected facet is degenerate
    (parallel to the direction) or the point lies outside it (a coordinate < -tol)."""
    if v.shape[1] == 2:
        a, b = v[:, 0, 0], v[:, 1, 0]
        span = b - a
        flat = np.abs(span) <= tol * np.abs(v).max(initial=1.0)
        s = (p[:, 0] - a) / np.where(flat, 1.0, span)
        lam = np.stack([1.0 - s, s], axis=1)
    else:
        e1, e2, r = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0], p - v[:, 0]
        det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        flat = np.abs(det) <= tol * np.einsum("ij,ij->i", e1, e1)
        safe = np.where(flat, 1.0, det)
        s = (r[:, 0] * e2[:, 1] - r[:, 1] * e2[:, 0]) / safe
        t = (e1[:, 0] * r[:, 1] - e1[:, 1] * r[:, 0]) / safe
        lam = np.stack([1.0 - s - t, s, t], axis=1)
    bad = flat | (lam < -tol).any(axis=1)
    return np.where(bad[:, None], np.nan, lam)


def cast_points(points, facets, facet_normals, direction, tol: float = 1e-8) -> Projection:
    """Project points onto a target surface along one fixed direction (a ray cast): the
    point pi(x) = x + d(x) e of the target facets on the line through x along the unit
    direction e, where the line enters the target (its outward normal n has n . e < 0);
    of several such points the one of the smallest |d(x)| (ties: the smallest facet index).

    The gap of linear contact theory (Johnson, Contact Mechanics, ch. 4): measured along
    one approach direction, d(x) > 0 where x lies outside the target (separation).  The
    facets and points are projected onto the plane orthogonal to e, where the facet
    containing x's image is found (a KD tree on the projected centroids); an affine map
    keeps the barycentric coordinates, which are pi(x)'s P1 weights.

    Args:
        points: (m, d) the points x (d = 2 or 3).
        facets: (nf, nv, d) the target facets' vertex coordinates.
        facet_normals: (nf, d) the target body's outward unit normal on each facet.
        direction: (d,) the approach direction e (from the points toward the target).
        tol: relative tolerance of a projected image inside a facet (barycentrics >= -tol).

    Returns:
        The Projection (``project_points``'s fields; ``normal`` the facet's outward normal,
        ``distance`` d(x) along e); a point whose line meets no facet entering the target
        is outside (inside False, facet -1, weights 0, closest x, normal 0, distance 0).
    """
    facets = _checked_facets(facets)
    nf, nv, d = facets.shape
    points = np.asarray(points, dtype=float).reshape(-1, d)
    normals = np.asarray(facet_normals, dtype=float).reshape(nf, d)
    e = np.asarray(direction, dtype=float)
    e = e / np.linalg.norm(e)
    basis = _plane_basis(e)
    fp, pp = facets @ basis, points @ basis
    centroids = fp.mean(axis=1)
    radius = np.linalg.norm(fp - centroids[:, None], axis=2).max(initial=0.0)
    entering = normals @ e < 0.0
    m = len(points)
    facet, dist = np.full(m, -1), np.zeros(m)
    weights = np.zeros((m, nv))
    if m == 0 or nf == 0:
        return Projection(facet, weights, points.copy(), np.zeros((m, d)), dist,
                          np.zeros(m, bool))
    tree = cKDTree(centroids)
    near = tree.query_ball_point(pp, radius * (1 + 1e-9) + tol * max(radius, 1e-300))
    counts = np.fromiter((len(c) for c in near), dtype=np.int64, count=m)
    row = np.repeat(np.arange(m), counts)
    cand = np.fromiter(itertools.chain.from_iterable(near), dtype=np.int64,
                       count=int(counts.sum()))
    lam = _cast_hits(pp[row], fp[cand], tol)
    ok = ~np.isnan(lam[:, 0]) & entering[cand]
    row, cand, lam = row[ok], cand[ok], np.clip(lam[ok], 0.0, None)
    lam /= lam.sum(axis=1, keepdims=True)
    hit = np.einsum("ik,ikd->id", lam, facets[cand])
    t = np.einsum("ij,j->i", hit - points[row], e)
    order = np.lexsort((cand, np.abs(t), row))
    first = order[np.unique(row[order], return_index=True)[1]]
    at = row[first]
    facet[at], weights[at], dist[at] = cand[first], lam[first], t[first]
    inside = facet >= 0
    closest = points.copy()
    closest[at] = hit[first]
    normal = np.where(inside[:, None], normals[np.maximum(facet, 0)], 0.0)
    return Projection(facet=facet, weights=weights, closest=closest, normal=normal,
                      distance=dist, inside=inside)
