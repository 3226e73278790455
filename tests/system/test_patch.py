"""Elastic patch test: a uniform-stress problem is reproduced to round-off.

u = (a x, c x) vanishes on Gamma1 = {x = 0} and has the uniform strain
eps = [[a, c/2], [c/2, 0]], so sigma = E eps is uniform; the tractions sigma n on the right,
top and bottom sides make it the exact solution, which P1 elements must reproduce.
"""
import numpy as np
import pytest

from conftest import make_case, paper_raw, run_case
from vpcontact.forms.elasticity import plane_stress_constants


@pytest.mark.parametrize("mesh", [{"kind": "structured", "n": 4, "diagonal": "left"},
                                  {"kind": "unstructured", "h": 0.3}])
def test_uniform_stress_patch(mesh):
    E, nu, a, c = 1000.0, 0.3, 2.0e-3, -1.0e-3
    lmbda, two_mu = plane_stress_constants(E, nu)
    eps = np.array([[a, c / 2], [c / 2, 0.0]])
    sigma = lmbda * np.trace(eps) * np.eye(2) + two_mu * eps
    raw = paper_raw()
    del raw["contact"]
    raw["material"] = {"E": E, "nu": nu}
    raw["mesh"] = {"L1": 1.0, "L2": 1.0, **mesh}
    raw["loads"] = {"traction": {"right": sigma @ [1, 0], "top": sigma @ [0, 1],
                                 "bottom": sigma @ [0, -1]}}
    raw["loads"] = {"traction": {k: [float(x) for x in v]
                                 for k, v in raw["loads"]["traction"].items()}}
    raw["time"] = {"T": 1.0, "N": 1}
    res = run_case(make_case(raw))
    p = res.problem
    assert res.status == "completed" and res.history is None and p.H is None
    x = p.disc.V.tabulate_dof_coordinates()[:, :2]
    exact = np.column_stack([a * x[:, 0], c * x[:, 0]])
    u = p.u.x.array.reshape(-1, 2)
    assert np.abs(u - exact).max() <= 1e-12 * np.abs(exact).max()
    s = p.sigma.x.array.reshape(-1, 2, 2)
    assert np.abs(s - sigma).max() <= 1e-10 * np.abs(sigma).max()
