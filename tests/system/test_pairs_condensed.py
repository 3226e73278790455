"""The condensed solver for two bodies in contact (app/solvers/condensed/pairs.py) solves the
same discrete problem as SNES VI's PairMap: the same case run with solver.method snes_vi
and condensed gives the same u and contact table to 1e-9 (relative to the largest
displacement or contact pressure; the stick/slip state where the node carries a friction
bound), with no step
handed to the SNES VI fallback:

- a frictionless pair with normal compliance and an extra gap g, pressed unevenly so that
  part of the interface reaches the bound and part stays in the compliance (2D);
- the contact patch test's geometry (tests/data/patch2d.geo, non-matching meshes), hard
  contact;
- Coulomb friction: the block on a block pressed, then pushed sideways into partial slip
  (the fixed point on p_n calls the condensed solver several times per step);
- laws per pair (compliance and memory on one pair, Coulomb on the other);
- 3D: the stacked cubes of tests/data/patch3d.geo, hard contact;
- mpirun -n 2 (MUMPS with Schur variables, G over both ranks) equals the serial condensed
  run, with Coulomb friction;
- a body held only by the contact pair (the viscoplastic punch of
  cases/punch_on_substrate.yaml, coarse): K is singular, the Gamma3 problem is solved in
  the reduced right-hand side r = S y0 (S semidefinite);
- the same punch under mpirun -n 2 (MUMPS's Schur complement, semidefinite, no factor of
  it) equals the serial condensed run;
- the rules: a body held only by a contact pair is refused with fast_* PETSc options
  (``condensed``: by name; ``auto``: SNES VI), and ``auto`` picks the condensed solver for
  pairs otherwise.
"""
import h5py
import numpy as np
import pytest

from conftest import ROOT, make_case, run_case, run_cli
from vpcontact.io.errors import CaseError
from vpcontact.post.quantities import contact_table

E, NU, DELTA = 1000.0, 0.3, 1e-8
ELASTIC = {"E": E, "nu": NU, "plane": "strain"}
COLUMNS = ("u_x", "u_y", "u_nu", "u_tau", "neg_sigma_nu", "neg_sigma_tau")


def _blocks(contact_pair: dict, displacement: dict, N: int = 2, **contact) -> dict:
    """patch2d.geo: the lower block clamped at its bottom, rollers on both left sides, its
    top (the finer side) the surface of the pair."""
    return {"mesh": {"file": str(ROOT / "tests" / "data" / "patch2d.geo"), "dim": 2},
            "materials": {"upper": ELASTIC, "lower": ELASTIC},
            "boundaries": {"clamped": ["lower_bottom"]},
            "contact": {"pairs": [{"surface": "lower_top", "target": "upper_bottom",
                                   **contact_pair}], **contact},
            "loads": {"displacement": {"upper_left": [0.0, None], "lower_left": [0.0, None],
                                       **displacement}},
            "time": {"T": 1.0, "N": N}, "solver": {"delta": DELTA}}


def _both(raw: dict):
    """The case run with SNES VI and with the condensed solver (in this process)."""
    out = []
    for method in ("snes_vi", "condensed"):
        raw = {**raw, "solver": {**raw.get("solver", {}), "method": method}}
        result = run_case(make_case(raw))
        assert result.status == "completed"
        assert result.summary["solver"]["used"] == method
        assert not any("fallback" in s for s in result.summary["steps"])
        out.append(result)
    return out


def _assert_same(snes, cond, tol=1e-9) -> dict:
    """u and the contact table of the two runs agree to tol (relative); returns the
    condensed run's table."""
    u1, u2 = snes.problem.u.x.array, cond.problem.u.x.array
    assert np.abs(u2 - u1).max() <= tol * np.abs(u1).max()
    t1, t2 = contact_table(snes.problem), contact_table(cond.problem)
    keys = [k for k in t1 if k.startswith(("u_", "neg_sigma", "friction_bound", "xi"))]
    assert set(COLUMNS) <= set(keys) or "u_z" in keys
    for key in keys:       # NaN: the column of another pair's laws (laws per pair)
        np.testing.assert_array_equal(np.isnan(t2[key]), np.isnan(t1[key]))
        # relative to the displacements' or the contact stresses' largest value
        scale = np.abs(t1["neg_sigma_nu"]).max() if not key.startswith("u_") else \
            np.abs(u1).max()
        assert np.nanmax(np.abs(t2[key] - t1[key]), initial=0.0) <= tol * scale, key
    if "slip_state" in t1:
        carried = t1["friction_bound"] > 1e-6 * t1["friction_bound"].max()
        np.testing.assert_array_equal(t2["slip_state"][carried], t1["slip_state"][carried])
    return t2


def test_compliance_and_gap_2d():
    """Normal compliance c_nu = 5000 and g = 0.0025, the top pushed down by 0.012 (1 + 2 x):
    nodes at the bound and nodes in the compliance."""
    g = 0.0025
    raw = _blocks({"g": g, "normal_compliance": {"c_nu": 5000.0}},
                  {"upper_top": [None, "-0.012 * (1 + 2 * x) * t"]})
    tab = _assert_same(*_both(raw))
    assert (tab["u_nu"] > g - 1e-12).any()
    assert ((tab["u_nu"] > 1e-5) & (tab["u_nu"] < 0.9 * g)).any()


