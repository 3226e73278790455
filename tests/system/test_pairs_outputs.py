"""The outputs of two bodies in contact (contact.pairs): the force on each body of a pair
(summary.json's pair_forces, history.csv's pair<i>_<group>_<axis>), contact.xdmf with the
pair's fields; and none of them in a single-body run.

References: the contact patch test's closed form (two stacked blocks of moduli E_l, E_u
under a uniform compression delta of heights 1 with free lateral sides: the interface
pressure p = delta / (1/E_l' + 1/E_u'), E' = E / (1 - nu^2) in plane strain); each body's
equilibrium (its supports' reactions plus its contact force sum to zero: no other load).
"""
import csv
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial import cKDTree

from conftest import cli_in_process, make_case, run_case, run_cli
from vpcontact.io.history import history_columns
from vpcontact.post.results import check_results

PATCH = str(Path(__file__).parents[1] / "data" / "patch2d.geo")
NU, E_LOWER, E_UPPER, DELTA = 0.3, 2000.0, 1000.0, 0.01


def _raw(loads: dict, friction=None, N: int = 1) -> dict:
    """The patch test's blocks, lower_top (the finer side) the surface."""
    pair = {"surface": "lower_top", "target": "upper_bottom"}
    if friction:
        pair["friction"] = friction
    mat = {"nu": NU, "plane": "strain"}
    return {"mesh": {"file": PATCH, "dim": 2},
            "materials": {"lower": {"E": E_LOWER, **mat}, "upper": {"E": E_UPPER, **mat}},
            "boundaries": {"clamped": []}, "contact": {"pairs": [pair]},
            "loads": {"displacement": loads}, "time": {"T": 1.0, "N": N}}


def test_pair_forces_equal_the_patch_tests_closed_form():
    """Frictionless uniform compression: the force on the upper (target) body is +p, on the
    lower (surface) one -p, per unit width 1."""
    loads = {"lower_bottom": [None, 0.0], "lower_left": [0.0, None],
             "upper_left": [0.0, None], "upper_top": [None, f"-{DELTA} * t"]}
    result = run_case(make_case(_raw(loads)))
    assert result.status == "completed"
    step = result.summary["steps"][-1]
    plane = 1 - NU ** 2
    p = DELTA / (plane / E_LOWER + plane / E_UPPER)
    (pair,) = step["pair_forces"]
    assert (pair["surface"], pair["target"]) == ("lower_top", "upper_bottom")
    assert pair["on_surface"] == pytest.approx([0.0, -p], rel=1e-9, abs=1e-9 * p)
    assert pair["on_target"] == pytest.approx([0.0, p], rel=1e-9, abs=1e-9 * p)
    assert step["contact_force"] == pytest.approx(pair["on_surface"], rel=1e-12, abs=1e-12)


@pytest.fixture(scope="module")
def sheared(tmp_path_factory):
    """The blocks pressed and sheared with Coulomb friction (the command line, in this
    process): the results directory."""
    tmp = tmp_path_factory.mktemp("pairs_outputs")
    loads = {"lower_bottom": [0.0, 0.0], "upper_top": [f"{DELTA / 2} * t", f"-{DELTA} * t"]}
    (tmp / "case.yaml").write_text(json.dumps(_raw(loads, {"coulomb": {"mu": 0.3}}, N=2)))
    out = tmp / "out"
    assert cli_in_process(["run", tmp / "case.yaml", "--out", out, "--no-plots",
                           "--quiet"]) == 0
    return out


def test_each_body_is_in_equilibrium_and_the_pair_forces_are_opposite(sheared):
    steps = json.loads((sheared / "summary.json").read_text())["steps"]
    for step in steps:
        (pair,) = step["pair_forces"]
        on_lower, on_upper = np.array(pair["on_surface"]), np.array(pair["on_target"])
        scale = np.abs(on_lower).max()
        assert abs(on_lower[0]) > 0.05 * scale                 # a shear is transmitted
        reactions = {k: np.array(v) for k, v in step["reactions"].items()}
        assert np.abs(on_lower + on_upper).max() <= 1e-9 * scale
        assert np.abs(reactions["lower_bottom"] + on_lower).max() <= 1e-9 * scale
        assert np.abs(reactions["upper_top"] + on_upper).max() <= 1e-9 * scale


