"""dense.NewtonDirection: the free block's Newton system (compiled and numpy alike); the
Gamma3 start guess."""
import numpy as np
import pytest

from app.solvers import dense


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
    """FastStepSolver._start: y0 at the first step, the last solution after one step or a
    restart (no time), the linear extrapolation in time after two steps (any step sizes)."""
    from types import SimpleNamespace

    from app.solvers.fast import FastStepSolver

    clock = SimpleNamespace(value=0.1)
    solver = SimpleNamespace(_y_prev=[], problem=SimpleNamespace(
        time_data=SimpleNamespace(t=clock)))
    y0 = np.array([5.0, 6.0])
    assert np.array_equal(FastStepSolver._start(solver, y0), y0)
    FastStepSolver._remember(solver, np.array([1.0, 2.0]))          # step at t = 0.1
    clock.value = 0.3
    assert np.array_equal(FastStepSolver._start(solver, y0), [1.0, 2.0])
    FastStepSolver._remember(solver, np.array([2.0, 2.0]))          # step at t = 0.3
    clock.value = 0.4                                                # k = 0.1 after k = 0.2
    assert np.allclose(FastStepSolver._start(solver, y0), [2.5, 2.0], rtol=1e-15)
    solver._y_prev = [(None, np.array([3.0, 1.0]))]                 # warm_start (restart)
    FastStepSolver._remember(solver, np.array([4.0, 1.0]))
    clock.value = 0.5
    assert np.array_equal(FastStepSolver._start(solver, y0), [4.0, 1.0])
