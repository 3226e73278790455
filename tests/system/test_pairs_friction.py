"""Coulomb friction between two elastic bodies (contact.pairs with friction.coulomb), against
closed forms:

- Cattaneo-Mindlin (cases/mindlin.yaml, coarsened: mesh.size = 4, one normal step and one
  shear step to Q ~ mu P / 2): a half cylinder pressed onto a block of the same E and nu
  (plane strain: the normal and the tangential problems uncouple), then sheared by
  Q < mu P with the depth held.  P and Q are the contact force on the cylinder, a and p0
  the Hertz values of P (R2 = inf, plane strain), c the half-width of the stick nodes
  (slip_state 0; each end halfway between the last stick node and the first slip node).
  c is a sqrt(1 - Q / (mu P)) within 5 % of a, at mesh.size 4 and 2 with the error
  falling; the shear traction follows Mindlin's q(x)
  (centred on the stick zone) within a measured bound; the slip nodes slip by more than
  1e3 delta (the regularisation |u_tau|_delta, delta = 1e-8 m, does not blur the stick
  zone's ends);
- a block on a block (tests/data/patch2d.geo, the lower one clamped at its bottom, the
  upper one's top pressed down, then pushed sideways): while every node sticks the
  tangential reaction Q < mu P and grows in proportion to the push (elastic); once every
  node slips Q = mu P to 1e-6 (the regularisation's error (delta / |u_tau|)^2 / 2 < 1e-10
  and the fixed point's 1e-8); pushed just past the onset of slip, a node that moved a few
  hundred delta reads slip, one that moved less than delta stick;
- static/kinetic friction {mu_s, mu_k, slip_length L} on the same blocks, pushed from all
  stick (Q < 0.75 mu_s P) to a gross slide in one step: Q = mu_s P at that step (to the
  drop (mu_s - mu_k) k max|u_tau| / L of the stick step's slip), mu_k P once the slip
  s = sum k |u_tau| exceeds L.
"""
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from conftest import make_case
from references.contact_closed_forms import hertz_cylinders, mindlin_shear, mindlin_stick_halfwidth
from vpcontact.case import load_raw
from vpcontact.observers import Observer
from vpcontact.post.quantities import contact_table
from vpcontact.simulation import run

ROOT = Path(__file__).parents[2]
E, NU, MU, DELTA = 1000.0, 0.3, 0.3, 1e-8


class _Tables(Observer):
    """contact_table after every accepted step."""

    def __init__(self):
        self.tables = []

    def step(self, sim, record):
        self.tables.append(contact_table(sim.problem))


def _run(raw: dict):
    """Run in this process; the summary's steps and each step's contact table."""
    rec = _Tables()
    result = run(make_case(raw), MPI.COMM_WORLD, [rec])
    assert result.status == "completed"
    return result.summary["steps"], rec.tables


# ------------------------------------------------------------------ Cattaneo-Mindlin
@pytest.fixture(scope="module")
def mindlin():
    return _mindlin(4.0)


@pytest.fixture(scope="module")
def mindlin_fine():
    return _mindlin(2.0)


def _mindlin(size: float) -> list[dict]:
    """cases/mindlin.yaml at mesh.size, pressed in one step and sheared in the next."""
    raw = load_raw(ROOT / "cases" / "mindlin.yaml")
    raw["mesh"].update({"file": str(ROOT / "cases" / "mindlin.geo"), "size": size})
    raw["time"]["N"] = 2                    # t = 1/2: pressed; 1: sheared
    for ramp in raw["loads"]["displacement"]["cylinder_top"]:
        assert ramp["table"][1][0] == 0.25 and len(ramp["table"]) == 3
        ramp["table"][1][0] = 0.5           # the end of the normal ramp
    assert raw["solver"]["delta"] == DELTA and raw["contact"]["pairs"][0]["friction"] == {
        "coulomb": {"mu": MU}}
    assert all(m == {"E": E, "nu": NU, "plane": "strain"}
               for m in raw["materials"].values())
    steps, tables = _run(raw)
    return [_measure(step, tab) for step, tab in zip(steps[1:], tables[1:])]


def _measure(step: dict, tab: dict) -> dict:
    """P, Q, the Hertz a and p0 of P, the stick zone's ends and the contact nodes."""
    Q, P = -step["contact_force"][0], step["contact_force"][1]
    a, p0 = hertz_cylinders(P, 1.0, float("inf"), E, NU, E, NU)
    order = np.argsort(tab["x"])
    t = {k: v[order] for k, v in tab.items()}
    touch = t["neg_sigma_nu"] > 1e-6 * t["neg_sigma_nu"].max()
    stick = np.flatnonzero(touch & (t["slip_state"] == 0))
    i, j = stick.min(), stick.max()
    return {"P": P, "Q": Q, "a": a, "p0": p0, "t": t, "touch": touch, "i": i, "j": j,
            "ends": ((t["x"][i - 1] + t["x"][i]) / 2, (t["x"][j] + t["x"][j + 1]) / 2)}


