"""General scenes: the user's gmsh meshes, named boundary groups, curved contact, gap
fields, prescribed displacements and plane strain, checked against closed forms (Hertz, a
uniform strain), symmetry (rotation invariance), the two step solvers against each other and
the KKT conditions of the bound."""
import json

import numpy as np
import pytest
import yaml
from mpi4py import MPI

from conftest import PAPER_CASE, ROOT, run_cli
from meshtools import rotation_2d, rotation_3d, write_rotated_box, write_rotated_square
from vpcontact.post.quantities import contact_table

HERTZ = ROOT / "cases" / "hertz_cylinder.yaml"
NORMS = ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y", "max_vm", "max_kappa")


def _run(path, overrides=()):
    from vpcontact.case import load_case
    from vpcontact.simulation import run
    result = run(load_case(path, list(overrides)), MPI.COMM_WORLD)
    assert result.status == "completed"
    return result


def _write(tmp_path, raw: dict, name="case.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(raw))
    return path


def _hertz_raw(tmp_path, **contact) -> dict:
    raw = yaml.safe_load(HERTZ.read_text())
    raw["mesh"]["file"] = str(ROOT / "cases" / "hertz_cylinder.geo")
    raw["contact"].update(contact)
    raw["contact"] = {k: v for k, v in raw["contact"].items() if v is not None}
    return raw


# ----------------------------------------------------------------------------- Hertz 2D
def _hertz_fit(x, p):
    """p0 and a of p = p0 sqrt(1 - x^2 / a^2), fitted by least squares of p^2 against x^2
    on the nodes inside the contact (the edge node, with its partial load, left out)."""
    inside = p > 1e-6 * p.max()
    edge = x[inside].max()
    use = inside & (x < edge)
    B, A = np.polyfit(x[use] ** 2, p[use] ** 2, 1)
    return np.sqrt(A), np.sqrt(-A / B), edge


def test_hertz_cylinder_half_width_and_pressure():
    result = _run(HERTZ)
    tab = contact_table(result.problem)
    step = result.summary["steps"][-1]
    P = 2.0 * step["contact_force"][1]                 # the whole cylinder: two quarters
    E, nu, R = 1000.0, 0.3, 1.0
    E_star = E / (1.0 - nu ** 2)
    a = np.sqrt(4.0 * P * R / (np.pi * E_star))
    p0 = 2.0 * P / (np.pi * a)
    x, p = tab["x"], tab["neg_sigma_nu"]
    p0_fit, a_fit, edge = _hertz_fit(x, p)
    assert p0_fit == pytest.approx(p0, rel=0.02)
    assert a_fit == pytest.approx(a, rel=0.02)
    h = np.diff(np.sort(x)).max(initial=0.0)
    inner = x < a - 2 * 0.003                          # the profile, off the edge singularity
    hertz = p0 * np.sqrt(np.clip(1 - (x / a) ** 2, 0, None))
    assert np.abs(p[inner] - hertz[inner]).max() <= 0.03 * p0
    off = (x > a + 0.01) & (tab["y"] < 0.5)             # not the top's corner (prescribed)
    assert np.all(p[off] == pytest.approx(0.0, abs=1e-9 * p0)) and h > 0
    # equilibrium: the push on the top balances the foundation's force
    assert step["reactions"]["top"][1] == pytest.approx(-step["contact_force"][1], rel=1e-9)


@pytest.mark.parametrize("direction", [[0.0, -1.0], None], ids=["direction", "nodal-normals"])
def test_hertz_fast_equals_snes_vi_and_kkt(tmp_path, direction):
    """Both step solvers (the fast one in nodal frames, SNES VI in rotated coordinates on a
    curved Gamma3) solve the same discrete problem; the bound's KKT conditions hold."""
    path = _write(tmp_path, _hertz_raw(tmp_path, direction=direction))
    tabs = {}
    for method in ("fast", "snes_vi"):
        res = _run(path, [f"solver.method={method}"])
        tabs[method] = contact_table(res.problem)
        pb = res.problem
        pos = np.searchsorted(pb.disc.frames.nodes, pb.disc.gamma3.nodes)
        # the nodes with no prescribed component (the roller's and the top's are reactions)
        free = ~pb.disc.dirichlet.fixed[pb.disc.gamma3.nodes].any(axis=1)
        g = pb.disc.frames.g[pos][free]
    for col in ("u_x", "u_y", "u_nu", "neg_sigma_nu"):
        a, b = tabs["fast"][col], tabs["snes_vi"][col]
        assert np.abs(a - b).max() <= 1e-8 * np.abs(b).max(), col
    tab = {k: v[free] for k, v in tabs["snes_vi"].items()}
    assert free.sum() >= len(free) - 2
    u_nu, p = tab["u_nu"], tab["neg_sigma_nu"]
    scale_u, scale_p = 0.015, np.abs(p).max()
    assert np.all(u_nu <= g + 1e-10 * scale_u)                     # the bound
    assert np.all(p >= -1e-8 * scale_p)                            # compression only
    assert np.abs(p * (g - u_nu)).max() <= 1e-8 * scale_p * scale_u  # complementarity
    assert np.abs(tab["neg_sigma_tau"]).max() <= 1e-8 * scale_p    # frictionless


@pytest.mark.parametrize("name, steps", [("punch_relaxation", 20),
                                         pytest.param("sphere3d", 2, marks=pytest.mark.slow)])
def test_shipped_scenes_fast_equals_snes_vi(name, steps):
    """The shipped scenes (a viscoplastic punch with a gap field; a ball in a compliant,
    frictional socket in rotated 3D frames): both step solvers agree to 1e-8 at every step,
    and the forces on the body balance (no body force or traction in these cases)."""
    runs = {m: _run(ROOT / "cases" / f"{name}.yaml", [f"solver.method={m}", f"time.N={steps}"])
            for m in ("fast", "snes_vi")}
    for a, b in zip(runs["fast"].summary["steps"], runs["snes_vi"].summary["steps"],
                    strict=True):
        for key in NORMS:
            assert a[key] == pytest.approx(b[key], rel=1e-8, abs=1e-14), key
        total = np.sum(list(b["reactions"].values()), axis=0) + b["contact_force"]
        assert np.abs(total).max() <= 1e-8 * np.abs(b["contact_force"]).max()
    ua = runs["fast"].problem.u.x.array
    ub = runs["snes_vi"].problem.u.x.array
    assert np.abs(ua - ub).max() <= 1e-8 * np.abs(ub).max()


def test_shipped_friction_table_fast_equals_snes_vi():
    """The shipped case with a nonmonotone friction table and a compliance table
    (cases/friction_table.yaml): both step solvers agree to 1e-8 at every step and at T,
    and (2.6) is checked with m_j the table's steepest softening (90 N/m^3)."""
    runs = {m: _run(ROOT / "cases" / "friction_table.yaml", [f"solver.method={m}"])
            for m in ("fast", "snes_vi")}
    for a, b in zip(runs["fast"].summary["steps"], runs["snes_vi"].summary["steps"],
                    strict=True):
        for key in NORMS:
            assert a[key] == pytest.approx(b[key], rel=1e-8, abs=1e-14), key
    ua, ub = runs["fast"].problem.u.x.array, runs["snes_vi"].problem.u.x.array
    assert np.abs(ua - ub).max() <= 1e-8 * np.abs(ub).max()
    tab = contact_table(runs["snes_vi"].problem)
    assert np.abs(tab["u_tau"]).max() > 0.005          # slip past the softening branch
    diag = runs["snes_vi"].summary["diagnostics"]
    assert diag["m_j"] == pytest.approx(90.0, rel=1e-12) and diag["unique"]


def test_kinked_contact_boundary(tmp_path):
    """Gamma3 = bottom and right sides of the square (a kink at (1, 0)): the corner's normal
    is the area-weighted (1, -1)/sqrt(2), its frame rotated; both solvers agree to 1e-8 and
    the bound holds at every node."""
    raw = yaml.safe_load(PAPER_CASE.read_text())
    raw["mesh"]["n"] = 8
    raw["boundaries"] = {"clamped": ["left"], "contact": ["bottom", "right"]}
    raw["loads"]["traction"] = {"top": [4.0, -8.0]}
    raw["contact"]["g"] = 0.002
    raw["time"]["N"] = 2
    path = _write(tmp_path, raw)
    runs = {m: _run(path, [f"solver.method={m}"]) for m in ("fast", "snes_vi")}
    p = runs["snes_vi"].problem
    fr = p.disc.frames
    x = p.disc.V.tabulate_dof_coordinates()[fr.nodes, :2]
    corner = np.flatnonzero((np.abs(x[:, 0] - 1) < 1e-12) & (np.abs(x[:, 1]) < 1e-12))
    assert len(corner) == 1 and fr.rotated
    np.testing.assert_allclose(fr.normal[corner[0]], [2 ** -0.5, -2 ** -0.5], atol=1e-14)
    ua, ub = runs["fast"].problem.u.x.array, p.u.x.array
    assert np.abs(ua - ub).max() <= 1e-8 * np.abs(ub).max()
    u_nu = np.einsum("ij,ij->i", p.u.x.array.reshape(-1, 2)[fr.nodes], fr.normal)
    assert np.all(u_nu <= fr.g + 1e-12) and np.any(u_nu >= fr.g - 1e-12)


# ----------------------------------------------------------------------------- rotation
def _paper_rotated(tmp_path, angle, steps):
    raw = yaml.safe_load(PAPER_CASE.read_text())
    R = rotation_2d(angle)
    msh = write_rotated_square(tmp_path / "square.msh", raw["mesh"]["n"], angle,
                               raw["mesh"]["diagonal"])
    raw["mesh"] = {"file": str(msh), "dim": 2}
    raw["boundaries"] = {"clamped": ["left"], "contact": ["bottom"]}
    raw["loads"]["traction"] = {k: [float(c) for c in R @ np.array(v, float)]
                                for k, v in raw["loads"]["traction"].items()}
    raw["time"]["N"] = steps
    return _write(tmp_path, raw, "rotated.yaml"), R


def _matched(back: np.ndarray, x_ref: np.ndarray):
    """The orders that put the rotated-back nodes and the reference nodes side by side.

    Both are sorted by their coordinates rounded to 1e-9: the reference's exact float order
    is not enough, as gmsh's coordinates differ in the last bits between CPUs (0.25 against
    0.25000000000000006 sorted a node before its neighbour on one machine and not on
    another).  The coordinates then agree to 1e-12."""
    def key(x):
        return np.lexsort(tuple(np.round(x[:, i], 9) for i in reversed(range(x.shape[1]))))
    order, ref = key(back), key(x_ref)
    np.testing.assert_allclose(back[order], x_ref[ref], atol=1e-12)
    return order, ref


@pytest.mark.parametrize("method", ["fast", "snes_vi"])
def test_paper_case_rotated_by_30_degrees(tmp_path, method):
    """The paper's scene on the unit square rotated by 30 degrees (the same triangles, read
    from a .msh, tractions rotated) gives the unrotated run's norms and Gamma3 profile in
    local coordinates to 1e-8."""
    path, R = _paper_rotated(tmp_path, 30.0, 4)
    over = [f"solver.method={method}", "time.N=4"]
    ref, rot = _run(PAPER_CASE, over), _run(path, [f"solver.method={method}"])
    for a, b in zip(ref.summary["steps"], rot.summary["steps"], strict=True):
        for key in NORMS:
            assert b[key] == pytest.approx(a[key], rel=1e-8, abs=1e-14), key
    t_ref, t_rot = contact_table(ref.problem), contact_table(rot.problem)
    back = np.column_stack([t_rot["x"], t_rot["y"]]) @ R        # R^T x, row-wise
    order, ref = _matched(back, np.column_stack([t_ref["x"], t_ref["y"]]))
    for col in ("u_nu", "u_tau", "neg_sigma_nu", "neg_sigma_tau"):
        scale = np.abs(t_ref[col]).max()
        np.testing.assert_allclose(t_rot[col][order], t_ref[col][ref], rtol=0,
                                   atol=1e-8 * scale, err_msg=col)


@pytest.mark.parametrize("method", ["fast", "snes_vi"])
def test_box_rotated_3d(tmp_path, method):
    """The 3D box case (n = 4) rotated by 30 degrees about z and 20 about x, from a .msh with
    the same tetrahedra and rotated tractions: the unrotated run's norms and Gamma3 profile
    (u_nu, |u_tau|, the pressure, |sigma_tau|: the tangent frames differ) to 1e-8."""
    raw = yaml.safe_load((ROOT / "cases" / "box3d.yaml").read_text())
    R = rotation_3d((30.0, 20.0))
    msh = write_rotated_box(tmp_path / "box.msh", 4, (30.0, 20.0))
    raw["mesh"] = {"file": str(msh), "dim": 3}
    raw["boundaries"] = {"clamped": ["left"], "contact": ["bottom"]}
    raw["loads"]["traction"] = {k: [float(c) for c in R @ np.array(v, float)]
                                for k, v in raw["loads"]["traction"].items()}
    raw["time"]["N"] = 2
    over = ["mesh.n=4", "time.N=2", f"solver.method={method}"]
    ref, rot = _run(ROOT / "cases" / "box3d.yaml", over), \
        _run(_write(tmp_path, raw, "rotated.yaml"), [f"solver.method={method}"])
    for a, b in zip(ref.summary["steps"], rot.summary["steps"], strict=True):
        for key in NORMS:
            assert b[key] == pytest.approx(a[key], rel=1e-8, abs=1e-14), key
    t_ref, t_rot = contact_table(ref.problem), contact_table(rot.problem)
    back = np.column_stack([t_rot[a] for a in "xyz"]) @ R
    order, ref = _matched(back, np.column_stack([t_ref[a] for a in "xyz"]))

    def columns(t):
        return {"u_nu": t["u_nu"], "u_tau": t["u_tau"], "p": t["neg_sigma_nu"],
                "f_tau": np.hypot(t["neg_sigma_tau1"], t["neg_sigma_tau2"])}
    c_ref, c_rot = columns(t_ref), columns(t_rot)
    for col, v in c_ref.items():
        np.testing.assert_allclose(c_rot[col][order], v[ref], rtol=0,
                                   atol=1e-8 * np.abs(v).max(), err_msg=col)


def test_hertz_sphere_3d(tmp_path):
    """An eighth of a sphere (R = 1, E = 1000, nu = 0.3, frictionless, g = z) pushed 0.02
    onto a plane: a and p0 fitted from the pressure within 5% of Hertz's a = (3PR/(4E*))^(1/3),
    p0 = 3P/(2 pi a^2), P = 4 x the eighth's contact force."""
    raw = {"mesh": {"file": str(ROOT / "cases" / "sphere3d.geo"), "dim": 3},
           "material": {"E": 1000.0, "nu": 0.3},
           "boundaries": {"clamped": [], "contact": ["surface"]},
           "contact": {"g": "z", "direction": [0.0, 0.0, -1.0]},
           "loads": {"displacement": {"symx": [0.0, None, None], "symy": [None, 0.0, None],
                                      "top": [None, None, -0.02]}},
           "time": {"T": 1.0, "N": 1}}
    res = _run(_write(tmp_path, raw))
    tab = contact_table(res.problem)
    P = 4.0 * res.summary["steps"][-1]["contact_force"][2]
    E_star = 1000.0 / (1 - 0.3 ** 2)
    a = (3 * P / (4 * E_star)) ** (1 / 3)
    p0 = 3 * P / (2 * np.pi * a ** 2)
    free = ~tab["_prescribed"]
    r, p = np.hypot(tab["x"], tab["y"])[free], tab["neg_sigma_nu"][free]
    p0_fit, a_fit, _ = _hertz_fit(r, p)
    assert p0_fit == pytest.approx(p0, rel=0.05)
    assert a_fit == pytest.approx(a, rel=0.05)


# ----------------------------------------------------------------------------- Dirichlet
def _patch_raw(displacement, clamped=()):
    return {"mesh": {"n": 4, "diagonal": "left"},
            "material": {"E": 1000.0, "nu": 0.3},
            "boundaries": {"clamped": list(clamped), "contact": []},
            "loads": {"displacement": displacement},
            "time": {"T": 1.0, "N": 2}}


@pytest.mark.parametrize("method", ["fast", "snes_vi"])
def test_displacement_patch_test(tmp_path, method):
    """u = A x (t) prescribed on the whole boundary: P1 reproduces the uniform strain
    exactly, at every node and step, and sigma = E eps(u) in every cell."""
    ux, uy = "t*(0.001*x + 0.0005*y)", "t*(0.0005*x - 0.002*y)"
    raw = _patch_raw({s: [ux, uy] for s in ("left", "right", "bottom", "top")})
    raw["solver"] = {"method": method}
    res = _run(_write(tmp_path, raw))
    p = res.problem
    x = p.disc.V.tabulate_dof_coordinates()[:, :2]
    exact = np.column_stack([0.001 * x[:, 0] + 0.0005 * x[:, 1],
                             0.0005 * x[:, 0] - 0.002 * x[:, 1]])
    np.testing.assert_allclose(p.u.x.array.reshape(-1, 2), exact, rtol=0, atol=1e-15)
    E, nu = 1000.0, 0.3
    e = np.array([[0.001, 0.0005], [0.0005, -0.002]])
    sigma = E / (1 - nu ** 2) * nu * np.trace(e) * np.eye(2) + E / (1 + nu) * e
    cells = p.sigma.x.array.reshape(-1, 2, 2)
    np.testing.assert_allclose(cells, np.broadcast_to(sigma, cells.shape), atol=1e-12)


@pytest.mark.parametrize("plane", ["stress", "strain"])
def test_uniaxial_rollers_and_reactions(tmp_path, plane):
    """Rollers on x = 0 and y = 0, u_x = 0.001 t on x = 1: uniaxial stress, u_x = 0.001 t x,
    u_y = -nu' 0.001 t y (nu' = nu, plane stress; nu / (1 - nu), plane strain), and the
    reaction on the right side is E' 0.001 t (E' = E or E / (1 - nu^2))."""
    raw = _patch_raw({"left": [0.0, None], "bottom": [None, 0.0],
                      "right": ["0.001*t", None]})
    raw["material"]["plane"] = plane
    res = _run(_write(tmp_path, raw))
    E, nu = 1000.0, 0.3
    E_eff, nu_eff = (E, nu) if plane == "stress" else (E / (1 - nu ** 2), nu / (1 - nu))
    p = res.problem
    x = p.disc.V.tabulate_dof_coordinates()[:, :2]
    exact = np.column_stack([0.001 * x[:, 0], -nu_eff * 0.001 * x[:, 1]])
    np.testing.assert_allclose(p.u.x.array.reshape(-1, 2), exact, rtol=0, atol=1e-15)
    for step in res.summary["steps"]:
        force = E_eff * 0.001 * step["t"]
        assert step["reactions"]["right"][0] == pytest.approx(force, rel=1e-10)
        assert step["reactions"]["left"][0] == pytest.approx(-force, rel=1e-10)
        assert abs(step["reactions"]["bottom"][1]) <= 1e-10 * force


@pytest.mark.parametrize("method", ["fast", "snes_vi"])
def test_pressure_on_a_group(tmp_path, method):
    """loads.pressure p = 2 t on the right side with rollers on x = 0 and y = 0: uniaxial
    compression, u_x = -p x / E, u_y = nu p y / E (plane stress), the left roller's reaction
    +p."""
    raw = _patch_raw({"left": [0.0, None], "bottom": [None, 0.0]})
    raw["loads"]["pressure"] = {"right": "2.0*t"}
    raw["solver"] = {"method": method}
    res = _run(_write(tmp_path, raw))
    p = res.problem
    x = p.disc.V.tabulate_dof_coordinates()[:, :2]
    exact = np.column_stack([-2.0 * x[:, 0] / 1000.0, 0.3 * 2.0 * x[:, 1] / 1000.0])
    np.testing.assert_allclose(p.u.x.array.reshape(-1, 2), exact, rtol=0, atol=1e-15)
    for step in res.summary["steps"]:
        assert step["reactions"]["left"][0] == pytest.approx(2.0 * step["t"], rel=1e-10)


def test_paper_case_equilibrium():
    """Reactions on Gamma1, the foundation's force and the tractions balance."""
    res = _run(PAPER_CASE, ["time.N=4"])
    loads = np.array([-3.2, -8.0])          # right [-3.2, 0] + top [0, -8] on unit sides
    for step in res.summary["steps"]:
        total = np.array(step["reactions"]["left"]) + np.array(step["contact_force"]) + loads
        assert np.abs(total).max() <= 1e-9 * 8.0


# ----------------------------------------------------------------------------- refusals
@pytest.mark.parametrize("change, key", [
    ({"loads": {"displacement": {"sym": [0.0, None]}}}, "boundaries.clamped / loads.displacement"),
    ({"boundaries": {"clamped": [], "contact": ["nope"]}}, "boundaries.contact"),
    ({"contact": {"g": "y - 0.1", "direction": [0.0, -1.0]}}, "contact.g"),
    ({"boundaries": {"clamped": [], "contact": ["body"]}}, "boundaries.contact"),
], ids=["rigid-motion", "unknown-group", "negative-gap", "wrong-dimension"])
def test_scene_refusals(tmp_path, change, key):
    raw = _hertz_raw(tmp_path)
    for section, value in change.items():
        raw[section] = value
    if "displacement" in change.get("loads", {}):
        raw["boundaries"] = {"clamped": [], "contact": ["arc"]}
    proc = run_cli(["run", _write(tmp_path, raw), "--out", tmp_path / "out", "--quiet"])
    assert proc.returncode == 2, proc.stdout + proc.stderr
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and key in err[0], proc.stderr
    if "body" in str(change):
        assert "'body' is a group of dimension 2; boundary groups have dimension 1" in err[0]
    assert not (tmp_path / "out" / "summary.json").exists()


@pytest.mark.mpi
def test_curved_case_two_ranks_equal_serial(tmp_path):
    path = _write(tmp_path, _hertz_raw(tmp_path, direction=None))
    out = {}
    for n in (1, 2):
        proc = run_cli(["run", path, "--out", tmp_path / f"np{n}", "--quiet"], nprocs=n)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        out[n] = json.loads((tmp_path / f"np{n}" / "summary.json").read_text())
        out[n]["rows"] = (tmp_path / f"np{n}" / "contact.csv").read_text().splitlines()
    for a, b in zip(out[1]["steps"], out[2]["steps"], strict=True):
        for key in NORMS:
            assert b[key] == pytest.approx(a[key], rel=1e-8, abs=1e-14), key
        assert np.allclose(b["contact_force"], a["contact_force"], rtol=1e-8)
    r1 = np.array([[float(v) for v in r.split(",")[:-1]] for r in out[1]["rows"][1:]])
    r2 = np.array([[float(v) for v in r.split(",")[:-1]] for r in out[2]["rows"][1:]])
    np.testing.assert_allclose(r2, r1, rtol=0, atol=1e-8 * np.abs(r1).max())
