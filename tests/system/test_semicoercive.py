"""Force control of a body held only by contact (app/model/semicoercive.py): the probe of
the issue (a block on the foundation, top traction
[1, -10], no Dirichlet data) runs with both step solvers, serially and under mpirun -n 2,
and its contact force balances the applied load (the statics of a free body: contact
force = minus the applied resultant); the shipped cases (a sheared block that sticks with
slipping edges, a pushed block that slides at mu P); a block on a clamped block through
contact.pairs; Hertz's cylinder under a force against Hertz's closed form; loads the contact
cannot balance are refused in one line with exit code 2 before anything is solved; the cone
test of the loads against its closed form for two contact points."""
import numpy as np
import pytest

from conftest import ROOT, cli_in_process, run_cli, summary_steps

PROBE = ROOT / "tests" / "data" / "block_force_probe.yaml"
APPLIED = np.array([1.0, -10.0])          # the probe's top traction times its width 1


def _balance(out) -> float:
    """The largest relative misfit of contact force + applied resultant over the steps."""
    steps = summary_steps(out)
    assert len(steps) == 2
    return max(np.abs(np.array(s["contact_force"]) + APPLIED).max() / np.abs(APPLIED).max()
               for s in steps)


@pytest.mark.parametrize("method", ["condensed", "snes_vi"])
def test_probe_runs_and_balances_serially(tmp_path, method):
    """On main: 'leave 3 rigid motion(s) of the body free', exit 2."""
    code = cli_in_process(["run", PROBE, "--out", tmp_path / "o", "--quiet", "--no-plots",
                           "--set", f"solver.method={method}"])
    assert code == 0
    assert _balance(tmp_path / "o") < 1e-6


@pytest.mark.parametrize("method", ["condensed", "snes_vi"])
def test_probe_runs_and_balances_under_mpirun(tmp_path, method):
    proc = run_cli(["run", PROBE, "--out", tmp_path / "o", "--quiet",
                    "--set", f"solver.method={method}"], nprocs=2)
    assert proc.returncode == 0, proc.stderr
    assert _balance(tmp_path / "o") < 1e-6


