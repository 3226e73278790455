"""The geometry of a contact pair (app/model/pairgeometry.py), numpy only: the closest point,
P1 weights, normal and signed gap d = (x - pi(x)) . n of points projected onto a target
surface, against closed forms: flat targets (the exact linear interpolation coordinates,
d = height), a circle of 200 chords and a refined icosahedron (d within the chord error of
the height, the angle of pi(x) within a closed-form bound, the closest points against a
second algorithm written here: the plane projection if inside, else the nearest of the
three edges), the free end of a chain and a convex kink, the normals' orientation, and the
independence of the closest points from the facets' order."""
import numpy as np
import pytest

from vpcontact.model import pairgeometry
from vpcontact.model.pairgeometry import facet_normals, project_points

RNG_SEED = 20261126


def _chain(vertices):
    """The segments (n - 1, 2, 2) of a polyline."""
    v = np.asarray(vertices, dtype=float)
    return np.stack([v[:-1], v[1:]], axis=1)


def _grid_triangles(n):
    """The unit square z = 0 in n x n squares, each two triangles: (i, j) lower
    (P_ij, P_i+1j, P_ij+1) at 2 (i n + j), upper (P_i+1j+1, P_ij+1, P_i+1j) next."""
    x = np.linspace(0.0, 1.0, n + 1)
    P = np.stack(np.meshgrid(x, x, np.zeros(1), indexing="ij"), axis=-1)[:, :, 0]
    tris = [t for i in range(n) for j in range(n)
            for t in ([P[i, j], P[i + 1, j], P[i, j + 1]],
                      [P[i + 1, j + 1], P[i, j + 1], P[i + 1, j]])]
    return np.array(tris)


def _circle(n, R=1.0):
    """The n chords of the circle of radius R, and their outward normals (radial at the
    chord's middle angle)."""
    th = 2 * np.pi * np.arange(n + 1) / n
    F = _chain(R * np.stack([np.cos(th), np.sin(th)], axis=1))
    mid = th[:-1] + np.pi / n
    return F, np.stack([np.cos(mid), np.sin(mid)], axis=1)


