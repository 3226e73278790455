"""The full model: memory term, slip dependence, time-dependent loads, initial
values, non-uniform time grids; terms that are off allocate nothing."""
import copy

import numpy as np
import pytest

from conftest import ROOT, paper_raw, run_case, validate_raw
from vpcontact.case import CaseError, load_case
from vpcontact.post.quantities import contact_table

CASES = ROOT / "cases"


def _raw(name):
    from vpcontact.case import load_raw
    return load_raw(CASES / f"{name}.yaml")


def _final(res):
    tab = contact_table(res.problem)
    return np.column_stack([tab["u_x"], tab["u_y"]]), \
        np.array([[s[k] for k in ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y")]
                  for s in res.summary["steps"]])


def _same(a, b, rtol=1e-10):
    (ua, na), (ub, nb) = a, b
    assert np.abs(ua - ub).max() <= rtol * np.abs(ub).max()
    np.testing.assert_allclose(na, nb, rtol=rtol)


# ----------------------------------------------------------------------------- memory
def test_b0_zero_equals_no_memory():
    raw = _raw("memory")
    raw["contact"]["memory"]["b0"] = 0.0
    with_mem = run_case(validate_raw(raw))
    assert with_mem.gamma3_history.memory is not None
    del raw["contact"]["memory"]
    without = run_case(validate_raw(raw))
    assert without.gamma3_history is None and without.problem.xi is None
    assert not any("memory" in t for t in without.problem.forms.terms)
    _same(_final(with_mem), _final(without), rtol=1e-12)


def test_memory_changes_the_solution_and_direct_sum_agrees():
    raw = _raw("memory")
    rec = run_case(validate_raw(raw))
    assert rec.gamma3_history.memory.recursion and rec.gamma3_history.memory.stored_steps == 0
    raw["contact"]["memory"]["sum"] = "direct"
    direct = run_case(validate_raw(raw))
    assert not direct.gamma3_history.memory.recursion
    assert direct.gamma3_history.memory.stored_steps == 16
    _same(_final(rec), _final(direct), rtol=1e-10)
    del raw["contact"]["memory"]
    ua, _ = _final(rec)
    ub, _ = _final(run_case(validate_raw(raw)))
    assert np.abs(ua - ub).max() > 1e-4     # the memory force is felt


def _memory_complementarity(res):
    case, p = res.problem.case, res.problem
    c_nu, g, delta = case.contact.c_nu, case.contact.g, case.numerics.delta
    tab = contact_table(p)
    u_nu, f, xi = tab["u_nu"], tab["neg_sigma_nu"], tab["xi"]
    tol = 1e-7 * c_nu * g
    assert np.all(u_nu <= g * (1 + 1e-12)) and np.all(xi >= 0)
    bound = u_nu >= g * (1 - 1e-9)
    inside = (u_nu > 10 * delta) & ~bound
    zero = np.abs(u_nu) <= 10 * delta
    apart = u_nu < -10 * delta
    np.testing.assert_allclose(f[inside], c_nu * u_nu[inside] + xi[inside], atol=tol)
    assert np.all(f[bound] >= c_nu * g + xi[bound] - tol)
    assert np.all((f[zero] >= -tol) & (f[zero] <= xi[zero] + tol))
    assert np.all(np.abs(f[apart]) <= tol + xi[apart] * 1e-6)
    return {"bound": bound.sum(), "inside": inside.sum(), "zero": zero.sum(),
            "apart": apart.sum()}


def test_memory_complementarity_push_then_pull():
    """Pressed, then pulled away: the memory force is xi where u_nu > 0, in [0, xi] at
    u_nu = 0, and vanishes once the node separates (xi stays > 0 from the past)."""
    raw = _raw("memory")
    raw["loads"]["traction"]["top"] = [0.0, {"table": [[0, -8.0], [0.5, -8.0], [0.75, 6.0]]}]
    raw["time"]["N"] = 12
    raw["contact"]["memory"]["b0"] = 300.0
    counts = _memory_complementarity(run_case(validate_raw(raw)))
    assert counts["apart"] > 0
    counts = _memory_complementarity(run_case(validate_raw(_raw("memory"))))
    assert counts["inside"] > 0 and counts["bound"] > 0


# ----------------------------------------------------------------------------- slip
def test_theta_inf_one_equals_plain_friction():
    raw = _raw("slip_weakening")
    raw["contact"]["friction"]["slip"]["theta_inf"] = 1.0
    res = run_case(validate_raw(raw))
    assert res.gamma3_history.slip is not None and res.gamma3_history.memory is None
    assert np.all(res.problem.theta.function.x.array[res.problem.theta.dofs] == 1.0)
    del raw["contact"]["friction"]["slip"]
    plain = run_case(validate_raw(raw))
    assert plain.gamma3_history is None and plain.problem.theta is None
    _same(_final(res), _final(plain), rtol=1e-12)


def test_slip_weakening_follows_theta():
    res = run_case(validate_raw(_raw("slip_weakening")))
    g3, tab = res.gamma3_history, contact_table(res.problem)
    fr = res.problem.case.contact.friction
    s = g3.slip.s
    assert np.all(s > 0)
    r = np.abs(tab["u_tau"])
    dpsi = np.where(r <= fr.u1, fr.b - fr.c1 * r, fr.c2 * (r - fr.u1) + fr.b - fr.c1 * fr.u1)
    np.testing.assert_allclose(np.abs(tab["neg_sigma_tau"]), tab["theta"] * dpsi, rtol=1e-6)
    assert tab["theta"].min() < 0.5          # weakened


# ----------------------------------------------------------------------------- loads, time
def test_table_and_expression_loads_equal_constants():
    base = run_case(validate_raw(_time_raw(N=4)))
    raw = _time_raw(N=4)
    raw["loads"]["traction"]["top"] = ["0", {"table": [[0.0, -8.0], [2.0, -8.0]]}]
    raw["loads"]["traction"]["right"] = ["-3.2 + 0*x*t", "sin(0)"]
    _same(_final(run_case(validate_raw(raw))), _final(base), rtol=1e-12)


def test_time_dependent_load_is_applied_at_t_n():
    """A load ramp -8 t: the elastic response at t_n must equal a constant load -8 t_n."""
    raw = _time_raw(N=2, elastic=True)
    raw["loads"]["traction"]["top"] = [0.0, "-8*t"]
    ramp = run_case(validate_raw(raw))
    raw["loads"]["traction"]["top"] = [0.0, -8.0]
    raw["time"] = {"T": 1.0, "N": 1}
    const = run_case(validate_raw(raw))
    _same((_final(ramp)[0], _final(ramp)[1][-1:]), (_final(const)[0], _final(const)[1]),
          rtol=1e-9)


def _time_raw(N, elastic=False):
    raw = paper_raw()
    raw["time"] = {"T": 1.0, "N": N}
    if elastic:
        del raw["material"]["viscoplastic"]
    return raw


def test_time_grids():
    c = validate_raw({**_time_raw(4), "time": {"T": 1.0, "k": 0.25}})
    assert c.time.times == (0.0, 0.25, 0.5, 0.75, 1.0) and c.time.uniform
    c = validate_raw({**_time_raw(4), "time": {"times": [0, 0.1, 0.5, 1.0]}})
    assert c.time.N == 3 and c.time.T == 1.0 and not c.time.uniform
    c = validate_raw({**_time_raw(4), "time": {"T": 1.0, "N": 3, "grading": 2.0}})
    k = np.diff(c.time.times)
    np.testing.assert_allclose(k, [1 / 7, 2 / 7, 4 / 7]) and not c.time.uniform
    for bad, key in [({"T": 1.0, "N": 2, "k": 0.5}, "time"), ({"times": [0.1, 1.0]}, "time.times"),
                     ({"times": [0, 0.5, 0.5]}, "time.times"), ({"T": 1.0, "k": 0.3}, "time.k"),
                     ({"times": [0, 1], "N": 1}, "time.N"), ({"N": 4}, "time.T")]:
        with pytest.raises(CaseError, match=key.replace(".", r"\.")):
            validate_raw({**_time_raw(4), "time": bad})


def test_nonuniform_grid_equals_uniform_when_the_points_agree():
    """The same points given as a list give the same run as N; a graded grid runs."""
    a = run_case(validate_raw({**_time_raw(4), "time": {"T": 1.0, "N": 4}}))
    b = run_case(validate_raw({**_time_raw(4), "time": {"times": [0, 0.25, 0.5, 0.75, 1.0]}}))
    _same(_final(a), _final(b), rtol=1e-12)
    g = run_case(validate_raw({**_time_raw(4), "time": {"T": 1.0, "N": 6, "grading": 0.7}}))
    assert g.status == "completed"
    assert [s["t"] for s in g.summary["steps"]][-1] == pytest.approx(1.0)


# ----------------------------------------------------------------------------- initial values
def _free_elastic(dim=2):
    raw = paper_raw()
    del raw["contact"]
    del raw["material"]["viscoplastic"]
    raw["loads"] = {}
    raw["time"] = {"T": 1.0, "N": 1}
    raw["mesh"]["n"] = 4
    return raw


def test_initial_displacement_is_kept_without_loads():
    """H_0 = sigma0 - E eps(u0): with no loads the step solution is u_1 = u0 exactly."""
    raw = _free_elastic()
    raw["initial"] = {"u0": ["0.01*x*y", "0.02*x**2"]}
    res = run_case(validate_raw(raw))
    p = res.problem
    x = p.disc.V.tabulate_dof_coordinates()
    u0 = np.column_stack([0.01 * x[:, 0] * x[:, 1], 0.02 * x[:, 0] ** 2])
    np.testing.assert_allclose(p.u.x.array.reshape(-1, 2), u0, atol=1e-13)


def test_initial_stress_with_matching_tractions():
    """sigma0 = S uniform, tractions S n on the free sides: u_1 = 0, sigma_1 = S."""
    S = np.array([[2.0, -1.0], [-1.0, 3.0]])
    raw = _free_elastic()
    raw["initial"] = {"sigma0": S.tolist()}
    raw["loads"] = {"traction": {"right": list(S @ [1, 0]), "top": list(S @ [0, 1]),
                                 "bottom": list(S @ [0, -1])}}
    raw["loads"] = {"traction": {k: [float(v) for v in vs]
                                 for k, vs in raw["loads"]["traction"].items()}}
    p = run_case(validate_raw(raw)).problem
    assert np.abs(p.u.x.array).max() < 1e-13
    np.testing.assert_allclose(p.sigma.x.array.reshape(-1, 2, 2), np.broadcast_to(S, (32, 2, 2)),
                               atol=1e-11)


def test_kappa0_expression():
    raw = paper_raw()
    raw["material"]["viscoplastic"]["kappa0"] = "5 + 2*x"
    raw["time"] = {"T": 1.0, "N": 1}
    res = run_case(validate_raw(raw))
    # kappa_1 = kappa_0 + k Gk(sigma_0 = 0, kappa_0) = kappa_0: the cell averages of 5 + 2x
    msh = res.problem.disc.mesh
    x = msh.geometry.x
    dm = msh.geometry.dofmap
    cx = np.array([x[dm.links(c)][:, 0].mean() for c in range(res.problem.disc.num_owned_cells)])
    np.testing.assert_allclose(res.history.kappa.x.array[:len(cx)], 5 + 2 * cx, rtol=1e-12)


@pytest.mark.parametrize("patch,pattern", [
    ({"loads": {"traction": {"top": [0, 0, -8]}}}, r"loads\.traction\.top: expected 2"),
    ({"loads": {"traction": {"top": [0, "sin(q)"]}}},
     r"loads\.traction\.top\[1\]: unknown name 'q'"),
    ({"loads": {"traction": {"top": [0, "__import__('os')"]}}}, r"top\[1\]: function not allowed"),
    ({"loads": {"traction": {"front": [0, 1]}}}, r"loads\.traction\.front: no such side in 2D"),
    ({"initial": {"u0": ["t", 0]}}, r"initial\.u0\[0\]: unknown name 't'"),
    ({"initial": {"sigma0": [[1, 2], [3, 4]]}}, r"sigma0: must be symmetric"),
    ({"contact": {"memory": {"b0": 1.0, "kernel": "power"}}}, r"contact\.memory\.alpha: required"),
    ({"contact": {"memory": {"b0": 1.0, "kernel": "power", "alpha": 1, "tau": 1,
                             "sum": "recursion"}}}, r"contact\.memory\.sum"),
    ({"contact": {"friction": {"b": 1, "c1": 1, "c2": 1, "u1": 0.1, "slip": {"theta_inf": 2,
                                                                        "s0": 1}}}},
     r"contact\.friction\.slip\.theta_inf"),
])
def test_new_keys_are_validated(patch, pattern):
    raw = copy.deepcopy(dict(paper_raw()))   # no YAML line numbers in the messages
    for section, value in patch.items():
        raw[section] = {**raw.get(section, {}), **value}
    with pytest.raises(CaseError, match=pattern):
        validate_raw(raw)


def test_initial_u0_must_be_admissible():
    raw = paper_raw()
    raw["initial"] = {"u0": ["0", "-0.02*x"]}      # u_nu = 0.02 x > g near x = 1
    raw["time"] = {"T": 1.0, "N": 1}
    with pytest.raises(CaseError, match=r"initial\.u0: violates u_nu <= g"):
        run_case(validate_raw(raw))
    raw["initial"] = {"u0": ["1 + x", "0"]}
    with pytest.raises(CaseError, match=r"initial\.u0: must vanish on Gamma1"):
        run_case(validate_raw(raw))


def test_cases_load():
    for name in ("memory", "slip_weakening", "box3d"):
        assert load_case(CASES / f"{name}.yaml").name == name
