"""Two contact pairs with different laws (each pair's own normal_compliance, memory,
friction), on three stacked blocks (tests/data/stack3.geo: bottom, middle, top; pair 0 the
bottom's top onto the middle's bottom, pair 1 the middle's top onto the top's bottom), all
three elastic (E = 1000, nu = 0.3, plane strain), the bottom clamped, a weight f0 in every
block (so that the bounds hold the middle block from the first Newton iteration), the top
pressed down and then pushed sideways by its top, the middle block pushed sideways half as
far by a roller on its left side.  Closed forms:

- Coulomb mu_0 = 0.2 under pair 0 and mu_1 = 0.4 under pair 1: once both interfaces slide,
  the tangential force of each is mu_i times its normal force, Q_i = mu_i P_i (to 1e-6: the
  regularisation's error (delta / |u_tau|)^2 / 2 and the fixed point's 1e-8), and at every
  node the friction stress reaches mu_i p_n;
- pair 0 frictionless with normal compliance c_nu and a memory term (and g = 0.01 m, an
  interface layer thicker than the penetration ~2e-3 m), pair 1 Coulomb mu = 0.3 with hard
  contact: pair 0 transmits no tangential force (the middle block slides freely on
  the bottom one), pair 1 slides with Q_1 = mu P_1; at pair 0's nodes the contact pressure
  is c_nu u_nu + xi_n with xi_n the left-rectangle sum of b0 exp(-beta (t_n - t_{j-1}))
  u_{j-1,nu}^+ of the nodes' own u_nu history (summed here), and xi = 0 at pair 1's nodes.

The forces come from summary.json's pair_forces, each on the side of the interface without
prescribed dofs (pair 0's surface, the bottom block's top; pair 1's target, the top
block's bottom): the middle block's roller prescribes u_x at its corners, which are nodes of
pair 0's target and pair 1's surface, and the force there is in the roller's reaction.
"""
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from conftest import make_case
from vpcontact.case import validate
from vpcontact.observers import Observer
from vpcontact.post.quantities import contact_table
from vpcontact.simulation import run

ROOT = Path(__file__).parents[2]
E, NU, DELTA = 1000.0, 0.3, 1e-8
C_NU, B0, BETA = 2000.0, 500.0, 2.0


class _Tables(Observer):
    """contact_table after every accepted step."""

    def __init__(self):
        self.tables = []

    def step(self, sim, record):
        self.tables.append(contact_table(sim.problem))


def _stack(law0: dict, law1: dict, N: int = 5) -> dict:
    """stack3.geo: pressed by 0.01 in the first step, then pushed sideways (top 0.06,
    middle 0.03) in N - 1 steps; pair 0 with the laws law0, pair 1 with law1."""
    t1 = 1.0 / N
    elastic = {"E": E, "nu": NU, "plane": "strain"}
    return {"mesh": {"file": str(ROOT / "tests" / "data" / "stack3.geo"), "dim": 2},
            "materials": {"bottom": elastic, "middle": elastic, "top": elastic},
            "boundaries": {"clamped": ["bottom_bottom"]},
            "contact": {"pairs": [
                {"surface": "bottom_top", "target": "middle_bottom", **law0},
                {"surface": "middle_top", "target": "top_bottom", **law1}]},
            "loads": {"f0": [0.0, -0.5], "displacement": {
                "top_top": [{"table": [[0.0, 0.0], [t1, 0.0], [1.0, 0.06]]},
                            {"table": [[0.0, 0.0], [t1, -0.01], [1.0, -0.01]]}],
                "middle_left": [{"table": [[0.0, 0.0], [t1, 0.0], [1.0, 0.03]]}, None]}},
            "time": {"T": 1.0, "N": N},
            "solver": {"delta": DELTA, "method": "snes_vi"}}


def _run(raw: dict):
    """Run in this process: the summary's steps and each step's contact table."""
    rec = _Tables()
    result = run(make_case(raw), MPI.COMM_WORLD, [rec])
    assert result.status == "completed"
    return result.summary["steps"], rec.tables


def _forces(step: dict) -> list[tuple[float, float]]:
    """(Q_i, P_i) of each pair: on pair 0's surface, on pair 1's target."""
    f = step["pair_forces"]
    return [(abs(f[0]["on_surface"][0]), -f[0]["on_surface"][1]),
            (abs(f[1]["on_target"][0]), f[1]["on_target"][1])]


@pytest.fixture(scope="module")
def two_coulombs():
    return _run(_stack({"friction": {"coulomb": {"mu": 0.2}}},
                       {"friction": {"coulomb": {"mu": 0.4}}}))


def test_each_pair_slides_at_its_own_mu(two_coulombs):
    """Steps 3-5 (both interfaces sliding): Q_i = mu_i P_i to 1e-6, every node slipping
    with its friction stress at mu_i p_n."""
    steps, tables = two_coulombs
    for step, tab in zip(steps[3:], tables[3:]):
        for (Q, P), mu in zip(_forces(step), (0.2, 0.4)):
            assert P > 1.0 and abs(Q / (mu * P) - 1.0) <= 1e-6
        mu_node = np.where(tab["pair"] == 0, 0.2, 0.4)
        free = ~tab["_prescribed"]
        assert (tab["slip_state"][free] == 1).all()
        assert np.allclose(tab["friction_bound"][free], mu_node[free] * tab["neg_sigma_nu"][free],
                           rtol=1e-6)


@pytest.fixture(scope="module")
def mixed():
    return _run(_stack({"normal_compliance": {"c_nu": C_NU}, "g": 0.01,
                        "memory": {"b0": B0, "beta": BETA}},
                       {"friction": {"coulomb": {"mu": 0.3}}}))