def test_patch_test_geometry_hard_contact():
    """Hard contact on the non-matching blocks of the patch test, pressed by 0.01."""
    raw = _blocks({}, {"upper_top": [None, "-0.01 * t"]})
    tab = _assert_same(*_both(raw))
    assert (tab["neg_sigma_nu"] > 1.0).all()


def test_coulomb_block_on_block():
    """Pressed by 0.01, then pushed sideways by 0.004 in two steps: partial slip, the fixed
    point on p_n solving each step several times."""
    raw = _blocks({"friction": {"coulomb": {"mu": 0.3}}},
                  {"upper_top": [{"table": [[0.0, 0.0], [1 / 3, 0.0], [1.0, 0.004]]},
                                 {"table": [[0.0, 0.0], [1 / 3, -0.01], [1.0, -0.01]]}]},
                  N=3)
    raw["loads"]["displacement"].pop("upper_left")
    snes, cond = _both(raw)
    tab = _assert_same(snes, cond)
    assert (tab["slip_state"] == 1).any() and (tab["slip_state"] == 0).any()


def test_laws_per_pair():
    """Three stacked blocks (tests/data/stack3.geo), pair 0 frictionless with normal
    compliance, memory and g = 0.01, pair 1 Coulomb with hard contact; pressed, then pushed
    sideways (the middle block's left side held vertically: a body held only by a pair is
    not for the condensed solver)."""
    elastic = {"E": E, "nu": NU, "plane": "strain"}
    raw = {"mesh": {"file": str(ROOT / "tests" / "data" / "stack3.geo"), "dim": 2},
           "materials": {"bottom": elastic, "middle": elastic, "top": elastic},
           "boundaries": {"clamped": ["bottom_bottom"]},
           "contact": {"pairs": [
               {"surface": "bottom_top", "target": "middle_bottom", "g": 0.01,
                "normal_compliance": {"c_nu": 2000.0}, "memory": {"b0": 500.0, "beta": 2.0}},
               {"surface": "middle_top", "target": "top_bottom",
                "friction": {"coulomb": {"mu": 0.3}}}]},
           "loads": {"f0": [0.0, -0.5], "displacement": {
               "top_top": [{"table": [[0.0, 0.0], [1 / 3, 0.0], [1.0, 0.06]]},
                           {"table": [[0.0, 0.0], [1 / 3, -0.01], [1.0, -0.01]]}],
               "middle_left": [{"table": [[0.0, 0.0], [1 / 3, 0.0], [1.0, 0.03]]}, 0.0]}},
           "time": {"T": 1.0, "N": 3}, "solver": {"delta": DELTA}}
    snes, cond = _both(raw)
    tab = _assert_same(snes, cond)
    on0 = tab["pair"] == 0
    assert (tab["xi"][on0] > 0).any() and (tab["slip_state"][~on0] == 1).any()


def test_3d_stacked_cubes_hard_contact():
    """patch3d.geo: the lower cube clamped at its bottom, rollers on the symmetry planes,
    the upper top pressed by 0.01."""
    sym = {f"{b}_{side}": comps for b in ("upper", "lower")
           for side, comps in (("left", [0.0, None, None]), ("front", [None, 0.0, None]))}
    raw = {"mesh": {"file": str(ROOT / "tests" / "data" / "patch3d.geo"), "dim": 3},
           "materials": {"upper": {"E": E, "nu": NU}, "lower": {"E": E, "nu": NU}},
           "boundaries": {"clamped": ["lower_bottom"]},
           "contact": {"pairs": [{"surface": "lower_top", "target": "upper_bottom"}]},
           "loads": {"displacement": {"upper_top": [None, None, "-0.01 * t"], **sym}},
           "time": {"T": 1.0, "N": 1}}
    tab = _assert_same(*_both(raw))
    assert (tab["neg_sigma_nu"] > 1.0).all()


