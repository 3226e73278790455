"""Discrete complementarity of converged steps at every Gamma3 node (laws (4.1), (4.2)),
symmetry of the step Jacobian, and terms a case does not enable are not built."""
import numpy as np
from dolfinx import fem

from conftest import paper_raw, run_case, validate_raw
from vpcontact.post.quantities import contact_table


def dpsi(r, b, c1, c2, u1):
    """psi'(r) of law (4.2)."""
    return np.where(r <= u1, b - c1 * r, c2 * (r - u1) + b - c1 * u1)


def check_complementarity(res, stick_tol=1e-5):
    case, p = res.problem.case, res.problem
    c_nu, g, fr = case.contact.c_nu, case.contact.g, case.contact.friction
    tab = contact_table(p)
    u_nu, f_nu = tab["u_nu"], tab["neg_sigma_nu"]
    u_tau, f_tau = tab["u_tau"], tab["neg_sigma_tau"]
    scale = c_nu * g
    tol = 1e-7 * scale
    # admissibility u_nu <= g
    assert np.all(u_nu <= g * (1 + 1e-12))
    at_bound = u_nu >= g * (1 - 1e-9)
    separated = u_nu <= 0.0
    inside = ~at_bound & ~separated
    # (4.1): -sigma_nu = 0 (u_nu <= 0), c_nu u_nu (0 < u_nu < g), >= c_nu g (u_nu = g)
    assert np.all(np.abs(f_nu[separated]) <= tol)
    np.testing.assert_allclose(f_nu[inside], c_nu * u_nu[inside], atol=tol)
    assert np.all(f_nu[at_bound] >= c_nu * g - tol)
    # (4.2): -sigma_tau on the branch selected by |u_tau|; |.| <= b where u_tau ~ 0
    r = np.abs(u_tau)
    delta = case.numerics.delta
    slip = r > stick_tol
    expected = dpsi(r[slip], fr.b, fr.c1, fr.c2, fr.u1) * np.sign(u_tau[slip])
    # the regularisation changes the force by O(delta^2 / r^2) relative
    np.testing.assert_allclose(f_tau[slip], expected, rtol=1e-6 + (delta / stick_tol) ** 2,
                               atol=tol)
    assert np.all(np.abs(f_tau[~slip]) <= fr.b * (1 + 1e-9))
    return {"bound": int(at_bound.sum()), "compliance": int(inside.sum()),
            "separated": int(separated.sum()), "slip": int(slip.sum()),
            "stick": int((~slip).sum()), "beyond_u1": int((r >= fr.u1).sum())}


def test_paper_case_complementarity(paper_run):
    counts = check_complementarity(paper_run)
    # the paper's Fig. 3/4 story: part at the bound, part in compliance, all slipping,
    # part beyond u1
    assert counts["bound"] > 0 and counts["compliance"] > 0
    assert counts["slip"] == 16 and 0 < counts["beyond_u1"] < 16


def test_sticking_case_complementarity():
    """b large: every node sticks (|u_tau| ~ delta) and |sigma_tau| <= b."""
    raw = paper_raw()
    raw["contact"]["friction"]["b"] = 30.0
    raw["time"]["N"] = 4
    counts = check_complementarity(run_case(validate_raw(raw)))
    assert counts["stick"] == 16


def test_separation_and_compliance():
    """A pull-up load separates part of Gamma3; a large g is never reached."""
    raw = paper_raw()
    raw["loads"]["traction"]["top"] = [0.0, 2.0]
    raw["contact"]["g"] = 1.0
    raw["time"]["N"] = 2
    counts = check_complementarity(run_case(validate_raw(raw)))
    assert counts["separated"] > 0 and counts["bound"] == 0


def test_jacobian_is_symmetric(paper_run):
    """J_n is the Hessian of an energy: the assembled Jacobian must be symmetric."""
    p = paper_run.problem
    A = fem.petsc.assemble_matrix(p.J_form, bcs=p.disc.bcs)
    A.assemble()
    assert A.isSymmetric(tol=1e-10 * A.norm())
    A.destroy()


def test_disabled_terms_are_not_built():
    raw = paper_raw()
    del raw["contact"]["friction"]
    del raw["material"]["viscoplastic"]
    raw["time"]["N"] = 1
    res = run_case(validate_raw(raw))
    p = res.problem
    assert res.history is None and p.H is None
    assert not any("friction" in t for t in p.forms.terms)
    assert "pre-stress H_n" not in p.forms.terms
    assert "delta" not in p.constants and "b" not in p.constants
    assert "normal compliance" in p.forms.terms
