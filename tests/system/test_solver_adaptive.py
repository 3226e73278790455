"""Adaptive steps do not depend on the step solver (app/model/stepping.py AdaptiveSteps,
app/simulation.py Simulation._relative_change): the growth rule reads the converged
solution, not the Newton iterations, so the fast solver and SNES VI take the same time grid
and agree to 1e-8 (before: growth after at most fast_newton iterations; SNES VI needs more
than the fast solver, the grids differed and u by 8e-5)."""
import numpy as np
import pytest

from conftest import paper_raw, run_case, validate_raw


def _adaptive(adaptive: dict) -> dict:
    raw = paper_raw()
    # a slower viscoplastic flow: the explicit stability limit (k <= 12 s) does not bind,
    # the growth rule decides the grid
    raw["material"]["viscoplastic"]["lambda1"] = 1000.0
    raw["time"]["adaptive"] = adaptive
    return raw


def _grid(result) -> list[tuple]:
    return [(d["k"], d["accepted"]) for d in result.summary["step_history"]]


@pytest.mark.parametrize("adaptive", [{}, {"max_change": 0.02}], ids=["default", "fine"])
def test_fast_and_snes_vi_take_the_same_adaptive_grid(adaptive):
    runs = {}
    for method in ("snes_vi", "fast"):
        raw = _adaptive(adaptive)
        raw["solver"]["method"] = method
        if method == "snes_vi":   # both start from the extrapolation of the last steps and
            # iterate alike; the semismooth Newton method takes other iterations
            raw["petsc"] = {"snes_type": "vinewtonssls"}
        runs[method] = run_case(validate_raw(raw))
        assert runs[method].status == "completed"
    a, b = runs["snes_vi"], runs["fast"]
    iterations = [[s["newton_iterations"] for s in r.summary["steps"]] for r in (a, b)]
    assert iterations[0] != iterations[1]          # the solvers do differ in iterations
    assert _grid(a) == _grid(b) and len(a.summary["steps"]) > 3
    assert [s["t"] for s in a.summary["steps"]] == [s["t"] for s in b.summary["steps"]]
    ua, ub = a.problem.u.x.array, b.problem.u.x.array
    assert np.abs(ua - ub).max() <= 1e-8 * np.abs(ua).max()


def test_the_grid_ignores_the_iteration_count(monkeypatch):
    """A step solver reporting many iterations takes the same grid (the iteration count is
    a property of the solver, not of the discrete problem)."""
    from vpcontact.solvers.condensed import CondensedStepSolver
    raw = _adaptive({})
    raw["solver"]["method"] = "fast"
    plain = run_case(validate_raw(raw))
    solve = CondensedStepSolver.solve
    monkeypatch.setattr(CondensedStepSolver, "solve", lambda self: solve(self) + 100)
    slow = run_case(validate_raw(raw))
    assert _grid(slow) == _grid(plain)
    assert slow.summary["steps"][0]["newton_iterations"] >= 100
    assert np.array_equal(slow.problem.u.x.array, plain.problem.u.x.array)


def test_growth_follows_the_solution_change():
    """max|u_n - u_{n-1}| / max|u_n| of each accepted step is recorded, and k grew exactly
    after the steps whose change was at most max_change."""
    raw = _adaptive({"max_change": 0.02})
    raw["solver"]["method"] = "fast"
    result = run_case(validate_raw(raw))
    accepted = [d for d in result.summary["step_history"] if d["accepted"]]
    assert accepted[0]["change"] == pytest.approx(1.0)     # from u_0 = 0
    for before, after in zip(accepted, accepted[1:]):
        grown = after["k"] > before["k"] * (1 + 1e-12)
        last = after is accepted[-1]                        # shortened to land on T
        if not last:
            assert grown == (before["change"] <= 0.02), (before, after)