def _icosphere(levels, R=1.0):
    """An icosahedron refined `levels` times (each triangle into four), its vertices on the
    sphere of radius R, and the outward normals of its triangles."""
    g = (1 + 5 ** 0.5) / 2
    V = [(-1, g, 0), (1, g, 0), (-1, -g, 0), (1, -g, 0), (0, -1, g), (0, 1, g),
         (0, -1, -g), (0, 1, -g), (g, 0, -1), (g, 0, 1), (-g, 0, -1), (-g, 0, 1)]
    T = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    F = np.array(V, dtype=float)[np.array(T)]
    F /= np.linalg.norm(F, axis=2)[..., None]
    for _ in range(levels):
        a, b, c = F[:, 0], F[:, 1], F[:, 2]
        ab, bc, ca = [m / np.linalg.norm(m, axis=1)[:, None]
                      for m in (a + b, b + c, c + a)]
        F = np.concatenate([np.stack(t, axis=1) for t in
                            ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    F *= R
    n = np.cross(F[:, 1] - F[:, 0], F[:, 2] - F[:, 0])
    n /= np.linalg.norm(n, axis=1)[:, None]
    n *= np.sign(np.einsum("ij,ij->i", n, F.mean(axis=1)))[:, None]
    return F, n


def _segment_closest(p, a, b):
    """The closest points (m, nf, d) of the points p (m, d) on the segments a-b (nf, d)."""
    ab = b - a
    t = np.einsum("mfd,fd->mf", p[:, None] - a[None], ab) / np.einsum("fd,fd->f", ab, ab)
    return a[None] + np.clip(t, 0, 1)[..., None] * ab[None]


def _triangle_closest(p, F):
    """The closest point of p (m, 3) on the triangles F (nf, 3, 3), by a second algorithm:
    the projection onto the plane when it lies in the triangle (by the signs of three
    cross products), else the nearest of the three edges' closest points."""
    a, b, c = F[:, 0], F[:, 1], F[:, 2]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    q = p[:, None] - np.einsum("mfd,fd->mf", p[:, None] - a[None], n)[..., None] * n[None]
    side = [np.einsum("mfd,fd->mf", np.cross(e1 - e0, q - e0), n)
            for e0, e1 in ((a, b), (b, c), (c, a))]
    inner = (side[0] >= 0) & (side[1] >= 0) & (side[2] >= 0)
    edges = np.stack([_segment_closest(p, e0, e1) for e0, e1 in ((a, b), (b, c), (c, a))])
    k = np.argmin(np.linalg.norm(edges - p[None, :, None], axis=3), axis=0)
    on_edge = np.take_along_axis(edges, k[None, ..., None], axis=0)[0]
    best = np.where(inner[..., None], q, on_edge)
    j = np.argmin(np.linalg.norm(best - p[:, None], axis=2), axis=1)
    return best[np.arange(len(p)), j]


def test_flat_segments_give_the_linear_interpolation_coordinates_and_the_height():
    rng = np.random.default_rng(RNG_SEED)
    xs = np.sort(np.r_[0.0, rng.uniform(0.05, 0.95, 9), 1.0])      # uneven segments
    F = _chain(np.c_[xs, np.zeros_like(xs)])
    x = rng.uniform(0.001, 0.999, 300)
    h = rng.uniform(-0.3, 0.3, 300)
    pr = project_points(np.c_[x, h], F, np.tile([0.0, 1.0], (len(F), 1)))
    j = np.searchsorted(xs, x) - 1
    s = (x - xs[j]) / (xs[j + 1] - xs[j])
    assert np.array_equal(pr.facet, j) and pr.inside.all()
    np.testing.assert_allclose(pr.weights, np.c_[1 - s, s], rtol=0, atol=1e-13)
    np.testing.assert_allclose(pr.closest, np.c_[x, np.zeros_like(x)], rtol=0, atol=1e-15)
    np.testing.assert_allclose(pr.distance, h, rtol=0, atol=1e-15)
    assert np.array_equal(pr.normal, np.tile([0.0, 1.0], (300, 1)))
    # on a vertex: both segments tie, both project inside: the smaller index
    at = project_points([[xs[3], 0.2], [xs[3], -0.2]], F, np.tile([0.0, 1.0], (len(F), 1)))
    assert list(at.facet) == [2, 2] and np.allclose(at.weights, [[0, 1], [0, 1]])
    assert at.distance.tolist() == [0.2, -0.2]


def test_flat_triangles_give_the_linear_interpolation_coordinates_and_the_height():
    n = 6
    F = _grid_triangles(n)
    rng = np.random.default_rng(RNG_SEED)
    xy = rng.uniform(0.001, 0.999, (400, 2))
    h = np.where(np.arange(400) % 2, 1, -1) * rng.uniform(0.001, 0.3, 400)
    pr = project_points(np.c_[xy, h], F, np.tile([0.0, 0.0, 1.0], (len(F), 1)))
    i, j = np.floor(xy * n).astype(int).T
    s, t = (xy * n - np.floor(xy * n)).T
    upper = s + t > 1
    expected = 2 * (i * n + j) + upper
    w = np.where(upper[:, None], np.c_[s + t - 1, 1 - s, 1 - t], np.c_[1 - s - t, s, t])
    keep = np.abs(s + t - 1) > 1e-9                    # off the shared diagonal
    assert np.array_equal(pr.facet[keep], expected[keep]) and pr.inside.all()
    np.testing.assert_allclose(pr.weights[keep], w[keep], rtol=0, atol=1e-12)
    np.testing.assert_allclose(pr.closest, np.c_[xy, np.zeros(400)], rtol=0, atol=1e-15)
    np.testing.assert_allclose(pr.distance, h, rtol=0, atol=1e-15)
    assert np.array_equal(pr.normal, np.tile([0.0, 0.0, 1.0], (400, 1)))
    assert (pr.distance[1::2] > 0).all() and (pr.distance[::2] < 0).all()


def test_circle_of_chords_gap_within_the_chord_error_and_the_angle_kept():
    R, n = 1.0, 200
    F, N = _circle(n, R)
    delta = np.pi / n                                    # half the angle of one chord
    rng = np.random.default_rng(RNG_SEED)
    phi = rng.uniform(0, 2 * np.pi, 500)
    h = rng.uniform(0.001, 0.05, 500)
    x = (R + h)[:, None] * np.c_[np.cos(phi), np.sin(phi)]
    pr = project_points(x, F, N)
    assert pr.inside.all()
    # the angle of pi(x) on the chord of psi - delta < phi < psi + delta (psi its middle):
    # beta - psi = arctan((R + h) sin(phi - psi) / (R cos delta)) clamped to the chord, so
    # |beta - phi| <= eps; and d = (R + h) cos(phi - psi') - R cos(delta) with psi' the middle
    # of the chosen chord (at a vertex either one), |phi - psi'| <= delta + eps
    eps = np.sin(delta) * ((R + h) / (R * np.cos(delta)) - 1)
    angle = np.angle(np.exp(1j * (np.arctan2(pr.closest[:, 1], pr.closest[:, 0]) - phi)))
    assert (np.abs(angle) <= eps + 1e-14).all()
    assert (pr.distance >= (R + h) * np.cos(delta + eps) - R * np.cos(delta) - 1e-14).all()
    assert (pr.distance <= h + R * (1 - np.cos(delta)) + 1e-14).all()
    ref = _segment_closest(x, F[:, 0], F[:, 1])
    ref = ref[np.arange(len(x)), np.argmin(np.linalg.norm(ref - x[:, None], axis=2), axis=1)]
    np.testing.assert_allclose(pr.closest, ref, rtol=0, atol=1e-14)
    # radially above a chord's middle: the closest point keeps the angle exactly
    j = rng.integers(0, n, 50)
    mid = 2 * np.pi * j / n + delta
    on = project_points((R + 0.02) * np.c_[np.cos(mid), np.sin(mid)], F, N)
    assert np.array_equal(on.facet, j)
    np.testing.assert_allclose(on.closest, R * np.cos(delta) * np.c_[np.cos(mid), np.sin(mid)],
                               rtol=0, atol=1e-14)
    np.testing.assert_allclose(on.distance, R + 0.02 - R * np.cos(delta), rtol=0, atol=1e-14)


def test_sphere_triangulation_closest_points_and_gaps():
    R = 2.0
    F, N = _icosphere(2, R)                              # 320 nearly equilateral triangles
    rho = np.einsum("ij,ij->i", F[:, 0], N)              # each plane's distance from 0
    # along each facet's normal: the foot is the facet's circumcentre, inside it
    pr = project_points((R + 0.1) * N, F, N)
    assert np.array_equal(pr.facet, np.arange(len(F))) and pr.inside.all()
    np.testing.assert_allclose(pr.closest, rho[:, None] * N, rtol=0, atol=1e-13)
    np.testing.assert_allclose(pr.distance, R + 0.1 - rho, rtol=0, atol=1e-13)
    np.testing.assert_allclose(np.einsum("ik,ikd->id", pr.weights, F), pr.closest, atol=1e-13)
    assert (pr.weights > 0).all()
    # random directions: h <= |x - pi| <= h + R - min rho (the polyhedron lies between the
    # spheres of radius min rho and R), and pi as found by the second algorithm
    rng = np.random.default_rng(RNG_SEED)
    u = rng.normal(size=(200, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    h = rng.uniform(0.001, 0.3, 200)
    x = (R + h)[:, None] * u
    pr = project_points(x, F, N)
    gap = np.linalg.norm(x - pr.closest, axis=1)
    assert pr.inside.all() and (gap >= h - 1e-13).all()
    assert (gap <= h + R - rho.min() + 1e-13).all()
    assert ((pr.distance > 0) & (pr.distance <= gap + 1e-13)).all()
    np.testing.assert_allclose(pr.closest, _triangle_closest(x, F), rtol=0, atol=1e-13)
    inner = project_points(0.9 * rho.min() * u, F, N)
    assert (inner.distance < 0).all() and inner.inside.all()


def test_free_end_is_outside_and_a_convex_kink_inside_2d():
    F = _chain([(-1.0, 0.0), (0.0, 1.0), (1.0, 0.0)])   # a roof over the body below
    N = np.array([[-1.0, 1.0], [1.0, 1.0]]) / 2 ** 0.5
    pr = project_points([(0.0, 2.0), (-2.0, -0.5), (-0.9, 0.5), (3.0, 0.5)], F, N)
    assert pr.inside.tolist() == [True, False, True, False]
    assert pr.facet.tolist() == [0, -1, 0, -1]
    np.testing.assert_allclose(pr.closest, [(0, 1), (-1, 0), (-0.7, 0.3), (1, 0)], atol=1e-15)
    np.testing.assert_allclose(pr.distance, [1 / 2 ** 0.5, 0.5 / 2 ** 0.5, 0.2 * 2 ** 0.5,
                                             2.5 / 2 ** 0.5], atol=1e-15)
    # above a vertex, two segments tie: the one the point projects into wins over index 0
    F = np.array([[(0.0, 0.0), (1.0, -1.0)], [(-1.0, 0.0), (0.0, 0.0)]])
    N = np.array([[1.0, 1.0], [0.0, 1.0]]) / np.array([[2 ** 0.5], [1.0]])
    pr = project_points([(0.0, 1.0)], F, N)
    assert pr.facet.tolist() == [1] and pr.weights.tolist() == [[0.0, 1.0]]
    assert pr.distance.tolist() == [1.0]


def test_free_edges_are_outside_and_a_ridge_inside_3d():
    square = _grid_triangles(1)
    up = np.tile([0.0, 0.0, 1.0], (2, 1))
    pr = project_points([(1.5, 0.5, 0.2), (1.2, 1.3, -0.1), (0.5, 0.5, 0.2),
                         (0.5, 0.99, 0.2)], square, up)
    assert pr.inside.tolist() == [False, False, True, True]
    assert pr.facet.tolist() == [-1, -1, 0, 1]         # the diagonal: both inside, the first
    np.testing.assert_allclose(pr.closest, [(1, 0.5, 0), (1, 1, 0), (0.5, 0.5, 0),
                                            (0.5, 0.99, 0)], atol=1e-15)
    np.testing.assert_allclose(pr.distance, [0.2, -0.1, 0.2, 0.2], atol=1e-15)
    P0, P1, L0, L1, R0, R1 = np.array([(0, 0, 1), (0, 1, 1), (-1, 0, 0), (-1, 1, 0),
                                       (1, 0, 0), (1, 1, 0)], dtype=float)
    roof = np.array([(P0, P1, L0), (P1, L1, L0), (P0, R0, P1), (P1, R0, R1)])
    N = facet_normals(roof, np.tile([0.0, 0.5, -1.0], (4, 1)))
    pr = project_points([(0.0, 0.5, 2.0), (0.0, 1.5, 2.0), (-0.5, 0.2, 0.6)], roof, N)
    assert pr.inside.tolist() == [True, False, True]
    np.testing.assert_allclose(pr.closest[:2], [(0, 0.5, 1), (0, 1, 1)], atol=1e-15)
    np.testing.assert_allclose(pr.distance[0], 1 / 2 ** 0.5, atol=1e-15)
    np.testing.assert_allclose(pr.distance[2], 0.1 / 2 ** 0.5, atol=1e-15)


def test_facet_normals_point_away_from_the_interior():
    rng = np.random.default_rng(RNG_SEED)
    square = _chain([(0, 0), (1, 0), (1, 1), (0, 1), (0, 0)])
    flip = rng.random(4) < 0.5
    square[flip] = square[flip, ::-1]
    n = facet_normals(square, np.tile([0.5, 0.5], (4, 1)))
    np.testing.assert_allclose(n, [(0, -1), (1, 0), (0, 1), (-1, 0)], atol=1e-15)
    F, N = _icosphere(1)
    F = np.array([f[rng.permutation(3)] for f in F])      # either orientation
    np.testing.assert_allclose(facet_normals(F, np.zeros((len(F), 3))), N, atol=1e-14)
    opposite = facet_normals(F, 2 * F.mean(axis=1))       # interior beyond: inward normals
    np.testing.assert_allclose(opposite, -N, atol=1e-14)
    tet = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)], dtype=float)
    n = facet_normals(tet[[[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]], tet)
    np.testing.assert_allclose(n, np.r_[[np.ones(3) / 3 ** 0.5], -np.eye(3)], atol=1e-15)
    with pytest.raises(ValueError, match="lies on the facet"):
        facet_normals(square[:1], [(0.5, 0.0)])
    with pytest.raises(ValueError, match="shape"):
        project_points(np.zeros((1, 2)), np.zeros((1, 3, 2)), np.zeros((1, 2)))


def test_shuffled_facets_give_the_same_closest_points():
    rng = np.random.default_rng(RNG_SEED)
    F, N = _circle(200)
    th = 2 * np.pi * np.arange(20) / 200                  # radially above vertices: ties
    x = np.r_[rng.normal(size=(300, 2)), 1.05 * np.c_[np.cos(th), np.sin(th)]]
    S, T = _icosphere(2)
    y = rng.normal(size=(300, 3)) * 1.2
    for G, M, z in ((F, N, x), (S, T, y)):
        a = project_points(z, G, M)
        perm = rng.permutation(len(G))
        b = project_points(z, G[perm], M[perm])
        np.testing.assert_allclose(b.closest, a.closest, rtol=0, atol=1e-14)
        assert np.array_equal(a.inside, b.inside)
        # on a vertex or an edge, every facet holding it ties: the lowest new index
        ties = (a.weights == 0).any(axis=1)
        found = np.where(b.facet >= 0, perm[b.facet], -1)
        assert ties.any() and np.array_equal(found[~ties], a.facet[~ties])
        inverse = np.argsort(perm)
        for i in np.flatnonzero(ties):
            support = G[a.facet[i]][a.weights[i] > 0]
            holds = (np.linalg.norm(G[:, :, None] - support[None, None], axis=3)
                     .min(axis=1) < 1e-14).all(axis=1)
            assert b.facet[i] == inverse[np.flatnonzero(holds)].min()


def test_candidates_beyond_the_nearest_centroids(monkeypatch):
    # one long segment, then 30 short ones: the 8 nearest centroids are all short ones
    xs = np.r_[0.0, np.linspace(10.0, 10.3, 31)]
    F = _chain(np.c_[xs, np.zeros_like(xs)])
    x = np.c_[np.linspace(9.0, 9.9, 10), np.full(10, 0.3)]
    pr = project_points(x, F, np.tile([0.0, 1.0], (len(F), 1)))
    assert (pr.facet == 0).all()
    np.testing.assert_allclose(pr.closest, np.c_[x[:, 0], np.zeros(10)], rtol=1e-15, atol=0)
    # far from a finer grid: many candidates each, in several chunks
    monkeypatch.setattr(pairgeometry, "CHUNK_PAIRS", 512)
    F = _grid_triangles(12)
    rng = np.random.default_rng(RNG_SEED)
    x = np.c_[rng.uniform(-0.5, 1.5, (300, 2)), rng.uniform(0.2, 1.0, 300)]
    pr = project_points(x, F, np.tile([0.0, 0.0, 1.0], (len(F), 1)))
    assert np.array_equal(pr.inside, ((x[:, :2] >= 0) & (x[:, :2] <= 1)).all(axis=1))
    np.testing.assert_allclose(pr.closest, np.c_[np.clip(x[:, :2], 0, 1), np.zeros(300)],
                               rtol=0, atol=1e-15)
    np.testing.assert_allclose(pr.distance, x[:, 2], rtol=0, atol=1e-15)


# the ray cast along a fixed direction (contact.direction with pairs): cast_points


def _line_circle(x, e, R):
    """The parameters t of the points x + t e (x (m, 2), e unit) on the circle |y| = R."""
    b = x @ e
    disc = b ** 2 - (np.einsum("ij,ij->i", x, x) - R ** 2)
    return -b - np.sqrt(disc), -b + np.sqrt(disc)


def test_cast_onto_a_circle_of_chords_enters_where_the_line_meets_it():
    """Vertical lines above the circle (R = 1, 400 chords) downward: pi(x) on the upper
    half where the line enters (not the lower half, where it leaves), the gap within the
    chord error R (1 - cos(pi / n)) of the exact line-circle distance, pi(x) on the line, and
    the P1 weights reproducing pi(x) on its chord; a tilted direction the same."""
    n, R = 400, 1.0
    F, N = _circle(n, R)
    rng = np.random.default_rng(RNG_SEED)
    chord = R * (1 - np.cos(np.pi / n))
    for e in (np.array([0.0, -1.0]), np.array([0.6, -0.8])):
        foot = rng.uniform(-0.9, 0.9, 50)[:, None] * np.array([-e[1], e[0]])
        x = foot - rng.uniform(1.2, 2.0, 50)[:, None] * e
        proj = pairgeometry.cast_points(x, F, N, e)
        assert proj.inside.all()
        t_in, _ = _line_circle(x, e, R)
        assert np.abs(proj.distance - t_in).max() <= chord / np.sqrt(1 - 0.9 ** 2)
        off = proj.closest - x - proj.distance[:, None] * e
        assert np.abs(off).max() <= 1e-12
        on = np.einsum("ik,ikd->id", proj.weights, F[proj.facet])
        assert np.abs(on - proj.closest).max() <= 1e-12
        assert (proj.normal @ e < 0).all()                  # the entering side


def test_cast_onto_a_tilted_triangulated_plane():
    """The plane z = 0.2 x + 0.1 y in 8 x 8 squares (two triangles each), lines along
    (0, 0, -1) from z = 1: the gap 1 - z(x, y) and the weights the P1 coordinates."""
    F = _grid_triangles(8)
    F[:, :, 2] = 0.2 * F[:, :, 0] + 0.1 * F[:, :, 1]
    N = np.tile(np.array([-0.2, -0.1, 1.0]) / np.linalg.norm([-0.2, -0.1, 1.0]), (len(F), 1))
    rng = np.random.default_rng(RNG_SEED)
    xy = rng.uniform(0.01, 0.99, (60, 2))
    x = np.c_[xy, np.ones(60)]
    proj = pairgeometry.cast_points(x, F, N, [0.0, 0.0, -1.0])
    assert proj.inside.all()
    assert np.allclose(proj.distance, 1.0 - 0.2 * xy[:, 0] - 0.1 * xy[:, 1], atol=1e-13)
    assert np.allclose(proj.closest[:, :2], xy, atol=1e-13)
    assert np.allclose(proj.weights.sum(axis=1), 1.0) and (proj.weights >= 0).all()


def test_cast_misses_and_back_faces():
    """A line past the target's end is outside; a facet the line leaves through (n . e > 0)
    is not taken; of two entering layers the nearer one is."""
    F = _chain([[0.0, 0.0], [1.0, 0.0]])
    up = np.array([[0.0, 1.0]])
    down = np.array([[0.0, -1.0]])
    x = np.array([[0.5, 1.0], [1.5, 1.0]])
    proj = pairgeometry.cast_points(x, F, up, [0.0, -1.0])
    assert proj.inside.tolist() == [True, False] and proj.facet.tolist() == [0, -1]
    assert proj.distance[0] == pytest.approx(1.0)
    assert not pairgeometry.cast_points(x, F, down, [0.0, -1.0]).inside.any()
    two = np.concatenate([F, F - [0.0, 0.5]])
    proj = pairgeometry.cast_points(x[:1], two, np.concatenate([up, up]), [0.0, -1.0])
    assert proj.facet.tolist() == [0] and proj.distance[0] == pytest.approx(1.0)
