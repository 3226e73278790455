"""Rigid caps (loads.rigid, app/model/rigidcap.py) against closed forms:

- a bar (nu = 0, on rollers) under a cap force F: the homogeneous stress F / A is exact for
  P1, so the cap's u_y = F L / (E A) to round-off and its resultant on the body is F (both
  solvers); under a prescribed cap displacement delta the resultant is E A delta / L;
- a cantilever (nu = 0) clamped at x = 0 under a cap moment M at x = L: with nu = 0 the
  pure-bending field u_x = -k x y, u_y = k x^2 / 2 (k = M / (E I)) satisfies the clamp and is
  rigid on the end, so theta = M L / (E I) is the exact continuum answer; P1 locks in
  bending, and the error falls with h (measured: 29 % at n = 8, 9.2 % at n = 16); under a
  cap force the end's deflection approaches Timoshenko's;
- two cylinders in Hertz contact (cases/hertz_cap.yaml, the pair of
  tests/system/test_pairs_hertz.py) loaded by the cap force P/2 instead of a displacement:
  the contact force equals the cap force to 1e-6, a and p0 within 2 % of Hertz at that P
  (measured -0.95 % and +1.1 %, both solvers), serial == mpirun -n 2;
- one body on the rigid foundation (the paper's scene, its top load through a cap): the
  condensed solver equals SNES VI, serial == mpirun -n 2;
- Cattaneo-Mindlin under cap forces P and Q: the stick zone's half-width;
- bad input: one line naming the key.
"""
import copy
import json
from pathlib import Path

import numpy as np
import pytest

from conftest import make_case, run_case, run_cli
from references.contact_closed_forms import hertz_cylinders
from vpcontact.case import load_raw, validate
from vpcontact.io.errors import CaseError
from vpcontact.post.quantities import contact_table

CASES = Path(__file__).resolve().parents[2] / "cases"
E, L, H = 1000.0, 2.0, 1.0


def _bar(cap: dict, method: str = "snes_vi") -> dict:
    """A bar L1 = H wide, L2 = L high, nu = 0, rollers on the bottom and the left side, a
    cap on the top."""
    return {"name": "bar", "mesh": {"L1": H, "L2": L, "n": 4},
            "material": {"E": E, "nu": 0.0},
            "boundaries": {"clamped": [], "contact": []},
            "loads": {"displacement": {"left": [0.0, None], "bottom": [None, 0.0]},
                      "rigid": {"top": cap}},
            "time": {"T": 1.0, "N": 2}, "solver": {"method": method}}


@pytest.mark.parametrize("method", ["snes_vi", "condensed"])
def test_bar_under_a_cap_force(method):
    result = run_case(validate(_bar({"force": [None, "-4.0*t"]}, method), "bar"))
    assert result.status == "completed"
    assert result.summary["solver"]["used"] == method
    for step in result.summary["steps"]:
        F = -4.0 * step["t"]
        cap = step["rigid"]["top"]
        assert cap["displacement"][1] == pytest.approx(F * L / (E * H), rel=1e-12)
        assert abs(cap["rotation"]) < 1e-14
        assert cap["force"][1] == pytest.approx(F, rel=1e-12)
        assert abs(cap["moment"]) < 1e-12
        assert step["reactions"]["bottom"][1] == pytest.approx(-F, rel=1e-12)


def test_bar_under_a_prescribed_cap_displacement():
    result = run_case(validate(_bar({"displacement": [None, -0.01], "rotation": 0.0}), "bar"))
    cap = result.summary["steps"][-1]["rigid"]["top"]
    assert cap["displacement"][1] == pytest.approx(-0.01, rel=1e-14)
    assert cap["force"][1] == pytest.approx(-E * H * 0.01 / L, rel=1e-12)


def _cantilever_rotation(n: int, M: float) -> tuple[float, dict]:
    raw = {"name": "beam", "mesh": {"L1": 4.0, "L2": 1.0, "n": n},
           "material": {"E": E, "nu": 0.0},
           "boundaries": {"clamped": ["left"], "contact": []},
           "loads": {"rigid": {"right": {"moment": M}}},
           "time": {"T": 1.0, "N": 1}, "solver": {"method": "snes_vi"}}
    cap = run_case(validate(raw, "beam")).summary["steps"][-1]["rigid"]["right"]
    return cap["rotation"], cap