def test_mpirun_equals_serial(tmp_path):
    """The Coulomb block on a block under mpirun -n 2 (the condensed solver's MUMPS back
    end, G on both ranks) equals the serial condensed run at every vertex to 1e-9."""
    raw = _blocks({"friction": {"coulomb": {"mu": 0.3}}},
                  {"upper_top": [{"table": [[0.0, 0.0], [0.5, 0.0], [1.0, 0.003]]},
                                 {"table": [[0.0, 0.0], [0.5, -0.01], [1.0, -0.01]]}]})
    raw["loads"]["displacement"].pop("upper_left")
    raw["solver"]["method"] = "condensed"
    import yaml
    case = tmp_path / "blocks.yaml"
    case.write_text(yaml.safe_dump({"name": "blocks", **raw}))
    out = tmp_path / "np2"
    proc = run_cli(["run", case, "--out", out, "--quiet"], nprocs=2)
    serial = run_case(make_case(raw))
    assert proc.returncode == 0, proc.stderr
    assert serial.summary["solver"]["used"] == "condensed"
    with h5py.File(out / "solution.h5", "r") as f:
        last = max(f["Function/u"].keys(), key=lambda k: float(k.replace("_", ".")))
        x2, u2 = f["Mesh/mesh/geometry"][:, :2], f[f"Function/u/{last}"][:, :2]
    x1 = serial.problem.disc.V.tabulate_dof_coordinates()[:, :2]
    u1 = serial.problem.u.x.array.reshape(-1, 2)
    # the blocks' corner nodes at y = 1 share coordinates: ties broken by u
    order = [np.lexsort((u[:, 0], u[:, 1], np.round(x[:, 1], 9), np.round(x[:, 0], 9)))
             for x, u in ((x1, u1), (x2, u2))]
    np.testing.assert_array_equal(np.round(x1[order[0]], 9), np.round(x2[order[1]], 9))
    np.testing.assert_allclose(u2[order[1]], u1[order[0]], rtol=0,
                               atol=1e-9 * np.abs(u1).max())


def _punch_raw(method: str) -> dict:
    """cases/punch_on_substrate.yaml coarse (mesh.size 3), the ramp and two creep steps."""
    import yaml
    raw = yaml.safe_load((ROOT / "cases" / "punch_on_substrate.yaml").read_text())
    raw["mesh"].update(file=str(ROOT / "cases" / raw["mesh"]["file"]), size=3.0)
    raw["time"].update(T=0.24, N=3)
    raw["solver"] = {"method": method}
    return raw


def test_body_held_only_by_the_contact():
    """The viscoplastic punch on its substrate, its vertical translation held only by the
    contact pair (K singular, S semidefinite: the Gamma3 problem in r = S y0), Coulomb
    friction: condensed == SNES VI.  The contact nodes stick, friction carrying up to
    0.88 mu p_n (measured; the slip_state 1 read here before was the separated nodes',
    whose bound mu p_n is round-off: now -1)."""
    snes, cond = _both(_punch_raw("snes_vi"))
    tab = _assert_same(snes, cond)
    contact = tab["neg_sigma_nu"] > 1.0
    assert contact.any() and (tab["slip_state"][contact] == 0).all()
    assert (np.abs(tab["neg_sigma_tau"]) > 0.8 * tab["friction_bound"])[contact].any()
    assert (tab["slip_state"] == -1).any()


def test_body_held_only_by_the_contact_under_mpirun(tmp_path):
    """The punch under mpirun -n 2 (MUMPS, S semidefinite) equals the serial condensed run:
    contact.csv to 1e-9 of each column's largest value (the stick/slip state where the node
    carries a friction bound)."""
    import csv

    import yaml
    case = tmp_path / "punch.yaml"
    case.write_text(yaml.safe_dump(_punch_raw("condensed")))
    rows = []
    for nprocs in (1, 2):
        out = tmp_path / f"np{nprocs}"
        proc = run_cli(["run", case, "--out", out, "--quiet"], nprocs=nprocs)
        assert proc.returncode == 0, proc.stderr
        with open(out / "contact.csv") as f:
            rows.append(list(csv.DictReader(f)))
    one, two = ({k: np.array([float(r[k]) for r in rs]) for k in rs[0] if k != "state"}
                for rs in rows)
    carried = one["friction_bound"] > 1e-6 * one["friction_bound"].max()
    np.testing.assert_array_equal(two["slip_state"][carried], one["slip_state"][carried])
    for key in (k for k in one if k != "slip_state"):
        assert np.abs(two[key] - one[key]).max() <= 1e-9 * np.abs(one[key]).max(), key


def test_rules():
    """A body held only by the contact with fast_* options: ``condensed``
    refused naming the reason, ``auto`` SNES VI; serially without them, and for a pair
    whose bodies are held, auto picks the condensed solver."""
    from mpi4py import MPI

    from vpcontact.model.problem import ContactProblem
    from vpcontact.simulation import build_mesh
    from vpcontact.solvers import choose_method, condensed_eligible, gamma3_dofs
    raw = _punch_raw("condensed")
    raw["petsc"] = {"fast_pc_factor_mat_solver_type": "mumps"}
    case = make_case(raw)
    disc = ContactProblem(case, build_mesh(case, MPI.COMM_WORLD)).disc
    assert condensed_eligible(case)[0]                 # the case's rules alone: eligible
    ok, why = condensed_eligible(case, disc)
    assert not ok and "held only by a contact pair" in why and "fast_*" in why
    with pytest.raises(CaseError, match="'condensed' is not possible here: a body's rigid"):
        choose_method(case, gamma3_dofs(disc), disc)
    raw["solver"]["method"] = "auto"
    assert choose_method(make_case(raw), gamma3_dofs(disc), disc) == "snes_vi"
    assert choose_method(make_case(_punch_raw("auto")), gamma3_dofs(disc), disc) == "condensed"
    held = make_case(_blocks({}, {"upper_top": [None, "-0.01 * t"]}))
    assert held.numerics.method == "auto"
    assert run_case(held).summary["solver"]["used"] == "condensed"
