"""The Gamma3 quadrature option: the Gauss rule solves a slightly different discrete problem
(consistent to O(h^2)), so it must converge and stay close to the nodal (vertex) rule."""
import numpy as np

from conftest import paper_raw, run_case, validate_raw
from vpcontact.post.quantities import contact_table


def _final(quadrature, degree=2):
    raw = paper_raw()
    raw["time"]["N"] = 4
    raw["solver"].update({"quadrature": quadrature, "gauss_degree": degree})
    res = run_case(validate_raw(raw))
    assert res.status == "completed"
    return res.summary["steps"][-1], contact_table(res.problem)


def test_gauss_rule_is_close_to_vertex_rule():
    sv, tv = _final("vertex")
    sg, tg = _final("gauss", 3)
    for key in ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y"):
        assert abs(sg[key] - sv[key]) <= 1e-3 * abs(sv[key]), key
    du = np.abs(tg["u_x"] - tv["u_x"]).max() / np.abs(tv["u_x"]).max()
    assert 1e-12 < du < 2e-2   # different rules, close solutions
    assert np.all(tg["u_nu"] <= 0.012 * (1 + 1e-12))