def test_frictionless_pair_beside_a_coulomb_pair(mixed):
    """Pair 0 (no friction) transmits no tangential force; pair 1 slides at Q = 0.3 P."""
    steps, _ = mixed
    for step in steps[3:]:
        (Q0, P0), (Q1, P1) = _forces(step)
        assert P0 > 1.0 and Q0 <= 1e-8 * P0
        assert abs(Q1 / (0.3 * P1) - 1.0) <= 1e-6


def test_compliance_and_memory_of_one_pair_only(mixed):
    """At pair 0's nodes -sigma_nu = c_nu u_nu + xi_n, xi_n the sum of the nodes' own
    u_nu history (relative 1e-6); xi = 0 at pair 1's nodes (hard contact, no memory)."""
    steps, tables = mixed
    t = np.array([0.0] + [s["t"] for s in steps])
    r = [np.zeros(len(tables[0]["u_nu"]))] + [np.maximum(tab["u_nu"], 0.0) for tab in tables]
    for n, tab in enumerate(tables, start=1):
        xi = sum((t[j] - t[j - 1]) * B0 * np.exp(-BETA * (t[n] - t[j - 1])) * r[j - 1]
                 for j in range(1, n + 1))
        on0 = (tab["pair"] == 0) & ~tab["_prescribed"]
        assert (tab["xi"][tab["pair"] == 1] == 0.0).all()
        assert np.allclose(tab["xi"][on0], xi[on0], rtol=1e-9, atol=0.0)
        # the memory term's r^+ is regularised with delta: its slope is 1 to (delta/r)^2
        expected = C_NU * tab["u_nu"][on0] + xi[on0]
        assert np.allclose(tab["neg_sigma_nu"][on0], expected, rtol=1e-6)
    assert (tables[-1]["xi"][tables[-1]["pair"] == 0] > 0).all()


# ------------------------------------------------------------------ the case layer
def _pairs(raw: dict) -> dict:
    return validate(raw, "laws.yaml")


def test_contact_section_serves_pairs_without_their_own():
    """A law of the contact section serves every pair that gives none; a pair's own key
    overrides it; the same laws in every pair are one set (Contact.sections)."""
    raw = _stack({}, {"friction": {"coulomb": {"mu": 0.4}}})
    raw["contact"]["friction"] = {"coulomb": {"mu": 0.2}}
    raw["contact"]["normal_compliance"] = {"c_nu": C_NU}
    case = _pairs(raw)
    sections = case.contact.sections
    assert [s.friction.coulomb.mu for s in sections] == [0.2, 0.4]
    assert [s.c_nu for s in sections] == [C_NU, C_NU]
    assert case.contact.friction is None and "laws per pair" in case.active_terms()
    again = validate(case.raw, "again.yaml")          # case.raw validates to the same
    assert again.contact.sections == sections
    same = _stack({"friction": {"coulomb": {"mu": 0.2}}}, {})
    same["contact"]["friction"] = {"coulomb": {"mu": 0.2}}
    one = _pairs(same).contact
    assert one.sections == (one,) and one.friction.coulomb.mu == 0.2
    assert all(p.laws is None for p in one.pairs)


def test_restart_with_laws_per_pair(tmp_path):
    """A run restarted from step 2 equals the uninterrupted one (1e-12): pair 0's
    static/kinetic Coulomb friction (p_n, the slip s_n) and pair 1's compliant layer with a
    memory term (xi_n) are kept node by node in the checkpoint."""
    import shutil

    import yaml

    from conftest import cli_in_process, contact_rows
    raw = _stack({"friction": {"coulomb": {"mu_s": 0.3, "mu_k": 0.2, "slip_length": 0.01}}},
                 {"g": 0.01, "normal_compliance": {"c_nu": C_NU},
                  "memory": {"b0": B0, "beta": BETA}}, N=4)
    raw["output"] = {"checkpoint_every": 2}
    case = tmp_path / "laws.yaml"
    case.write_text(yaml.safe_dump(raw))
    full, first, again = tmp_path / "full", tmp_path / "first", tmp_path / "again"
    assert cli_in_process(["run", case, "--out", full, "--no-plots"]) == 0
    shutil.copytree(full, first)
    (first / "checkpoint_000004.npz").unlink()
    assert cli_in_process(["run", case, "--restart", first, "--out", again,
                           "--no-plots"]) == 0
    (s1, a), (s2, b) = contact_rows(full), contact_rows(again)
    assert s1 == s2 and np.isnan(a).any()          # NaN: columns of the other pair's laws
    assert np.allclose(a, b, rtol=0.0, atol=1e-12 * np.nanmax(np.abs(a)), equal_nan=True)


def test_mpirun_equals_serial_with_laws_per_pair(tmp_path):
    """mpirun -n 2 equals the serial run (contact.csv, 1e-10 of its largest value): the
    pairs' laws at the ranks' nodes (owned and ghost) by the node's pair."""
    import yaml

    from conftest import cli_in_process, contact_rows, run_cli
    case = tmp_path / "laws.yaml"
    case.write_text(yaml.safe_dump(_stack({"friction": {"coulomb": {"mu": 0.2}}},
                                          {"friction": {"coulomb": {"mu": 0.4}}}, N=3)))
    serial, parallel = tmp_path / "serial", tmp_path / "parallel"
    assert cli_in_process(["run", case, "--out", serial, "--no-plots"]) == 0
    proc = run_cli(["run", case, "--out", parallel, "--quiet"], nprocs=2)
    assert proc.returncode == 0, proc.stderr
    (s1, a), (s2, b) = contact_rows(serial), contact_rows(parallel)
    assert s1 == s2
    assert np.allclose(a, b, rtol=0.0, atol=1e-10 * np.nanmax(np.abs(a)), equal_nan=True)
