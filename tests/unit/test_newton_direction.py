"""fastsolver._newton_direction: the free block's Newton system, solved in place."""
import numpy as np

from app.fastsolver import _newton_direction


def test_direction_solves_the_free_block():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(12, 12))
    H = A @ A.T + 12 * np.eye(12)
    g = rng.normal(size=12)
    binding = np.zeros(12, dtype=bool)
    binding[[2, 7, 8]] = True
    f = np.flatnonzero(~binding)
    p = _newton_direction(H.copy(), g, binding)
    assert np.array_equal(p[binding], np.zeros(3))
    ref = np.linalg.solve(H[np.ix_(f, f)], -g[f])
    assert np.abs(p[f] - ref).max() <= 1e-13 * np.abs(ref).max()
    p_all = _newton_direction(H.copy(), g, np.zeros(12, dtype=bool))
    assert np.abs(p_all - np.linalg.solve(H, -g)).max() <= 1e-13 * np.abs(p_all).max()


def test_indefinite_matrix_gives_none():
    H = np.diag([1.0, -1.0, 2.0])
    assert _newton_direction(H, np.ones(3), np.zeros(3, dtype=bool)) is None