def test_cantilever_under_a_cap_moment():
    M, length, inertia = 2.0, 4.0, 1.0 / 12
    theta = M * length / (E * inertia)
    errors = []
    for n in (8, 16):
        rotation, cap = _cantilever_rotation(n, M)
        errors.append(abs(rotation / theta - 1))
        assert cap["moment"] == pytest.approx(M, rel=1e-10)
        assert np.allclose(cap["force"], 0.0, atol=1e-10)
    assert errors[1] < errors[0] / 2.5
    assert errors[1] < 0.1


def test_cantilever_under_a_cap_tip_force():
    """The cantilever (L = 4, h = 1, nu = 0) under a cap force P at its end: the deflection
    of the end's centroid against Timoshenko's P L^3 / (3 E I) + P L / (k G A) (k = 5/6,
    G = E/2) as h -> 0 (measured: -28.5, -9.1, -2.5 % at mesh.n = 8, 16, 32; the 2D
    solution's clamp and rigid end differ from the beam's by end effects, so the error need
    not reach 0)."""
    P, length, inertia = 0.1, 4.0, 1.0 / 12
    timoshenko = P * length ** 3 / (3 * E * inertia) + P * length / (5 / 6 * E / 2 * 1.0)
    errors = []
    for n in (16, 32):
        raw = {"name": "beam", "mesh": {"L1": length, "L2": 1.0, "n": n},
               "material": {"E": E, "nu": 0.0},
               "boundaries": {"clamped": ["left"], "contact": []},
               "loads": {"rigid": {"right": {"force": [0.0, -P]}}},
               "time": {"T": 1.0, "N": 1}}
        cap = run_case(validate(raw, "beam")).summary["steps"][-1]["rigid"]["right"]
        errors.append(abs(-cap["displacement"][1] / timoshenko - 1))
        assert cap["force"][1] == pytest.approx(-P, rel=1e-10)
    assert errors[1] < errors[0] / 3 and errors[1] < 0.03


def _hertz_raw(method: str) -> dict:
    raw = copy.deepcopy(dict(load_raw(CASES / "hertz_cap.yaml")))
    raw["mesh"] = {"file": str(CASES / "two_cylinders.geo"), "dim": 2, "size": 2.0}
    raw["time"] = {"T": 1.0, "N": 1}
    raw["solver"] = {"method": method}
    return raw


@pytest.mark.parametrize("method", ["snes_vi", "condensed"])
def test_hertz_under_a_cap_force(method):
    result = run_case(make_case(_hertz_raw(method)))
    assert result.status == "completed"
    assert result.summary["solver"]["used"] == method
    step = result.summary["steps"][-1]
    half = 4.315                                   # the case's cap force at t = 1
    assert step["contact_force"][1] == pytest.approx(half, rel=1e-6)
    cap = step["rigid"]["upper_top"]
    assert cap["force"][1] == pytest.approx(-half, rel=1e-6)
    assert abs(cap["displacement"][0]) < 1e-14 and abs(cap["rotation"]) < 1e-14
    tab = contact_table(result.problem)
    order = np.argsort(tab["x"])
    x, p = tab["x"][order], tab["neg_sigma_nu"][order]
    on = p > 1e-6 * p.max()
    (c0, c1), *_ = np.linalg.lstsq(np.c_[np.ones(on.sum()), x[on] ** 2], p[on] ** 2, rcond=None)
    a_ref, p0_ref = hertz_cylinders(2 * half, 1.0, 2.0, 1000.0, 0.3, 2000.0, 0.3,
                                    plane_strain=True)
    assert abs(np.sqrt(-c0 / c1) / a_ref - 1) <= 0.02
    assert abs(np.sqrt(c0) / p0_ref - 1) <= 0.02


@pytest.mark.mpi
@pytest.mark.parametrize("method", ["snes_vi", "condensed"])
def test_hertz_cap_on_two_ranks(method, tmp_path):
    caps = []
    for n in (1, 2):
        out = tmp_path / f"np{n}"
        proc = run_cli(["run", CASES / "hertz_cap.yaml", "--out", out, "--quiet", "--set",
                        "mesh.size=2", "--set", "time.N=2", "--set",
                        f"solver.method={method}"], nprocs=n)
        assert proc.returncode == 0, proc.stderr
        summary = json.loads((out / "summary.json").read_text())
        caps.append(summary["steps"][-1]["rigid"]["upper_top"])
        header = (out / "history.csv").read_text().splitlines()[0].split(",")
        assert "rigid_upper_top_u_y" in header and "rigid_upper_top_F_y" in header
    assert caps[1]["displacement"][1] == pytest.approx(caps[0]["displacement"][1], rel=1e-10)
    assert caps[1]["force"][1] == pytest.approx(-4.315, rel=1e-6)