def test_mindlin_stick_halfwidth(mindlin):
    """One central stick zone flanked by two slip zones inside the contact; its half-width
    c = a sqrt(1 - Q / (mu P)) within 5 % of a at Q / (mu P) ~ 0.5 (measured: -2 %)."""
    (m,) = mindlin
    assert 0.45 < m["Q"] / (MU * m["P"]) < 0.55
    t, i, j = m["t"], m["i"], m["j"]
    assert (t["slip_state"][i:j + 1] == 0).all()               # one stick zone
    assert m["touch"][i - 2] and m["touch"][j + 2]               # slip zones on both sides
    assert (t["slip_state"][[i - 2, i - 1, j + 1, j + 2]] == 1).all()
    c = (m["ends"][1] - m["ends"][0]) / 2
    assert abs(c - mindlin_stick_halfwidth(m["a"], m["Q"], MU, m["P"])) <= 0.05 * m["a"]


def test_mindlin_shear_traction(mindlin):
    """The nodal friction stress against Mindlin's q(x) about the stick zone's centre:
    within 0.35 mu p0 at every contact node, 0.12 mu p0 root mean square (measured 0.28,
    0.10 at mesh.size = 4; 0.20, 0.075 at 2); the slip nodes slip by > 1e3 delta."""
    (m,) = mindlin
    t, touch = m["t"], m["touch"]
    c = mindlin_stick_halfwidth(m["a"], m["Q"], MU, m["P"])
    x = t["x"][touch] - sum(m["ends"]) / 2
    err = (t["neg_sigma_tau"][touch] - mindlin_shear(x, m["a"], c, m["p0"], MU)) / (
        MU * m["p0"])
    assert np.abs(err).max() <= 0.35 and np.sqrt(np.mean(err ** 2)) <= 0.12
    slip = touch & (t["slip_state"] == 1)
    assert np.abs(t["u_tau"][slip]).min() > 1e3 * DELTA


def test_mindlin_stick_halfwidth_falls_with_h(mindlin, mindlin_fine):
    """c from slip_state at mesh.size 4 and 2 (cells of 0.01 and 0.005 on the contact)
    against a sqrt(1 - Q / (mu P)): within 5 % of a at both, the error smaller on the finer
    mesh (measured -2.0 %, -1.3 %; before: -2.0 %, +1.2 %, the node that slid 705 delta
    read stick).  At both, every contact node whose u_tau exceeds 100 delta (the
    regularised law's stick branch ends near delta: rho = delta s / sqrt(1 - s^2)) reads
    slip and every one below 3 delta reads stick."""
    errors = []
    for (m,) in (mindlin, mindlin_fine):
        t, touch = m["t"], m["touch"]
        rho = np.abs(t["u_tau"])
        assert (t["slip_state"][touch & (rho > 100 * DELTA)] == 1).all()
        assert (t["slip_state"][touch & (rho < 3 * DELTA)] == 0).all()
        c = (m["ends"][1] - m["ends"][0]) / 2
        errors.append((c - mindlin_stick_halfwidth(m["a"], m["Q"], MU, m["P"])) / m["a"])
    assert max(abs(e) for e in errors) <= 0.05
    assert abs(errors[1]) < abs(errors[0])


# ------------------------------------------------------------------ a block on a block
def _blocks(friction: dict, N: int, push: float) -> dict:
    """patch2d.geo: the lower block clamped at its bottom (its top, the finer side, is the
    surface), the upper top pressed down by 0.01 in the first step, then pushed sideways
    by push in N - 1 equal steps."""
    t1 = 1.0 / N
    elastic = {"E": E, "nu": NU, "plane": "strain"}
    return {"mesh": {"file": str(ROOT / "tests" / "data" / "patch2d.geo"), "dim": 2},
            "materials": {"upper": elastic, "lower": elastic},
            "boundaries": {"clamped": ["lower_bottom"]},
            "contact": {"pairs": [{"surface": "lower_top", "target": "upper_bottom",
                                   "friction": friction}]},
            "loads": {"displacement": {"upper_top": [
                {"table": [[0.0, 0.0], [t1, 0.0], [1.0, push]]},
                {"table": [[0.0, 0.0], [t1, -0.01], [1.0, -0.01]]}]}},
            "time": {"T": 1.0, "N": N}, "solver": {"delta": DELTA}}


def _forces(steps: list) -> tuple[np.ndarray, np.ndarray]:
    """Q and P: the reaction of the upper top (tangential, normal: pressed)."""
    r = np.array([s["reactions"]["upper_top"] for s in steps])
    return r[:, 0], -r[:, 1]


