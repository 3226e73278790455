"""The normal of a contact pair and its coupling point (app/model/pairnormal.py), numpy only,
against closed forms: the vertex normals of a regular polygon are radial; two mirror-image
circles give the vertical normal and the mirror point (where the target's normal at the
closest point is tilted by about x / R, and the closest point is not the mirror point); a
flat surface over a flat target gives the target's normal and the closest point; a tilted
surface normal over a flat target (2D segments, 3D triangles) the bisector and the point
met along it, with the P1 weights of that point; a ray past the target's free end is
outside."""
import numpy as np

from vpcontact.model.pairgeometry import facet_normals, project_points
from vpcontact.model.pairnormal import pair_normal, pair_projection, vertex_normals


def _arc(R: float, centre_y: float, sign: float, n: int, half: float):
    """n chords of the circle of radius R centred at (0, centre_y), the arc within `half`
    radians of its point nearest the origin (sign -1: the lower point, +1: the upper), with
    the vertices' global nodes and the outward normals of the disc."""
    th = np.linspace(-half, half, n + 1)
    v = np.stack([R * np.sin(th), centre_y + sign * R * np.cos(th)], axis=1)
    F = np.stack([v[:-1], v[1:]], axis=1)
    nodes = np.stack([np.arange(n), np.arange(1, n + 1)], axis=1)
    N = facet_normals(F, np.tile([0.0, centre_y], (n, 1)))
    return v, F, nodes, N


def test_vertex_normals_of_a_regular_polygon_are_radial():
    v, F, nodes, N = _arc(1.0, 0.0, -1.0, 40, 0.6)
    vn = vertex_normals(F, N, nodes)
    inner = v[1:-1] / np.linalg.norm(v[1:-1], axis=1)[:, None]
    np.testing.assert_allclose(vn[1:, 0], inner, atol=1e-14)     # vertex k of facet k
    np.testing.assert_allclose(vn[:-1, 1], inner, atol=1e-14)
    np.testing.assert_allclose(vn[0, 0], N[0], atol=1e-15)        # an end: its one facet


def test_mirror_circles_give_the_vertical_normal_and_the_mirror_point():
    """Upper circle (centre (0, 1)) over its mirror image: nu = (0, -1) and pi(x) = (x, -y)
    at every upper vertex to 1e-14; d = 2 y.  The target's normal at the closest point (the
    former pair normal) is tilted by about x / (2 R) at x = 0.3, and the closest point lies
    nearer the axis than the mirror point."""
    R = 1.0
    up, Fu, nu_nodes, Nu = _arc(R, R, -1.0, 60, 0.5)
    lo, Fl, nl_nodes, Nl = _arc(R, -R, 1.0, 60, 0.5)
    n_s = vertex_normals(Fu, Nu, nu_nodes)
    pts, ns = up[1:-1], n_s[1:, 0]
    proj, nu = pair_projection(pts, ns, Fl, Nl, vertex_normals(Fl, Nl, nl_nodes))
    assert proj.inside.all()
    np.testing.assert_allclose(nu, np.tile([0.0, -1.0], (len(pts), 1)), atol=1e-14)
    np.testing.assert_allclose(proj.closest, pts * [1.0, -1.0], atol=1e-14)
    np.testing.assert_allclose(np.einsum("ij,ij->i", proj.closest - pts, nu), 2 * pts[:, 1],
                               atol=1e-14)
    near = project_points(pts, Fl, Nl)
    far = np.abs(pts[:, 0]) > 0.3
    assert (np.abs(near.normal[far, 0]) > 0.1).all()
    assert (np.abs(near.closest[far, 0]) < np.abs(pts[far, 0]) - 1e-3).all()


def test_flat_on_flat_is_the_closest_point():
    x = np.linspace(0.0, 1.0, 6)
    F = np.stack([np.c_[x[:-1], 0 * x[:-1]], np.c_[x[1:], 0 * x[1:]]], axis=1)
    N = np.tile([0.0, 1.0], (5, 1))
    nodes = np.stack([np.arange(5), np.arange(1, 6)], axis=1)
    pts = np.c_[np.linspace(0.05, 0.95, 13), np.full(13, 0.3)]
    proj, nu = pair_projection(pts, np.tile([0.0, -1.0], (13, 1)), F, N,
                               vertex_normals(F, N, nodes))
    near = project_points(pts, F, N)
    assert np.array_equal(nu, np.tile([0.0, -1.0], (13, 1)))
    np.testing.assert_allclose(proj.closest, near.closest, atol=1e-15)
    np.testing.assert_allclose(proj.weights, near.weights, atol=1e-14)