@pytest.mark.parametrize("cap, where, words", [
    ({"force": [0.0, 1.0, 2.0]}, "loads.rigid.top.force", "expected a list of 2 components"),
    ({"force": [None, 1.0], "displacement": [None, 0.0]}, "loads.rigid.top",
     "force[1] and displacement[1] are both given"),
    ({"moment": [1.0, 2.0, 3.0]}, "loads.rigid.top.moment", "one component (not a list)"),
    ({"force": [None, "x*t"]}, "loads.rigid.top.force[1]", "x"),
    ({"reference": [0.0, 1.0, 2.0]}, "loads.rigid.top.reference", "expected 2 coordinates"),
    ({"force": [None, "1/(t - 0.5)"]}, "loads.rigid.top.force[1]", "not finite at t = 0.5"),
])
def test_bad_caps_are_refused(cap, where, words):
    with pytest.raises(CaseError) as err:
        validate(_bar(cap), "bar.yaml")
    message = str(err.value)
    assert "\n" not in message and f"bar.yaml: {where}" in message and words in message


def test_a_cap_on_a_clamped_or_unknown_group_is_refused():
    raw = _bar({"force": [None, 1.0]})
    raw["boundaries"]["clamped"] = ["top"]
    with pytest.raises(CaseError, match=r"loads.rigid.top: the top side is also in "
                                        r"boundaries.clamped"):
        validate(raw, "bar.yaml")
    raw = _bar({"force": [None, 1.0]})
    raw["loads"]["rigid"] = {"topp": {"force": [None, 1.0]}}
    with pytest.raises(CaseError, match="loads.rigid.topp"):
        validate(raw, "bar.yaml")


def test_a_cap_on_a_contact_group_exits_2(tmp_path):
    import yaml
    raw = copy.deepcopy(dict(load_raw(CASES / "hertz_cap.yaml")))
    raw["mesh"]["file"] = str(CASES / "two_cylinders.geo")
    raw["loads"]["rigid"] = {"upper_arc": {"force": [None, -1.0]}}
    case = tmp_path / "bad.yaml"
    case.write_text(yaml.safe_dump(raw))
    proc = run_cli(["check", case])
    assert proc.returncode == 2
    lines = [s for s in proc.stderr.splitlines() if s.strip()]
    assert len(lines) == 1 and "contact.pairs[0].surface" in lines[0] \
        and "'upper_arc' carries a load (loads.traction, pressure, displacement or rigid)" \
        in lines[0], proc.stderr


def test_a_cap_sharing_nodes_with_a_clamped_group_is_refused():
    raw = _bar({"force": [None, 1.0]})
    raw["boundaries"]["clamped"] = ["left"]
    del raw["loads"]["displacement"]["left"]
    with pytest.raises(CaseError, match=r"loads.rigid.top: the cap shares 1 node\(s\) with "
                                        r"boundaries.clamped"):
        run_case(validate(raw, "bar.yaml"))


CAPPED_GEO = """
h = 1/16;
Point(1) = {0, 0, 0, h}; Point(2) = {1, 0, 0, h}; Point(3) = {1, 1, 0, h};
Point(4) = {0.75, 1, 0, h}; Point(5) = {0.25, 1, 0, h}; Point(6) = {0, 1, 0, h};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 5}; Line(5) = {5, 6};
Line(6) = {6, 1};
Curve Loop(1) = {1, 2, 3, 4, 5, 6}; Plane Surface(1) = {1};
Physical Curve("bottom") = {1}; Physical Curve("right") = {2};
Physical Curve("top_free") = {3, 5}; Physical Curve("cap") = {4};
Physical Curve("left") = {6}; Physical Surface("body") = {1};
"""


def _capped_scene(tmp_path, method: str) -> dict:
    """The paper's scene (Perzyna, compliance, nonmonotone friction on the bottom, the left
    side clamped) with its top load applied through a cap on the middle of the top side:
    force (0, -4 t), moment 0.1 t."""
    geo = tmp_path / "capped.geo"
    geo.write_text(CAPPED_GEO)
    raw = copy.deepcopy(dict(load_raw(CASES / "wang_cheng_2021.yaml")))
    raw["mesh"] = {"file": str(geo), "dim": 2}
    raw["material"]["plane"] = "stress"
    raw["boundaries"] = {"clamped": ["left"], "contact": ["bottom"]}
    raw["loads"] = {"traction": {"right": [-3.2, 0.0]},
                    "rigid": {"cap": {"force": [0.0, "-4.0*t"], "moment": "0.1*t"}}}
    raw["time"] = {"T": 1.0, "N": 8}
    raw["solver"] = {"method": method, "quadrature": "vertex"}
    raw["output"] = {"every": 1}
    return raw


