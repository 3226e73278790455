"""Whole runs with the general contact laws (contact.normal_compliance.table / m / c_nu(x),
contact.friction.table, contact.friction.slip.table, contact.memory.b0(x)) on the paper's
scene (h = 1/4, 8 steps): tables that sample (4.1)/(4.2) at their kinks give the built-in
laws' runs to 1e-12 with both step solvers; c_nu and b0 given as constant expressions give
the number's run; a finely sampled theta(s) stays close to the exponential one; the
condensed solver equals SNES VI to 1e-8 with a nonmonotone friction table in 3D (the 2D
check is the shipped case cases/friction_table.yaml in test_scenes.py)."""
import copy

import numpy as np
import pytest

from conftest import make_case, paper_raw, run_case
from vpcontact.model.contact_laws import PowerCompliance, TableCompliance, TableFriction
from vpcontact.model.contactregistry import contact_law
from vpcontact.post.quantities import contact_table

SMALL = {"mesh": {"n": 4}, "time": {"N": 8}}
FRICTION_42 = [[0.0, 1.0], [0.01, 0.4], [0.02, 1.0]]          # (4.2): b, c1, c2, u1 of Sec. 4
COMPLIANCE_41 = [[0.0, 0.0], [0.024, 2.4]]                     # (4.1): c_nu = 100 up to 2 g


def _run(method, contact=None, raw=None, **sections):
    raw = copy.deepcopy(raw if raw is not None else paper_raw())
    for key, value in (contact or {}).items():
        raw["contact"][key] = copy.deepcopy(value)
    sec = copy.deepcopy(SMALL)
    sec.update(copy.deepcopy(sections))
    sec.setdefault("solver", {})["method"] = method
    result = run_case(make_case(raw, **sec))
    assert result.status == "completed"
    return result


def _fields(result):
    p = result.problem
    tab = contact_table(p)
    return {"u": p.u.x.array.copy(), "sigma": p.sigma.x.array.copy(),
            "kappa": p.state.kappa.x.array.copy(),
            **{k: v for k, v in tab.items() if k.startswith("neg_sigma")}}


def _difference(a, b) -> float:
    """The largest relative difference of the final fields and every step's norms."""
    fa, fb = _fields(a), _fields(b)
    out = max(np.abs(fa[k] - fb[k]).max() / np.abs(fb[k]).max() for k in fa)
    for key in ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y"):
        na = np.array([s[key] for s in a.summary["steps"]])
        nb = np.array([s[key] for s in b.summary["steps"]])
        assert len(na) == len(nb) and np.abs(nb).max() > 0
        out = max(out, np.abs(na - nb).max() / np.abs(nb).max())
    return out


@pytest.fixture(scope="module")
def paper_runs():
    return {m: _run(m) for m in ("snes_vi", "condensed")}


@pytest.mark.parametrize("method", ["snes_vi", "condensed"])
def test_tables_sampling_the_paper_laws_give_the_paper_run(paper_runs, method):
    """Friction table [[0, b], [u1, b - c1 u1], [2 u1, b - c1 u1 + c2 u1]] and compliance
    table [[0, 0], [2 g, 2 c_nu g]]: the paper's run to 1e-12 (fields at T, norms of every
    step), the laws being the table classes (not the built-in ones)."""
    tables = _run(method, {"normal_compliance": {"table": COMPLIANCE_41},
                           "friction": {"table": FRICTION_42}})
    law = contact_law(tables.problem.case.contact, 1e-7)
    assert isinstance(law.normal, TableCompliance) and isinstance(law.friction, TableFriction)
    diff = _difference(tables, paper_runs[method])
    print(f"{method}: tables vs (4.1)-(4.2): max relative difference {diff:.2e}")
    assert diff <= 1e-12


@pytest.mark.parametrize("method", ["snes_vi", "condensed"])
def test_expression_c_nu_and_m1_give_the_number_run(paper_runs, method):
    """c_nu: '100 + 50 * y' with m: 1 (a field c_nu(x) (r^+)^m, 100 on Gamma3 = {y = 0},
    where the nodal rule evaluates it): the number's run to 1e-12 (condensed: numpy's
    nodal problem with c_nu per node; SNES VI: the UFL expression of x)."""
    field = _run(method, {"normal_compliance": {"c_nu": "100 + 50 * y", "m": 1}})
    law = contact_law(field.problem.case.contact, 1e-7, x=np.zeros((3, 2)))
    assert isinstance(law.normal, PowerCompliance) and law.normal.c_nu.tolist() == [100.0] * 3
    diff = _difference(field, paper_runs[method])
    print(f"{method}: c_nu(x) = 100 + 50 y, m = 1 vs c_nu = 100: {diff:.2e}")
    assert diff <= 1e-12