def test_history_csv_has_the_pair_force_columns(sheared):
    steps = json.loads((sheared / "summary.json").read_text())["steps"]
    with open(sheared / "history.csv") as fh:
        rows = list(csv.DictReader(fh))
    names = [f"pair0_{g}_{a}" for g in ("lower_top", "upper_bottom") for a in "xy"]
    assert set(names) <= set(rows[0])
    for row, step in zip(rows, steps, strict=True):
        pair = step["pair_forces"][0]
        assert [float(row[n]) for n in names] == pair["on_surface"] + pair["on_target"]


def _last_grid(path: Path) -> dict:
    """contact.xdmf's last time: its point arrays (read from contact.h5 where the XML's
    DataItems point) and the facet mesh's points."""
    import xml.etree.ElementTree as ET

    import h5py
    grid = list(ET.parse(path).getroot().iter("Grid"))[-1]
    out = {}
    with h5py.File(path.with_suffix(".h5"), "r") as f:
        out["points"] = f["Mesh/geometry"][...]
        for att in grid.iter("Attribute"):
            item = att.find("DataItem")
            name, dataset = item.text.strip().split(":")
            assert name == "contact.h5"
            assert f[dataset].shape == tuple(int(n) for n in item.get("Dimensions").split())
            out[att.get("Name")] = f[dataset][...]
    return out


