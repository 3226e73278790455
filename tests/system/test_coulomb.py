"""Coulomb friction against the rigid foundation (contact.friction.coulomb: the bound mu p_n,
p_n by a fixed point in each step) on an elastic block (h = 1/4, nu = 0, normal compliance,
2 steps):

- stick: a uniform pressure P on top and a shear Q = mu P / 2 on the top and right side
  (the left side held at the exact uniform state): the closed form is sigma_yy = -P,
  sigma_xy = Q, p_n = P, and every contact node sticks with mu P rho / |rho|_delta = Q, i.e.
  u_tau = rho = delta s / sqrt(1 - s^2), s = Q / (mu P);
- slide: the left side pushed by U = 0.05 (500000 delta): every contact node slides, its
  friction stress is the bound mu p_n with p_n its own -sigma_nu;
- law (4.2) with b = mu P, c1 = c2 = 0 (the constant friction stress tau = mu P) gives the
  stick run (p_n = P at every node);
- the condensed solver equals SNES VI on the slide run (p_n varies along Gamma3);
- the refusals, and a fixed point that does not converge fails the step.
"""
import copy
import re

import numpy as np
import pytest

from conftest import make_case, paper_raw, run_case
from vpcontact.io.errors import CaseError
from vpcontact.model.coulomb import MAX_ITERATIONS, CoulombPressure
from vpcontact.post.quantities import contact_table
from vpcontact.solvers.snesvi import StepSolveError

P, MU, E, C_NU, DELTA = 8.0, 0.3, 1000.0, 100.0, 1e-7
Q = 0.5 * MU * P
U = 0.05


def _raw(scene: str, friction: dict | None = None) -> dict:
    raw = paper_raw()
    raw["material"] = {"E": E, "nu": 0.0}
    raw["contact"] = {"normal_compliance": {"c_nu": C_NU},
                      "friction": friction or {"coulomb": {"mu": MU}}}
    raw["boundaries"] = {"clamped": []}
    u_y = f"{-P / C_NU!r} - {P / E!r} * y"        # u_nu = P / c_nu, eps_yy = -P / E
    if scene == "stick":
        rho = DELTA * 0.5 / np.sqrt(0.75)          # s = Q / (mu P) = 1/2
        raw["loads"] = {"f0": [0.0, 0.0], "traction": {"top": [Q, -P], "right": [0.0, Q]},
                        "displacement": {"left": [f"{rho!r} + {2 * Q / E!r} * y", u_y]}}
    else:
        raw["loads"] = {"f0": [0.0, 0.0], "traction": {"top": [0.0, -P]},
                        "displacement": {"left": [f"{U} * t", u_y]}}
    return raw


def _run(scene: str, method: str = "snes_vi", friction: dict | None = None):
    case = make_case(_raw(scene, friction), mesh={"n": 4}, time={"N": 2},
                     solver={"method": method})
    result = run_case(case)
    assert result.status == "completed"
    return result


@pytest.fixture(scope="module")
def runs():
    return {"stick": _run("stick"), "slide": _run("slide"),
            "slide_condensed": _run("slide", "condensed")}


def test_stick_below_mu_p(runs):
    """Q = mu P / 2: p_n = P, sigma_tau = Q and u_tau = rho (the closed form) at every free
    contact node; all stick."""
    tab = contact_table(runs["stick"].problem)
    free = ~tab["_prescribed"]
    assert free.sum() >= 3
    rho = DELTA * 0.5 / np.sqrt(0.75)
    assert np.abs(tab["neg_sigma_nu"][free] - P).max() <= 1e-8 * P
    assert np.abs(tab["neg_sigma_tau"][free] - Q).max() <= 1e-8 * P
    assert np.abs(tab["u_tau"][free] - rho).max() <= 1e-6 * rho
    assert np.all(tab["slip_state"][free] == 0.0)


def test_slide_at_mu_p(runs):
    """The pushed block slides: |u_tau| > 1e5 delta (rho < delta when sticking), and the
    friction stress is mu times the node's own pressure; all slip."""
    tab = contact_table(runs["slide"].problem)
    free = ~tab["_prescribed"]
    assert np.abs(tab["u_tau"][free]).min() > 1e5 * DELTA
    pn = tab["neg_sigma_nu"][free]
    assert np.ptp(pn) > 1e-2 * P                     # p_n varies: the fixed point matters
    assert np.abs(np.abs(tab["neg_sigma_tau"][free]) - MU * pn).max() <= 1e-7 * MU * P
    assert np.all(tab["slip_state"][free] == 1.0)


def test_constant_table_equals_coulomb_at_uniform_pressure(runs):
    """p_n = P at every node: law (4.2) with b = mu P, c1 = c2 = 0 (psi = mu P rho) gives
    the Coulomb run to 1e-10."""
    table = _run("stick", friction={"b": MU * P, "c1": 0.0, "c2": 0.0, "u1": 1.0})
    a, b = runs["stick"].problem.u.x.array, table.problem.u.x.array
    assert np.abs(a - b).max() <= 1e-10 * np.abs(b).max()


def test_condensed_equals_snes_vi(runs):
    """The condensed solver equals SNES VI on the slide run to 1e-8."""
    a = runs["slide_condensed"].problem.u.x.array
    b = runs["slide"].problem.u.x.array
    assert np.abs(a - b).max() <= 1e-8 * np.abs(b).max()


@pytest.mark.parametrize("change, key", [
    ({"friction": {"coulomb": {"mu": MU}, "b": 1.0}}, "contact.friction.b"),
    ({"friction": {"coulomb": {"mu": MU}, "table": [[0.0, 1.0], [1.0, 1.0]]}},
     "contact.friction.table"),
    ({"friction": {"coulomb": {"mu": MU}, "law": "python", "class": "X"}},
     "contact.friction.law"),
    ({"friction": {"coulomb": {"mu": -0.1}}}, "contact.friction.coulomb.mu"),
    ({"normal_compliance": None}, "contact.friction.coulomb"),
])
def test_refusals(change, key):
    """One line naming the key."""
    raw = _raw("stick")
    for k, v in copy.deepcopy(change).items():
        if v is None:
            raw["contact"].pop(k)
        else:
            raw["contact"][k] = v
    with pytest.raises(CaseError) as err:
        make_case(raw)
    msg = str(err.value)
    assert "\n" not in msg and re.search(rf"{re.escape(key)}( \(line \d+\))?:", msg), msg


def test_fixed_point_that_does_not_converge_fails_the_step():
    """A pressure that alternates between two values: StepSolveError after MAX_ITERATIONS
    solves, naming Coulomb friction."""
    class Comm:
        def allreduce(self, x, op=None):
            return x

    class Solver:
        calls = 0

        def solve(self):
            Solver.calls += 1
            return 1

    fp = CoulombPressure.__new__(CoulombPressure)
    fp.problem = type("Problem", (), {"comm": Comm()})()
    fp.mu, fp.p, fp.iterations = MU, np.zeros(3), 0
    fp.measure = lambda: np.full(3, 1.0 + Solver.calls % 2)
    with pytest.raises(StepSolveError, match="Coulomb friction: the fixed point"):
        fp.solve(Solver(), lambda mu_p: None)
    assert Solver.calls == MAX_ITERATIONS