def test_tilted_surface_over_a_flat_target_2d():
    """n_s at 40 degrees from the vertical, the target y = 0 (n_t = (0, 1)): nu is the
    bisector, at 20 degrees, and pi = x + (y / cos 20) nu, its weights linear in x."""
    x = np.linspace(-1.0, 1.0, 11)
    F = np.stack([np.c_[x[:-1], 0 * x[:-1]], np.c_[x[1:], 0 * x[1:]]], axis=1)
    N = np.tile([0.0, 1.0], (10, 1))
    nodes = np.stack([np.arange(10), np.arange(1, 11)], axis=1)
    a = np.radians(40.0)
    pts = np.array([[0.13, 0.2], [-0.41, 0.05], [0.07, 0.0]])
    ns = np.tile([np.sin(a), -np.cos(a)], (3, 1))
    proj, nu = pair_projection(pts, ns, F, N, vertex_normals(F, N, nodes))
    b = a / 2
    np.testing.assert_allclose(nu, np.tile([np.sin(b), -np.cos(b)], (3, 1)), atol=1e-15)
    hit = pts[:, 0] + pts[:, 1] * np.tan(b)
    np.testing.assert_allclose(proj.closest, np.c_[hit, np.zeros(3)], atol=1e-15)
    k = np.floor((hit + 1.0) / 0.2).astype(int)
    s = (hit - x[k]) / 0.2
    np.testing.assert_allclose(proj.weights, np.c_[1 - s, s], atol=1e-12)
    np.testing.assert_allclose(pair_normal(ns, np.tile([0.0, 1.0], (3, 1))), nu, atol=1e-15)


def test_tilted_surface_over_a_flat_target_3d():
    """The plane z = 0 in triangles, n_s tilted about the y axis by 30 degrees: nu tilted by
    15 degrees, pi = x + (z / cos 15) nu, its barycentric weights reproduce pi."""
    g = np.linspace(0.0, 1.0, 5)
    P = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1)
    tris, ids = [], []
    for i in range(4):
        for j in range(4):
            for t in (((i, j), (i + 1, j), (i, j + 1)), ((i + 1, j + 1), (i, j + 1), (i + 1, j))):
                tris.append([[*P[a, b], 0.0] for a, b in t])
                ids.append([a * 5 + b for a, b in t])
    F, nodes = np.array(tris), np.array(ids)
    N = np.tile([0.0, 0.0, 1.0], (len(F), 1))
    a = np.radians(30.0)
    pts = np.array([[0.4, 0.55, 0.1], [0.62, 0.3, 0.02]])
    ns = np.tile([np.sin(a), 0.0, -np.cos(a)], (2, 1))
    proj, nu = pair_projection(pts, ns, F, N, vertex_normals(F, N, nodes))
    b = a / 2
    np.testing.assert_allclose(nu, np.tile([np.sin(b), 0.0, -np.cos(b)], (2, 1)), atol=1e-15)
    want = pts + (pts[:, 2] / np.cos(b))[:, None] * nu
    np.testing.assert_allclose(proj.closest, want, atol=1e-15)
    back = np.einsum("ik,ikd->id", proj.weights, F[proj.facet])
    np.testing.assert_allclose(back, want, atol=1e-14)


def test_ray_past_the_free_end_is_outside():
    """A point above the target's end whose normal leans outward: the ray misses."""
    F = np.array([[[0.0, 0.0], [0.5, 0.0]], [[0.5, 0.0], [1.0, 0.0]]])
    N = np.tile([0.0, 1.0], (2, 1))
    nodes = np.array([[0, 1], [1, 2]])
    a = np.radians(60.0)
    pts = np.array([[0.98, 0.2], [0.5, 0.2]])
    ns = np.tile([np.sin(a), -np.cos(a)], (2, 1))
    proj, _ = pair_projection(pts, ns, F, N, vertex_normals(F, N, nodes))
    assert list(proj.inside) == [False, True] and proj.facet[0] == -1