def test_block_slides_only_when_q_reaches_mu_p():
    """Steps 2-3 every node sticks: Q < mu P, Q - Q(step 1) in proportion to the push (1e-4,
    measured 2e-5); step 4 partial slip, Q < mu P; steps 5-7 every node slips: Q = mu P to
    1e-6."""
    steps, tables = _run(_blocks({"coulomb": {"mu": MU}}, 7, 0.036))
    Q, P = _forces(steps)
    slips = [tab["slip_state"] for tab in tables]
    for n in (1, 2):
        assert not slips[n].any() and Q[n] < MU * P[n]
    assert abs((Q[2] - Q[0]) / (Q[1] - Q[0]) - 2.0) <= 1e-4     # linear elastic in the push
    assert 0 < slips[3].sum() < len(slips[3]) and Q[3] < MU * P[3]
    for n in (4, 5, 6):
        assert slips[n].all()
        assert abs(Q[n] / (MU * P[n]) - 1.0) <= 1e-6


def test_block_static_to_kinetic():
    """mu_s = 0.4, mu_k = 0.3, L = 2e-4, k = 0.2: step 2 every node sticks (Q < 0.75 mu_s
    P), step 3 every node slips at mu_s P, steps 4-5 at mu_k P (s > L)."""
    mu_s, mu_k, L, k = 0.4, 0.3, 2e-4, 0.2
    coulomb = {"coulomb": {"mu_s": mu_s, "mu_k": mu_k, "slip_length": L}}
    steps, tables = _run(_blocks(coulomb, 5, 0.061))
    Q, P = _forces(steps)
    assert not tables[1]["slip_state"].any() and Q[1] < 0.75 * mu_s * P[1]
    drop = (mu_s - mu_k) * k * np.abs(tables[1]["u_tau"]).max() / L
    assert tables[2]["slip_state"].all()
    assert mu_s - drop - 1e-6 * mu_s <= Q[2] / P[2] <= mu_s * (1 + 1e-6)
    assert (k * np.abs(tables[2]["u_tau"]) > L).all()
    for n in (3, 4):
        assert tables[n]["slip_state"].all()
        assert abs(Q[n] / (mu_k * P[n]) - 1.0) <= 1e-6


def test_block_edge_slide_reads_slip():
    """Pushed by 0.0164 in one step, just past the onset of slip: the nodes' tangential
    moves over the step, |u_tau(2) - u_tau(1)| from the recorded u_tau, span a stuck
    0.2 delta to 5e3 delta, one node (next to the slipping centre) a few hundred delta
    (measured 4e2: its friction stress within delta^2 / (2 rho^2) ~ 3e-6 of mu p_n, which
    the former test |q| >= (1 - 1e-6) mu p_n read as stick).  A move beyond 100 delta
    reads slip, one below 1 delta stick; slip_increment is that move."""
    _, tables = _run(_blocks({"coulomb": {"mu": MU}}, 2, 0.0164))
    move = np.abs(tables[1]["u_tau"] - tables[0]["u_tau"])
    assert ((move > 100 * DELTA) & (move < 700 * DELTA)).any()
    assert (move < DELTA).any()
    assert (tables[1]["slip_state"][move > 100 * DELTA] == 1).all()
    assert (tables[1]["slip_state"][move < DELTA] == 0).all()
    assert np.abs(tables[1]["slip_increment"] - move).max() <= 1e-12 * move.max()


# ------------------------------------------------------------------ the blocks separate
def test_separated_blocks_both_solvers_agree():
    """The upper block pressed (u_y = -0.01 at t = 1/2), then lifted off (+0.01 at t = 1)
    while pushed sideways: at the last step every node is separated, p_n is round-off
    (the fixed point's test must not compare that noise with max p_n ~ 1e-21: SNES VI
    failed here after 30 fixed-point iterations); the condensed solver and SNES VI agree
    at every step to SNES VI's active-set resolution snes_vi_zero_tolerance = 1e-8 L,
    L = 2 (measured: 1e-16 pressed, 1.7e-8 at t = 3/4 where the blocks just touch, 1e-12
    separated), and p_n = friction_bound / mu at the separated step is 0 up to
    1e-8 of the stress scale E |u_y| / h = 1000 x 0.01 / 1 (hand computed; h the upper
    block's height)."""
    raw = _blocks({"coulomb": {"mu": MU}}, 4, 0.0)
    raw["loads"]["displacement"]["upper_top"] = [
        {"table": [[0.0, 0.0], [0.5, 0.0], [1.0, 0.03]]},
        {"table": [[0.0, 0.0], [0.5, -0.01], [1.0, 0.01]]}]
    runs = {}
    for method in ("snes_vi", "condensed"):
        raw["solver"]["method"] = method
        runs[method] = _run(raw)[1]
    for a, b in zip(runs["condensed"], runs["snes_vi"]):
        for key in ("u_x", "u_y"):
            assert np.abs(a[key] - b[key]).max() <= 1e-8 * 2.0
    for tab in (runs["condensed"][-1], runs["snes_vi"][-1]):
        assert (tab["u_nu"] < 0).all()
        assert np.abs(tab["friction_bound"]).max() <= MU * 1e-8 * E * 0.01