def test_one_body_with_a_cap_both_solvers(tmp_path):
    """One body in contact with a rigid foundation, loaded through a cap: the condensed
    solver (in z of u = T z) equals SNES VI (measured 6e-15 of max |u|), and the cap's
    resultant is the applied force and moment at every step."""
    u = {}
    for method in ("snes_vi", "condensed"):
        result = run_case(validate(_capped_scene(tmp_path, method), "scene"))
        assert result.status == "completed"
        assert result.summary["solver"]["used"] == method
        for step in result.summary["steps"]:
            cap = step["rigid"]["cap"]
            assert cap["force"][1] == pytest.approx(-4.0 * step["t"], rel=1e-9)
            assert cap["moment"] == pytest.approx(0.1 * step["t"], rel=1e-9)
        u[method] = result.problem.u.x.array.copy()
    scale = np.abs(u["snes_vi"]).max()
    assert np.abs(u["condensed"] - u["snes_vi"]).max() <= 1e-10 * scale


@pytest.mark.mpi
@pytest.mark.parametrize("method", ["snes_vi", "condensed"])
def test_one_body_with_a_cap_on_two_ranks(tmp_path, method):
    import yaml
    case = tmp_path / "capped.yaml"
    case.write_text(yaml.safe_dump({**_capped_scene(tmp_path, method), "name": "capped"}))
    caps = []
    for n in (1, 2):
        out = tmp_path / f"np{n}"
        proc = run_cli(["run", case, "--out", out, "--quiet"], nprocs=n)
        assert proc.returncode == 0, proc.stderr
        summary = json.loads((out / "summary.json").read_text())
        assert summary["solver"]["used"] == method
        caps.append(summary["steps"][-1]["rigid"]["cap"])
    for key in ("displacement", "rotation"):
        assert np.allclose(caps[1][key], caps[0][key], rtol=1e-10, atol=1e-14)


def test_the_rigid_motion_check_counts_prescribed_amplitudes_only():
    """A bar hanging from a cap whose motion is prescribed is held (the cap carries its
    weight, rho g A L = 2); a cap under a force with the bottom on vertical rollers alone
    leaves the translation x free (refused), and its u_x prescribed holds it."""
    raw = _bar({"displacement": [0.0, -0.01], "rotation": 0.0})
    raw["loads"]["displacement"] = {}
    raw["loads"]["f0"] = [0.0, -1.0]
    cap = run_case(validate(raw, "bar")).summary["steps"][-1]["rigid"]["top"]
    assert cap["force"][1] == pytest.approx(1.0 * H * L, rel=1e-10)
    raw = _bar({"force": [None, -4.0]})
    raw["loads"]["displacement"] = {"bottom": [None, 0.0]}
    with pytest.raises(CaseError, match=r"loads.rigid: the prescribed displacements leave 1 "
                                        r"rigid motion\(s\) of the body free \(like "
                                        r"translation x\)"):
        run_case(validate(raw, "bar"))
    raw["loads"]["rigid"]["top"]["displacement"] = [0.0, None]
    cap = run_case(validate(raw, "bar")).summary["steps"][-1]["rigid"]["top"]
    assert cap["displacement"][1] == pytest.approx(-4.0 * L / (E * H), rel=1e-12)


@pytest.mark.parametrize("method", ["snes_vi", "condensed"])
def test_3d_bar_under_a_cap_force_and_moment(method):
    """A 3D bar (nu = 0, rollers on three faces): u_z = F L / (E A) to round-off; clamped
    at the bottom under a cap moment about x: the cap's moment resultant is M, its rotation
    turns about +x."""
    raw = {"name": "bar3", "mesh": {"dim": 3, "L1": 1.0, "L2": 1.0, "L3": L, "n": 2},
           "material": {"E": E, "nu": 0.0},
           "boundaries": {"clamped": [], "contact": []},
           "loads": {"displacement": {"left": [0.0, None, None], "front": [None, 0.0, None],
                                      "bottom": [None, None, 0.0]},
                     "rigid": {"top": {"force": [None, None, "-4.0*t"]}}},
           "time": {"T": 1.0, "N": 1}, "solver": {"method": method}}
    cap = run_case(validate(raw, "bar3")).summary["steps"][-1]["rigid"]["top"]
    assert cap["displacement"][2] == pytest.approx(-4.0 * L / E, rel=1e-12)
    assert cap["force"][2] == pytest.approx(-4.0, rel=1e-12)
    raw["boundaries"]["clamped"] = ["bottom"]
    raw["loads"] = {"rigid": {"top": {"moment": [1.0, 0.0, 0.0]}}}
    cap = run_case(validate(raw, "bar3")).summary["steps"][-1]["rigid"]["top"]
    assert np.allclose(cap["moment"], [1.0, 0.0, 0.0], atol=1e-10)
    assert cap["rotation"][0] > 0 and cap["displacement"][1] < 0


