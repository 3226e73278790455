"""fastsolver: the free block's Newton system, solved in place; the Gamma3 start guess."""
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


def test_start_extrapolates_the_last_two_steps():
    """FastStepSolver._start: y0 at the first step, the last solution after one step or a
    restart (no time), the linear extrapolation in time after two steps (any step sizes)."""
    from types import SimpleNamespace

    from app.fastsolver import FastStepSolver

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