def test_contact_xdmf_has_the_pair_fields(sheared):
    check_results(sheared)                       # complete XML, every dataset in contact.h5
    data = _last_grid(sheared / "contact.xdmf")
    with open(sheared / "contact.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(data["points"]) == len(rows) == 8               # lower_top: cells of 1/7
    x = np.array([[float(r["x"]), float(r["y"])] for r in rows])
    dist, at = cKDTree(data["points"][:, :2]).query(x)
    assert dist.max() <= 1e-12
    for name in ("pair", "d", "u_nu", "u_tau", "neg_sigma_tau"):
        assert np.array_equal(data[name][at], [float(r[name]) for r in rows]), name
    assert np.all(data["pair"] == 0.0)


def test_a_single_body_run_has_no_pair_outputs():
    base = ["n", "t", "k", "norm_u_V", "norm_sigma_Q", "norm_kappa_Y", "max_vm", "max_kappa",
            "contact_force_x", "contact_force_y", "reaction_a_x", "reaction_a_y"]
    assert history_columns(2, ["a"], True)[:len(base)] == base
    result = run_case(make_case(mesh={"n": 4}, time={"N": 2}))
    assert all("pair_forces" not in step for step in result.summary["steps"])


def _states(out: Path) -> dict:
    """contact.h5's state codes at each output time, by rounded coordinates."""
    import h5py
    with h5py.File(out / "contact.h5") as f:
        xyz = [tuple(np.round(p, 9)) for p in f["Mesh/geometry"][:]]
        return {int(s): dict(zip(xyz, f[f"Step/{s}/state"][:].ravel()))
                for s in f["Step"]}


def _stack_file(tmp_path, friction2=None) -> Path:
    """_stack_raw as a case file."""
    case = tmp_path / "stack.yaml"
    case.write_text(yaml.safe_dump(_stack_raw(friction2)))
    return case


def _stack_raw(friction2=None) -> dict:
    """tests/data/stack3.geo's three blocks, two Coulomb pairs (the second pair's friction
    ``friction2`` if given), the middle block held sideways only."""
    return {
        "mesh": {"file": str(Path(PATCH).with_name("stack3.geo")), "dim": 2},
        "materials": {b: {"E": 1000.0, "nu": 0.3, "plane": "strain"}
                      for b in ("bottom", "middle", "top")},
        "boundaries": {"clamped": ["bottom_bottom"]},
        "contact": {"pairs": [
            {"surface": "bottom_top", "target": "middle_bottom",
             "friction": {"coulomb": {"mu": 0.2}}},
            {"surface": "middle_top", "target": "top_bottom",
             "friction": friction2 or {"coulomb": {"mu": 0.4}}}]},
        "loads": {"f0": [0.0, -0.5], "displacement": {
            "top_top": [{"table": [[0, 0], [1, 0.01]]}, -0.01],
            "middle_left": [{"table": [[0, 0], [1, 0.005]]}, None]}},
        "time": {"T": 1.0, "N": 1}, "solver": {"delta": 1e-8}}


def test_touching_states_at_t0_do_not_depend_on_the_rank_count(tmp_path):
    """tests/data/stack3.geo: three blocks that touch (d = 0 in the geometry, +-2e-16 as
    measured on the mesh), Coulomb pairs without compliance: at t = 0 (u = 0) every node of
    both pairs is at its bound (state 2), serial and under mpirun -n 2, and the states
    agree at every output time.  Before, u_nu = -d = -2e-16 was 'separated' (0) at some
    nodes, at different nodes for 1 and 2 ranks (the tolerance was relative to u alone,
    0 at t = 0; now U_ROUNDOFF times the body's length scale as well)."""
    case = _stack_file(tmp_path)
    states = {}
    for n in (1, 2):
        proc = run_cli(["run", case, "--out", tmp_path / f"np{n}", "--quiet"], nprocs=n)
        assert proc.returncode == 0, proc.stderr
        states[n] = _states(tmp_path / f"np{n}")
    for n in (1, 2):
        codes = np.array(list(states[n][0].values()))
        assert len(codes) == 14 and np.all(codes == 2), (n, codes)
    assert states[1] == states[2]


def test_wellposedness_names_the_body_held_only_by_contact(tmp_path, capsys):
    """The middle block of the stack is held vertically only by the pairs: K of the trace
    constant is singular, ||gamma||^2 = inf.  With a softening law (4.2) on a pair, check
    says (2.6) cannot be checked for that reason and that uniqueness is not guaranteed;
    before, it printed "10 x inf: margin -inf ... the friction softening c1 is too large"."""
    case = _stack_file(tmp_path, {"b": 0.5, "c1": 10.0, "c2": 20.0, "u1": 0.01})
    assert cli_in_process(["check", case]) == 0
    out = capsys.readouterr()
    text = out.out + out.err
    assert "(2.6) cannot be checked: the trace constant ||gamma||^2 is unbounded because a " \
        "body is held only by contact" in text
    assert "uniqueness of the solution is not guaranteed" in text
    assert "c1 is too large" not in text and "x inf" not in text


def test_contact_force_of_two_pairs_is_the_sum_over_their_surfaces():
    """The stack's two pairs have different surface bodies (bottom, middle): contact_force
    is the sum of the pairs' on_surface (the documented meaning, kept), pair_forces gives
    each pair's force on each body, and the forces on the middle block (pair 0's target,
    pair 1's surface) are not contact_force.  Pins the meaning; the per-pair report was
    already there."""
    steps = run_case(make_case(_stack_raw())).summary["steps"]
    last = steps[-1]
    pairs = last["pair_forces"]
    assert [(p["surface"], p["target"]) for p in pairs] == [("bottom_top", "middle_bottom"),
                                                           ("middle_top", "top_bottom")]
    total = np.sum([p["on_surface"] for p in pairs], axis=0)
    scale = np.abs([p["on_surface"] for p in pairs]).max()
    assert np.abs(np.array(last["contact_force"]) - total).max() <= 1e-12 * scale
    assert np.abs(np.array(pairs[0]["on_surface"]) - last["contact_force"]).max() > 1e-3 * scale