TWO_SQUARES = """
h = 0.25;
Point(1) = {0, 0, 0, h}; Point(2) = {1, 0, 0, h}; Point(3) = {1, 1, 0, h};
Point(4) = {0, 1, 0, h}; Point(5) = {2, 0, 0, h}; Point(6) = {3, 0, 0, h};
Point(7) = {3, 1, 0, h}; Point(8) = {2, 1, 0, h};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Line(5) = {5, 6}; Line(6) = {6, 7}; Line(7) = {7, 8}; Line(8) = {8, 5};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Curve Loop(2) = {5, 6, 7, 8}; Plane Surface(2) = {2};
Physical Curve("bottom") = {1, 5}; Physical Curve("top") = {3, 7};
Physical Surface("body") = {1, 2};
"""


def test_a_cap_over_two_disconnected_parts_is_refused(tmp_path):
    geo = tmp_path / "two.geo"
    geo.write_text(TWO_SQUARES)
    raw = {"name": "two", "mesh": {"file": str(geo), "dim": 2},
           "material": {"E": E, "nu": 0.0},
           "boundaries": {"clamped": ["bottom"], "contact": []},
           "loads": {"rigid": {"top": {"force": [0.0, -1.0]}}},
           "time": {"T": 1.0, "N": 1}}
    with pytest.raises(CaseError, match=r"two.yaml: loads.rigid.top: the cap spans "
                                        r"disconnected parts of the body"):
        run_case(validate(raw, "two.yaml"))


@pytest.mark.parametrize("method", ["condensed", "snes_vi"])
def test_mindlin_under_cap_forces(method):
    """Cattaneo-Mindlin loaded by forces (the issue's use): cases/mindlin.yaml's cylinder
    with a cap on its flat top (rotation 0) pressed by P = 4.28 in the first step and
    sheared by Q = 0.5 mu P in the second (mesh.size 4), its tangential motion held by
    friction alone: the contact force is (-Q, P) to 1e-6 and the stick nodes' half-width c
    within 5 % of a of Mindlin's a sqrt(1 - Q/(mu P)) (measured -0.67 % with both solvers),
    as the displacement-controlled run
    (tests/system/test_pairs_friction.py).  SNES VI here with vinewtonssls; the default
    vinewtonrsls, which needs the held start of a body held only by contact
    (app/model/semicoercive.py), in
    test_semicoercive.py::test_mindlin_under_cap_forces_with_the_default_snes."""
    P, Q, mu = 4.28, 0.642, 0.3
    raw = load_raw(CASES / "mindlin.yaml")
    raw["mesh"].update({"file": str(CASES / "mindlin.geo"), "size": 4.0})
    raw["loads"] = {"rigid": {"cylinder_top": {
        "force": [{"table": [[0.0, 0.0], [0.5, 0.0], [1.0, Q]]},
                  {"table": [[0.0, 0.0], [0.5, -P], [1.0, -P]]}], "rotation": 0.0}}}
    raw["time"] = {"T": 1.0, "N": 2}
    raw["solver"]["method"] = method
    if method == "snes_vi":
        raw["petsc"] = {"snes_type": "vinewtonssls"}
    result = run_case(make_case(raw))
    assert result.status == "completed" and result.summary["solver"]["used"] == method
    force = result.summary["steps"][-1]["contact_force"]
    assert force[0] == pytest.approx(-Q, rel=1e-6) and force[1] == pytest.approx(P, rel=1e-6)
    tab = contact_table(result.problem)
    order = np.argsort(tab["x"])
    x, p, state = tab["x"][order], tab["neg_sigma_nu"][order], tab["slip_state"][order]
    stick = np.flatnonzero((p > 1e-6 * p.max()) & (state == 0))
    i, j = stick.min(), stick.max()
    assert (state[i:j + 1] == 0).all() and state[i - 1] == state[j + 1] == 1
    c = ((x[j] + x[j + 1]) / 2 - (x[i - 1] + x[i]) / 2) / 2
    a, _ = hertz_cylinders(P, 1.0, float("inf"), 1000.0, 0.3, 1000.0, 0.3)
    assert abs(c - a * np.sqrt(1 - Q / (mu * P))) <= 0.05 * a
