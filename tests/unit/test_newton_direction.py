"""dense.NewtonDirection: the free block's Newton system (compiled and numpy alike); the
Gamma3 start guess."""
import numpy as np
import pytest

from vpcontact.solvers import dense


def _directions(S, d):
    out = [dense.NewtonDirection(S, d, None)]
    module = dense.load()
    if module is not None:
        out.append(dense.NewtonDirection(S, d, module))
    return out


@pytest.mark.parametrize("d", [2, 3])
def test_direction_solves_the_free_block(d):
    rng = np.random.default_rng(d)
    m = 4 * d
    A = rng.normal(size=(m, m))
    S = A @ A.T + m * np.eye(m)
    B = rng.normal(size=(m // d, d, d))
    W = np.einsum("nij,nkj->nik", B, B)               # nodal blocks, positive semidefinite
    H = S.copy()
    for i in range(m // d):
        H[i * d:(i + 1) * d, i * d:(i + 1) * d] += W[i]
    g = rng.normal(size=m)
    binding = np.zeros(m, dtype=bool)
    binding[[1, d + 1, d + 2, m - 1]] = True          # parts of nodes, and whole ones
    f = np.flatnonzero(~binding)
    ref = np.linalg.solve(H[np.ix_(f, f)], -g[f])
    for direction in _directions(S, d):
        assert np.abs(direction.matrix(W) - H).max() <= 1e-14 * np.abs(H).max()
        p = direction(W, g, binding)
        assert np.array_equal(p[binding], np.zeros(binding.sum()))
        assert np.abs(p[f] - ref).max() <= 1e-13 * np.abs(ref).max()
        p_all = direction(W, g, np.zeros(m, dtype=bool))
        assert np.abs(p_all - np.linalg.solve(H, -g)).max() <= 1e-13 * np.abs(p_all).max()
        assert np.array_equal(direction(W, g, np.ones(m, dtype=bool)), np.zeros(m))


def test_indefinite_matrix_gives_none():
    S = np.diag([1.0, -1.0, 2.0, 3.0])
    W = np.zeros((2, 2, 2))
    for direction in _directions(S, 2):
        assert direction(W, np.ones(4), np.zeros(4, dtype=bool)) is None
        binding = np.array([False, True, False, False])   # the indefinite dof held
        assert direction(W, np.ones(4), binding) is not None


def test_start_extrapolates_the_last_two_steps():
    """Gamma3Problem._start: y0 at the first step, the last solution after one step or a
    restart (no time), the linear extrapolation in time after two steps (any step sizes)."""
    from types import SimpleNamespace

    from vpcontact.solvers.condensed.problem import Gamma3Problem

    problem = SimpleNamespace(_y_prev=[])
    y0 = np.array([5.0, 6.0])
    assert np.array_equal(Gamma3Problem._start(problem, y0, 0.1), y0)
    Gamma3Problem._remember(problem, np.array([1.0, 2.0]), 0.1)      # step at t = 0.1
    assert np.array_equal(Gamma3Problem._start(problem, y0, 0.3), [1.0, 2.0])
    Gamma3Problem._remember(problem, np.array([2.0, 2.0]), 0.3)      # step at t = 0.3
    # k = 0.1 after k = 0.2
    assert np.allclose(Gamma3Problem._start(problem, y0, 0.4), [2.5, 2.0], rtol=1e-15)
    problem._y_prev = [(None, np.array([3.0, 1.0]))]                # warm_start (restart)
    Gamma3Problem._remember(problem, np.array([4.0, 1.0]), 0.4)
    assert np.array_equal(Gamma3Problem._start(problem, y0, 0.5), [4.0, 1.0])


def _system(rng, m, d):
    A = rng.normal(size=(m, m))
    S = A @ A.T + m * np.eye(m)
    B = rng.normal(size=(m // d, d, d))
    return S, np.einsum("nij,nkj->nik", B, B)


@pytest.mark.parametrize("d", [2, 3])
def test_kept_factor_with_cg_solves_changed_systems(monkeypatch, d):
    """Above PCG_MIN the factor is kept: the next Newton matrix (other nodal blocks W, some
    dofs binding or released) is solved by CG preconditioned with it, to the asked relative
    residual, without a new factorisation; too many changed dofs factorise afresh."""
    monkeypatch.setattr(dense, "PCG_MIN", 0)
    monkeypatch.setattr(dense, "PCG_MAX_CHANGED", 6)
    rng = np.random.default_rng(10 + d)
    m = 30 * d
    S, W = _system(rng, m, d)
    binding = np.zeros(m, dtype=bool)
    binding[::7] = True
    for direction in _directions(S, d):
        direction(W, rng.normal(size=m), binding, rtol=1e-10)       # factorises, keeps L
        assert (direction.factorisations, direction.cg_iterations) == (1, 0)
        W2 = W * (1 + 0.05 * rng.random(W.shape[0]))[:, None, None]
        b2 = binding.copy()
        b2[[1, 2]], b2[[0, 7]] = True, False                         # 4 dofs changed
        g = rng.normal(size=m)
        H = direction.matrix(W2)
        f = np.flatnonzero(~b2)
        ref = np.linalg.solve(H[np.ix_(f, f)], -g[f])
        p = direction(W2, g, b2, rtol=1e-12)
        assert direction.factorisations == 1 and 0 < direction.cg_iterations <= 15
        assert np.array_equal(p[b2], np.zeros(b2.sum()))
        assert np.linalg.norm(H[np.ix_(f, f)] @ p[f] + g[f]) <= 1e-12 * np.linalg.norm(g[f])
        assert np.abs(p[f] - ref).max() <= 1e-9 * np.abs(ref).max()
        b3 = b2.copy()
        b3[10:20] = True                                             # > PCG_MAX_CHANGED
        direction(W2, g, b3, rtol=1e-12)
        assert direction.factorisations == 2
        direction(W2, g, b3)                                         # rtol = 0: exact
        assert direction.factorisations == 3