def test_shipped_case_balances_its_ramp(tmp_path):
    """cases/block_force.yaml: contact force (-2, 10) t at every step; the edge nodes slip,
    the middle sticks (Q / (mu P) = 0.67)."""
    import csv
    out = tmp_path / "o"
    assert cli_in_process(["run", ROOT / "cases" / "block_force.yaml", "--out", out,
                           "--quiet", "--no-plots"]) == 0
    for s in summary_steps(out):
        want = np.array([-2.0, 10.0]) * s["t"]
        assert np.abs(np.array(s["contact_force"]) - want).max() < 1e-6 * 10 * s["t"]
    with open(out / "contact.csv") as f:
        rows = sorted(csv.DictReader(f), key=lambda r: float(r["x"]))
    slip = [float(r["slip_state"]) for r in rows]
    assert slip[0] == slip[-1] == 1.0 and slip[len(slip) // 2] == 0.0


@pytest.mark.parametrize("traction, words", [
    ("[4,-10]", "tangential resultant 4 >= mu P = 0.3 x 10 = 3"),
    ("[1,10]", "does not press it onto Gamma3 (normal component -10 <= 0: a pull-off)"),
    ("[0,'-10 + 15*t']", "at t = 1 the applied force resultant (0, 5)"),
])
def test_unbalanceable_loads_are_refused_before_any_solve(tmp_path, capsys, traction, words):
    """Exit 2, one line naming the keys and the numbers, no solution written."""
    out = tmp_path / "o"
    code = cli_in_process(["run", PROBE, "--out", out, "--quiet", "--no-plots",
                           "--set", f"loads.traction.top={traction}"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    line = [e for e in err if "error" in e]
    assert len(line) == 1 and words in line[0] and "loads.traction" in line[0], err
    assert not (out / "solution.h5").exists()


def test_frictionless_free_tangential_motion_is_refused(tmp_path, capsys):
    """No friction: the tangential translation is free even under a purely normal load
    (Code_Aster refuses the singular system; we do too)."""
    import yaml
    raw = yaml.safe_load(PROBE.read_text())
    del raw["contact"]["friction"]
    raw["loads"]["traction"]["top"] = [0.0, -10.0]
    path = tmp_path / "nofriction.yaml"
    path.write_text(yaml.safe_dump(raw))
    assert cli_in_process(["check", path]) == 2
    assert "frictionless contact cannot hold its tangential motion" in capsys.readouterr().err


@pytest.mark.parametrize("Q, P, M", [(2.9, 10, 0), (3.1, 10, 0), (1, 10, 9.9), (1, 10, 10.1),
                                     (0, 10, -9), (1, -1, 0), (0, 0, 0), (-2.9, 10, -9)])
def test_cone_test_against_two_contact_points(Q, P, M):
    """Two contact nodes at x = -1, 1 on y = 0, outward normal (0, -1), Coulomb mu = 0.3;
    the free motions x, y, rotation; load W = (Q, -P, M).  Closed form: node forces
    p_1,2 = (P -+ M) / 2 must be > 0 and |Q| < mu P."""
    from vpcontact.model.semicoercive import _strictly_inside
    mu, x = 0.3, np.array([-1.0, 1.0])
    modes = np.array([[[1, 0, 0], [0, 1, xi]] for xi in x])        # (node, d, free)
    nu = np.array([[0.0, -1.0]] * 2)
    tau = np.array([[1.0, 0.0]] * 2)
    A = np.concatenate([np.einsum("nd,ndr->rn", -nu + s * mu * tau, modes) for s in (1, -1)],
                       axis=1)
    W = np.array([Q, -P, M], dtype=float)
    expected = P > 0 and abs(M) < P and abs(Q) < mu * P
    assert _strictly_inside(A, np.zeros((4, 0)), -W) == expected


# ------------------------------------------------------------------ held by a contact pair
def _block_on_block(tmp_path, top=(1.0, -10.0)):
    """The upper block of patch2d.geo on the clamped lower one, no Dirichlet data on it:
    held only by the pair (compliance, the bound at touching, Coulomb mu = 0.3)."""
    import yaml
    raw = {"name": "block_on_block",
           "mesh": {"file": str(ROOT / "tests" / "data" / "patch2d.geo"), "dim": 2},
           "materials": {b: {"E": 1000.0, "nu": 0.3, "plane": "strain"}
                         for b in ("upper", "lower")},
           "boundaries": {"clamped": ["lower_bottom"]},
           "contact": {"pairs": [{"surface": "lower_top", "target": "upper_bottom",
                                  "normal_compliance": {"c_nu": 1000.0},
                                  "friction": {"coulomb": {"mu": 0.3}}}]},
           "loads": {"traction": {"upper_top": list(top)}},
           "solver": {"delta": 1e-7}, "time": {"T": 1.0, "N": 2}}
    path = tmp_path / "block_on_block.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


@pytest.mark.parametrize("method, nprocs", [("condensed", 1), ("snes_vi", 1),
                                            ("condensed", 2), ("snes_vi", 2)])
def test_block_held_by_a_pair_balances(tmp_path, method, nprocs):
    """The force on the lower block (the pair's contact force) is the load on the upper
    one, the clamp's reaction its opposite (on main: SNES VI ran away at step 1; the
    condensed solver's Coulomb fixed point started from p_n = 0)."""
    case = _block_on_block(tmp_path)
    proc = run_cli(["run", case, "--out", tmp_path / "o", "--quiet",
                    "--set", f"solver.method={method}"], nprocs=nprocs)
    assert proc.returncode == 0, proc.stderr
    for s in summary_steps(tmp_path / "o"):
        assert np.abs(np.array(s["contact_force"]) - APPLIED).max() < 1e-6 * 10
        assert np.abs(np.array(s["reactions"]["lower_bottom"]) + APPLIED).max() < 1e-6 * 10


def test_block_held_by_a_pair_refuses_sliding_load(tmp_path, capsys):
    case = _block_on_block(tmp_path, top=(3.5, -10.0))
    assert cli_in_process(["check", case]) == 2
    err = capsys.readouterr().err
    assert "tangential resultant 3.5 >= mu P = 0.3 x 10 = 3" in err
    assert "held only by contact pair(s) contact.pairs[0]" in err


@pytest.mark.parametrize("method", ["condensed", "snes_vi"])
def test_hertz_cylinder_under_a_force(tmp_path, method):
    """cases/hertz_cylinder.yaml pressed by a traction of 10 on its top instead of a
    displacement (the roller on 'sym' holds x and the rotation, the Signorini contact the
    vertical translation): the contact force is the load to 1e-6 and the pressure Hertz's
    for P = 2 x 10 (the half model): half-width within 1e-3 (5e-5 measured) and peak
    within 1 % (0.2 % measured) of a = sqrt(4 P R / (pi E*)), p0 = 2 P / (pi a)."""
    import csv
    import shutil

    import yaml

    from references.contact_closed_forms import hertz_cylinders
    raw = yaml.safe_load((ROOT / "cases" / "hertz_cylinder.yaml").read_text())
    raw["loads"] = {"displacement": {"sym": [0.0, None]},
                    "traction": {"top": [0.0, -10.0]}}
    shutil.copy(ROOT / "cases" / "hertz_cylinder.geo", tmp_path)
    (tmp_path / "hertz_force.yaml").write_text(yaml.safe_dump(raw))
    out = tmp_path / "o"
    assert cli_in_process(["run", tmp_path / "hertz_force.yaml", "--out", out, "--quiet",
                           "--no-plots", "--set", f"solver.method={method}"]) == 0
    force = summary_steps(out)[-1]["contact_force"]
    assert abs(force[1] - 10.0) < 1e-5 and abs(force[0]) < 1e-5
    with open(out / "contact.csv") as f:
        rows = list(csv.DictReader(f))
    x = np.array([float(r["x"]) for r in rows])
    p = np.array([float(r["neg_sigma_nu"]) for r in rows])
    inside = p > 1e-6 * p.max()
    use = inside & (x < x[inside].max())          # the edge node's partial load left out
    B, A = np.polyfit(x[use] ** 2, p[use] ** 2, 1)
    a, p0 = hertz_cylinders(20.0, 1.0, float("inf"), 1000.0, 0.3, float("inf"), 0.3)
    assert abs(np.sqrt(-A / B) / a - 1) < 1e-3
    assert abs(p.max() / p0 - 1) < 1e-2


def test_shipped_sliding_case_slides_at_mu_p(tmp_path):
    """cases/block_slide.yaml: pressed by P = 10, pushed by its left side: the push's
    reaction grows, then stays at mu P = 3 while the block slides (Coulomb); the contact
    force balances push and pressure."""
    out = tmp_path / "o"
    assert cli_in_process(["run", ROOT / "cases" / "block_slide.yaml", "--out", out,
                           "--quiet", "--no-plots"]) == 0
    steps = summary_steps(out)
    push = [s["reactions"]["left"][0] for s in steps]
    assert push[0] < 3.0 * (1 - 1e-3)                 # still sticking at the first step
    assert abs(push[-1] / 3.0 - 1) < 1e-6
    for s in steps:
        force = np.array(s["contact_force"])
        assert np.abs(force - [-s["reactions"]["left"][0], 10.0]).max() < 1e-6 * 10


def test_mindlin_under_cap_forces_with_the_default_snes():
    """cases/mindlin.yaml's cylinder loaded by a rigid cap (P, then Q = 0.15 P; rotation 0),
    held sideways by friction alone, with SNES VI's default vinewtonrsls: the held start
    solves its first step (on main it failed: the touching nodes' bound inactive, the Newton
    matrix singular; test_rigid_cap.py needs vinewtonssls), contact force (-Q, P) to 1e-6."""
    from conftest import make_case, run_case
    from vpcontact.case import load_raw
    P, Q = 4.28, 0.642
    raw = load_raw(ROOT / "cases" / "mindlin.yaml")
    raw["mesh"].update({"file": str(ROOT / "cases" / "mindlin.geo"), "size": 4.0})
    raw["loads"] = {"rigid": {"cylinder_top": {
        "force": [{"table": [[0.0, 0.0], [0.5, 0.0], [1.0, Q]]},
                  {"table": [[0.0, 0.0], [0.5, -P], [1.0, -P]]}], "rotation": 0.0}}}
    raw["time"] = {"T": 1.0, "N": 2}
    raw["solver"]["method"] = "snes_vi"
    result = run_case(make_case(raw))
    assert result.status == "completed"
    force = result.summary["steps"][-1]["contact_force"]
    assert force[0] == pytest.approx(-Q, rel=1e-6) and force[1] == pytest.approx(P, rel=1e-6)


@pytest.mark.parametrize("Qx, refused", [(0.28, False), (0.2955, True)])
def test_3d_cone_polygon_refusal_names_its_reason(tmp_path, capsys, Qx, refused):
    """3D: the check takes the Coulomb cone as its inscribed 16-gon (mu cos(pi/16) = 0.981
    mu), so a load within 2 % below mu P (here at pi/16 to a vertex of the polygon, its
    inscribed radius) is refused, with that reason (before: 'a moment the contact zone
    cannot carry'); 0.933 mu P passes."""
    import math

    import yaml
    a = math.pi / 16
    raw = {"name": "block3d", "mesh": {"dim": 3, "L1": 1.0, "L2": 1.0, "L3": 0.5,
                                       "kind": "structured", "n": 2},
           "material": {"E": 1000.0, "nu": 0.3}, "boundaries": {"clamped": []},
           "contact": {"g": 0.01, "normal_compliance": {"c_nu": 1000.0},
                       "friction": {"coulomb": {"mu": 0.3}}},
           "loads": {"traction": {"top": [Qx * math.cos(a), Qx * math.sin(a), -1.0]}},
           "time": {"T": 1.0, "N": 1}}
    path = tmp_path / "block3d.yaml"
    path.write_text(yaml.safe_dump(raw))
    code = cli_in_process(["check", path])
    err = capsys.readouterr().err
    if not refused:
        assert code == 0, err
        return
    assert code == 2
    assert "within 1.9 % below mu P = 0.3" in err and "inscribed 16-gon (0.9808 mu)" in err, err
