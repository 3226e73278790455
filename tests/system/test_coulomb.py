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
- the refusals, and a fixed point that does not converge fails the step;
- static/kinetic (mu_s, mu_k, slip_length L): the slide run over 6 steps, every contact node's
  friction stress is mu(s_n) p_n with mu(s) = mu_s - (mu_s - mu_k) min(s / L, 1) and s_n =
  sum_{j<=n} k |u_{j-1,tau}| summed here from the recorded u_tau (mu_s p_n at the first
  step, s = 0; between and beyond L later); mu_s = mu_k is {mu} bit for bit; the run
  restarted from its step-3 checkpoint (p_n and s_n stored) is the uninterrupted run to
  1e-12; check names the law; the refusals of the pair.
"""
import copy
import json
import re

import numpy as np
import pytest
import yaml
from mpi4py import MPI

from conftest import cli_in_process, make_case, paper_raw, run_case
from vpcontact.io.checkpoint import Checkpoint
from vpcontact.io.errors import CaseError, StepSolveError
from vpcontact.model.coulomb import CoulombPressure
from vpcontact.observers import Checkpointer, Observer
from vpcontact.post.quantities import contact_table
from vpcontact.simulation import run
from vpcontact.solvers.coulomb import MAX_ITERATIONS, CoulombFixedPoint

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
    fp.problem = type("Problem", (), {"disc": type("Disc", (), {"comm": Comm()})()})()
    fp.mu, fp.p = MU, np.zeros(3)
    fp.measure = lambda: np.full(3, 1.0 + Solver.calls % 2)
    history = type("History", (), {"coulomb": fp, "set_coulomb_bound": lambda mu_p: None})
    with pytest.raises(StepSolveError, match="Coulomb friction: the fixed point"):
        CoulombFixedPoint(Solver(), history, 0.0).solve()
    assert Solver.calls == MAX_ITERATIONS


# ------------------------------------------------------------------ static/kinetic Coulomb
MU_S, MU_K, L_SLIP, N_SK = 0.5, 0.3, 0.01, 6
STATIC_KINETIC = {"coulomb": {"mu_s": MU_S, "mu_k": MU_K, "slip_length": L_SLIP}}


class _Tables(Observer):
    """contact_table after every accepted step."""

    def __init__(self):
        self.tables = []

    def step(self, sim, record):
        self.tables.append(contact_table(sim.problem))


def _mu(s):
    """mu(s) = mu_s - (mu_s - mu_k) min(s / L, 1)."""
    return MU_S - (MU_S - MU_K) * np.minimum(s / L_SLIP, 1.0)


@pytest.fixture(scope="module")
def static_kinetic(tmp_path_factory):
    """The slide run with mu_s, mu_k over 6 steps (checkpoint at step 3), each step's
    contact table, and the run restarted from the checkpoint."""
    out = tmp_path_factory.mktemp("static_kinetic")
    case = make_case(_raw("slide", STATIC_KINETIC), mesh={"n": 4}, time={"N": N_SK},
                     output={"checkpoint_every": 3})
    rec = _Tables()
    full = run(case, MPI.COMM_WORLD, [rec, Checkpointer()], outdir=out)
    assert full.status == "completed"
    ck = Checkpoint(out / "checkpoint_000003.npz")
    assert ck.check(case) is None
    again = _Tables()
    restarted = run(case, MPI.COMM_WORLD, [again], restart=ck)
    assert restarted.status == "completed"
    return case, rec.tables, full, restarted, again.tables


def test_static_kinetic_bound_follows_the_slip(static_kinetic):
    """|sigma_tau| = friction_bound = mu(s_n) p_n at every sliding node of every step, s_n
    summed from the recorded u_tau (left rectangle rule of (3.4)); s_n spans 0, (0, L) and
    beyond L."""
    case, tables = static_kinetic[:2]
    k = case.time.T / N_SK
    s = np.zeros(len(tables[0]["x"]))
    seen = []
    for tab in tables:
        free = ~tab["_prescribed"]
        pn = tab["neg_sigma_nu"][free]
        bound = _mu(s[free]) * pn
        assert np.abs(tab["friction_bound"][free] - bound).max() <= 1e-7 * MU_S * P
        assert np.abs(np.abs(tab["neg_sigma_tau"][free]) - bound).max() <= 1e-7 * MU_S * P
        assert np.all(tab["slip_state"][free] == 1.0)
        seen.append(s[free].copy())
        s = s + k * np.abs(tab["u_tau"])            # s_{n+1} = s_n + k |u_{n,tau}|
    assert np.all(seen[0] == 0.0)                   # first slip: mu_s p_n
    between = np.concatenate(seen)
    assert np.any((between > 0.1 * L_SLIP) & (between < 0.9 * L_SLIP))
    assert np.any(between > 1.1 * L_SLIP)


def test_static_kinetic_restart_equals_uninterrupted(static_kinetic):
    """The run restarted from its step-3 checkpoint (u, s_n and p_n restored) is the
    uninterrupted run to 1e-12: u and the friction bound at steps 4 to 6 (at step 4 a fixed
    point restarted from p_n = 0 stops elsewhere within its tolerance, ~1e-8), and u at the
    end."""
    _, tables, full, restarted, again = static_kinetic
    assert len(again) == N_SK - 3
    for ta, tb in zip(tables[3:], again):
        for col in ("u_x", "u_y", "friction_bound"):
            assert np.abs(ta[col] - tb[col]).max() <= 1e-12 * np.abs(ta[col]).max(), col
    a, b = full.problem.u.x.array, restarted.problem.u.x.array
    assert np.abs(a - b).max() <= 1e-12 * np.abs(a).max()


def test_slip_path_columns(static_kinetic):
    """slip_increment = |u_{n,tau} - u_{n-1,tau}| and slip_accumulated = its sum over the
    steps, from the recorded u_tau (u_0 = 0), to 1e-12 at every node of every step; the run
    restarted from the step-3 checkpoint (the path stored) writes the same columns to
    1e-12 of their largest value."""
    _, tables, _, _, again = static_kinetic
    prev = np.zeros(len(tables[0]["x"]))
    total = np.zeros_like(prev)
    for tab in tables:
        inc = np.abs(tab["u_tau"] - prev)
        total = total + inc
        assert np.abs(tab["slip_increment"] - inc).max() <= 1e-12 * U
        assert np.abs(tab["slip_accumulated"] - total).max() <= 1e-12 * U
        prev = tab["u_tau"]
    assert total.min() > 0.5 * U                   # every node slid about U
    for ta, tb in zip(tables[3:], again):
        for col in ("slip_increment", "slip_accumulated"):
            assert np.abs(ta[col] - tb[col]).max() <= 1e-12 * np.abs(ta[col]).max(), col


def test_equal_coefficients_are_coulomb_mu(runs):
    """mu_s = mu_k = mu: the run is the {mu} run bit for bit (theta(s) = 1 exactly)."""
    same = _run("slide", friction={"coulomb": {"mu_s": MU, "mu_k": MU, "slip_length": 1e-3}})
    assert np.array_equal(same.problem.u.x.array, runs["slide"].problem.u.x.array)


def _case_file(tmp_path, friction: dict) -> str:
    raw = _raw("slide", friction)
    raw["mesh"]["n"], raw["time"]["N"] = 4, 2
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(json.loads(json.dumps(raw))))
    return str(path)


def test_check_names_the_static_kinetic_law(tmp_path, capsys):
    """check lists the term and the law with mu_s, mu_k and the slip length."""
    assert cli_in_process(["check", _case_file(tmp_path, STATIC_KINETIC)]) == 0
    out = capsys.readouterr().out
    assert "Coulomb friction mu(s) p_n (mu_s = 0.5, mu_k = 0.3 over slip length 0.01 m s)" \
        in out
    assert "mu_s = 0.5, mu_k = 0.3, slip_length = 0.01 m s" in out


@pytest.mark.parametrize("coulomb, slip, key", [
    ({"mu": 0.3, "mu_s": 0.5, "mu_k": 0.3, "slip_length": L_SLIP}, False,
     "contact.friction.coulomb.mu_s"),
    ({"mu_s": 0.5, "mu_k": 0.3}, False, "contact.friction.coulomb.slip_length"),
    ({"mu_s": 0.3, "mu_k": 0.5, "slip_length": L_SLIP}, False,
     "contact.friction.coulomb.mu_s"),
    ({"mu_s": 0.5, "mu_k": -0.1, "slip_length": L_SLIP}, False,
     "contact.friction.coulomb.mu_k"),
    ({"mu_s": 0.5, "mu_k": 0.3, "slip_length": 0.0}, False,
     "contact.friction.coulomb.slip_length"),
    ({"mu_s": 0.5, "mu_k": 0.3, "slip_length": L_SLIP}, True, "contact.friction.slip"),
    ({}, False, "contact.friction.coulomb.mu"),
])
def test_static_kinetic_refusals(coulomb, slip, key, tmp_path, capsys):
    """check refuses with one line naming the key (exit code 2), before computing."""
    friction = {"coulomb": coulomb, **({"slip": {"theta_inf": 0.5, "s0": 0.01}} if slip
                                       else {})}
    assert cli_in_process(["check", _case_file(tmp_path, friction)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and re.search(rf"{re.escape(key)}( \(line \d+\))?:", err[0]), err


@pytest.mark.parametrize("verbose", [False, True])
def test_fixed_point_line_only_with_verbose(verbose, tmp_path, capsys):
    """The per-step line of the converged fixed point is a --verbose line: a run at the
    default level prints none of them, with --verbose one per step."""
    out = tmp_path / "out"
    args = ["run", _case_file(tmp_path, {"coulomb": {"mu": MU}}), "--out", out, "--no-plots"]
    assert cli_in_process(args + (["--verbose"] if verbose else [])) == 0
    lines = [x for x in capsys.readouterr().out.splitlines()
             if "Coulomb friction: the fixed point" in x]
    assert len(lines) == (2 if verbose else 0), lines


# ------------------------------------------------------------------ a held node in Gamma3
@pytest.fixture(scope="module")
def held_corner():
    """The slide run with the right side pushed as the left, by u_x = U t (u_y free): the
    corner (1, 0) of Gamma3 is held by the Dirichlet data in x, its normal free."""
    raw = _raw("slide")
    raw["loads"]["displacement"]["right"] = [f"{U} * t", None]
    rec = _Tables()
    result = run(make_case(raw, mesh={"n": 4}, time={"N": 2}), MPI.COMM_WORLD, [rec])
    assert result.status == "completed"
    return result, rec.tables[-1]


def test_held_corner_is_marked_and_carries_the_law_friction(held_corner):
    """The corner is marked held (1; 0 elsewhere), its u_nu free (not 'prescribed'); its
    written friction stress is the law's, mu p_n (it slides by U t = 5e5 delta: within
    (delta / U)^2 of the bound), not the support's reaction (-4.54 against a bound of 2.43
    before); it and every other node slide at mu p_n (slip_state 1)."""
    _, tab = held_corner
    corner = (np.abs(tab["x"] - 1.0) < 1e-12) & (np.abs(tab["y"]) < 1e-12)
    assert corner.sum() == 1 and not tab["_prescribed"][corner].any()
    np.testing.assert_array_equal(tab["held"], corner.astype(float))
    bound = MU * tab["neg_sigma_nu"][corner]
    assert abs(abs(tab["neg_sigma_tau"][corner][0]) - bound[0]) <= 1e-9 * bound[0]
    assert np.abs(tab["friction_bound"][corner] - bound).max() <= 1e-7 * MU * P
    assert np.all(tab["slip_state"] == 1.0)


def test_held_corner_totals(held_corner):
    """Every node slides against the push (-x), so the contact force on the body is
    F_x = -mu F_y (Coulomb, summed over the nodes with the corner's pressure and
    friction both in) to 1e-6, and the two sides' reactions balance it (equilibrium with
    the top's load (0, -P) to 1e-8)."""
    result, _ = held_corner
    step = result.summary["steps"][-1]
    fx, fy = step["contact_force"]
    assert abs(fx + MU * fy) <= 1e-6 * MU * fy
    left, right = step["reactions"]["left"], step["reactions"]["right"]
    assert abs(left[0] + right[0] + fx) <= 1e-8 * P and right[1] == 0.0
    assert abs(left[1] + fy - P) <= 1e-8 * P