def test_varying_c_nu_condensed_equals_snes_vi():
    """c_nu(x) = 40 + 120 x varying along Gamma3: the condensed solver (c_nu at its nodes in
    G order) equals SNES VI (the UFL field) to 1e-8, and differs from the c_nu = 100 run."""
    contact = {"normal_compliance": {"c_nu": "40 + 120 * x"}}
    runs = [_run(m, contact) for m in ("snes_vi", "condensed")]
    diff = _difference(runs[1], runs[0])
    print(f"c_nu(x) = 40 + 120 x: condensed vs SNES VI {diff:.2e}")
    assert diff <= 1e-8
    assert _difference(runs[0], _run("snes_vi")) > 1e-4


def test_constant_expression_b0_gives_the_number_run():
    """contact.memory.b0: '50 + 7 * y' (b0(x) per node, 50 on Gamma3 = {y = 0}) gives the
    run of b0 = 50 to 1e-12."""
    memory = {"b0": 50.0, "beta": 2.0}
    number = _run("condensed", {"memory": memory})
    field = _run("condensed", {"memory": {**memory, "b0": "50 + 7 * y"}})
    assert contact_table(number.problem)["xi"].max() > 0        # the memory term acts
    diff = _difference(field, number)
    print(f"b0(x) = 50 + 7 y vs b0 = 50: {diff:.2e}")
    assert diff <= 1e-12


def test_fine_slip_table_is_close_to_the_exponential():
    """theta(s) sampled every 1e-5 m s (interpolation error <= h^2 (1 - theta_inf) /
    (8 s0^2) = 2.2e-6 of theta): the run stays within 1e-5 of the exponential law's."""
    theta_inf, s0, h = 0.3, 0.002, 1e-5
    s = np.arange(0.0, 0.05 + h / 2, h)
    theta = theta_inf + (1 - theta_inf) * np.exp(-s / s0)
    fr = paper_raw()["contact"]["friction"]
    exp = _run("condensed", {"friction": {**fr, "slip": {"theta_inf": theta_inf, "s0": s0}}})
    tab = _run("condensed", {"friction": {**fr, "slip": {
        "table": np.column_stack([s, theta]).tolist()}}})
    diff = _difference(tab, exp)
    print(f"slip table (h = {h:g}) vs exponential theta: {diff:.2e}")
    assert diff <= 1e-5


def test_3d_friction_table_condensed_equals_snes_vi():
    """A tiny box (h = 1/2, 2 steps) with a nonmonotone friction table and a compliance
    c_nu (r^+)^2: the condensed solver equals SNES VI to 1e-8."""
    from conftest import ROOT
    from vpcontact.case import load_raw
    raw = load_raw(ROOT / "cases" / "box3d.yaml")
    contact = {"normal_compliance": {"c_nu": 8000.0, "m": 2},
               "friction": {"table": [[0.0, 1.0], [0.005, 0.55], [0.01, 0.55],
                                      [0.02, 1.15]]}}
    runs = [_run(m, contact, raw, mesh={"n": 2}, time={"N": 2})
            for m in ("snes_vi", "condensed")]
    diff = _difference(runs[1], runs[0])
    print(f"3D friction table: condensed vs SNES VI {diff:.2e}")
    assert diff <= 1e-8


def test_a_friction_table_of_one_segment_with_snes_vi():
    """A constant friction table [[0, 1], [0.01, 1]] is law (4.2) with b = 1, c1 = c2 = 0:
    SNES VI gives its run to 1e-12 (its Jacobian form failed to compile in FFCx, 'LiteralFloat'
    has no attribute 'args', before the table's energy kept a conditional)."""
    flat = {"friction": {"table": [[0.0, 1.0], [0.01, 1.0]]}}
    law42 = {"friction": {"b": 1.0, "c1": 0.0, "c2": 0.0, "u1": 0.01}}
    assert _difference(_run("snes_vi", flat), _run("snes_vi", law42)) <= 1e-12
