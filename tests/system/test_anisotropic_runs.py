"""Whole runs with a general elasticity E(x) (H(E)): orthotropic, a Voigt matrix, E and nu
expressions taken per cell.  References: the isotropic runs (a Voigt matrix equal to the
isotropic law, a constant expression), the same scene rotated with its material axes, the
uniaxial compliances written out from the engineering constants, a layered body's closed
form; and the two step solvers against each other."""
import copy

import numpy as np
import pytest
import yaml
from mpi4py import MPI

from conftest import PAPER_CASE, make_case, paper_raw, run_case
from meshtools import rotation_2d, rotation_3d, write_rotated_box, write_rotated_square
from vpcontact.model.material import CellElasticity, MatrixElasticity
from vpcontact.post.quantities import contact_table

NORMS = ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y", "max_vm", "max_kappa")
ORTHO = {"E": [3000.0, 1000.0, 700.0], "nu": [0.25, 0.2, 0.35], "G": [500.0, 450.0, 300.0]}
SMALL = {"mesh": {"n": 8}, "time": {"N": 8}}


def _final(result):
    p = result.problem
    return p.u.x.array.copy(), p.sigma.x.array.copy(), p.state.kappa.x.array.copy()


def _equal(ref, other, tol, what=""):
    """The final u, sigma, kappa agree to tol relative to their largest entries."""
    for a, b in zip(_final(ref), _final(other)):
        scale = np.abs(a).max()
        assert scale > 0
        print(what, "max diff / max:", np.abs(a - b).max() / scale)
        assert np.abs(a - b).max() <= tol * scale


def _orthotropic_2d(angle_deg: float) -> dict:
    c, s = np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))
    return {"orthotropic": {"E": ORTHO["E"][:2], "nu": ORTHO["nu"][:1], "G": ORTHO["G"][:1],
                            "axes": [[float(c), float(s)]]}}


def _with_material(raw: dict, **material) -> dict:
    raw = copy.deepcopy(raw)
    vp = raw["material"].get("viscoplastic")
    raw["material"] = {**({"viscoplastic": vp} if vp else {}), **material}
    return raw


@pytest.mark.parametrize("scheme", ["explicit", "implicit"])
def test_constant_expression_equals_the_number(scheme):
    """E = '1000 + 0*x' (a CellElasticity: the DG0 field in the forms, the numpy Perzyna
    update with the batched projection, the implicit update's row selection) gives the
    number's run to 1e-12."""
    sec = {**copy.deepcopy(SMALL), "time": {"N": 4, "scheme": scheme},
           "solver": {"method": "condensed" if scheme == "explicit" else "snes_vi"}}
    ref = run_case(make_case(paper_raw(), **copy.deepcopy(sec)))
    raw = paper_raw()
    raw["material"]["E"] = "1000 + 0*x"
    cell = run_case(make_case(raw, **copy.deepcopy(sec)))
    assert isinstance(cell.problem.elasticity, CellElasticity)
    assert ref.status == cell.status == "completed"
    _equal(ref, cell, 1e-12, f"E(x) constant, {scheme}")


def test_isotropic_voigt_matrix_equals_the_isotropic_run():
    """The plane-stress law's Voigt matrix (engineering shears) gives the isotropic run to
    1e-12 (SNES VI)."""
    E, nu = 1000.0, 0.4
    D = E / (1 - nu ** 2) * np.array([[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]])
    sec = {**copy.deepcopy(SMALL), "time": {"N": 4}, "solver": {"method": "snes_vi"}}
    ref = run_case(make_case(paper_raw(), **copy.deepcopy(sec)))
    raw = _with_material(paper_raw(), elasticity={"voigt": D.tolist()})
    voigt = run_case(make_case(raw, **copy.deepcopy(sec)))
    assert isinstance(voigt.problem.elasticity, MatrixElasticity)
    _equal(ref, voigt, 1e-12, "voigt = isotropic")


@pytest.mark.parametrize("material", [
    {"elasticity": _orthotropic_2d(30.0)},
    {"E": 1000.0, "nu": "0.05 + 0.4*x*y", "plane": "strain"}],
    ids=["orthotropic", "nu(x)"])
def test_snes_vi_equals_condensed_2d(material):
    """The paper's scene with an orthotropic E (fibres at 30 degrees) or nu(x) per cell in
    plane strain (Perzyna's projection changes per cell): both step solvers agree to 1e-8."""
    raw = _with_material(paper_raw(), **material)
    runs = [run_case(make_case(raw, **{**copy.deepcopy(SMALL), "solver": {"method": m}}))
            for m in ("snes_vi", "condensed")]
    assert runs[0].status == runs[1].status == "completed"
    assert runs[0].history is not None and _final(runs[0])[2].max() > 0     # it flows
    for a, b in zip(runs[0].summary["steps"], runs[1].summary["steps"], strict=True):
        for key in NORMS:
            assert b[key] == pytest.approx(a[key], rel=1e-8, abs=1e-14), key
    _equal(runs[0], runs[1], 1e-8, f"snes_vi vs condensed {material}")


def test_orthotropic_body_rotated_with_its_axes(tmp_path):
    """The paper's scene with fibres at 10 degrees, and the same scene rotated by 30
    degrees (the same triangles from a .msh, tractions and fibres rotated, a1 at 40
    degrees): the norms at every step and the Gamma3 profile agree to 1e-8."""
    raw = yaml.safe_load(PAPER_CASE.read_text())
    raw["mesh"]["n"], raw["time"]["N"] = 8, 4
    raw = _with_material(raw, elasticity=_orthotropic_2d(10.0))
    ref = run_case(make_case(raw, solver={"method": "condensed"}))
    R = rotation_2d(30.0)
    msh = write_rotated_square(tmp_path / "square.msh", 8, 30.0, raw["mesh"]["diagonal"])
    rot = copy.deepcopy(raw)
    rot["mesh"] = {"file": str(msh), "dim": 2}
    rot["boundaries"] = {"clamped": ["left"], "contact": ["bottom"]}
    rot["loads"]["traction"] = {k: [float(c) for c in R @ np.array(v, float)]
                                for k, v in raw["loads"]["traction"].items()}
    rot["material"]["elasticity"] = _orthotropic_2d(40.0)
    turned = run_case(make_case(rot, solver={"method": "condensed"}))
    for a, b in zip(ref.summary["steps"], turned.summary["steps"], strict=True):
        for key in NORMS:
            assert b[key] == pytest.approx(a[key], rel=1e-8, abs=1e-14), key
    t_ref, t_rot = contact_table(ref.problem), contact_table(turned.problem)
    back = np.column_stack([t_rot["x"], t_rot["y"]]) @ R          # R^T x, row-wise
    x_ref = np.column_stack([t_ref["x"], t_ref["y"]])
    i, j = _order(back), _order(x_ref)
    np.testing.assert_allclose(back[i], x_ref[j], atol=1e-12)     # the same nodes
    for col in ("u_nu", "u_tau", "neg_sigma_nu", "neg_sigma_tau"):
        scale = np.abs(t_ref[col]).max()
        print(col, "rotated vs unrotated:", np.abs(t_rot[col][i] - t_ref[col][j]).max() / scale)
        np.testing.assert_allclose(t_rot[col][i], t_ref[col][j], rtol=0, atol=1e-8 * scale)


def _order(x):
    """The nodes sorted by their coordinates rounded to 1e-9 (gmsh's last bits vary)."""
    return np.lexsort(tuple(np.round(x[:, i], 9) for i in reversed(range(x.shape[1]))))


def test_orthotropic_box_rotated_with_its_axes_3d(tmp_path):
    """The shipped orthotropic box (n = 2, two steps) and the same box rotated by 30 degrees
    about z and 20 about x (the same tetrahedra from a .msh, tractions and both material
    axes rotated): the norms at every step and R^T u at the nodes agree to 1e-8."""
    from conftest import ROOT
    path = ROOT / "cases" / "orthotropic_box.yaml"
    raw = yaml.safe_load(path.read_text())
    raw["mesh"]["n"], raw["time"]["N"] = 2, 2
    ref = run_case(make_case(raw, solver={"method": "condensed"}))
    R = rotation_3d((30.0, 20.0))
    rot = copy.deepcopy(raw)
    rot["mesh"] = {"file": str(write_rotated_box(tmp_path / "box.msh", 2, (30.0, 20.0))),
                   "dim": 3}
    rot["boundaries"] = {"clamped": ["left"], "contact": ["bottom"]}
    rot["loads"]["traction"] = {k: [float(c) for c in R @ np.array(v, float)]
                                for k, v in raw["loads"]["traction"].items()}
    ortho = rot["material"]["elasticity"]["orthotropic"]
    ortho["axes"] = [[float(c) for c in R @ np.array(a, float)] for a in ortho["axes"]]
    turned = run_case(make_case(rot, solver={"method": "condensed"}))
    for a, b in zip(ref.summary["steps"], turned.summary["steps"], strict=True):
        for key in NORMS:
            assert b[key] == pytest.approx(a[key], rel=1e-8, abs=1e-14), key
    x_ref = ref.problem.disc.V.tabulate_dof_coordinates()
    back = turned.problem.disc.V.tabulate_dof_coordinates() @ R       # R^T x, row-wise
    i, j = _order(back), _order(x_ref)
    np.testing.assert_allclose(back[i], x_ref[j], atol=1e-12)
    u_ref = ref.problem.u.x.array.reshape(-1, 3)[j]
    u_back = (turned.problem.u.x.array.reshape(-1, 3) @ R)[i]
    print("3D rotated vs unrotated u:", np.abs(u_back - u_ref).max() / np.abs(u_ref).max())
    np.testing.assert_allclose(u_back, u_ref, rtol=0, atol=1e-8 * np.abs(u_ref).max())


def _uniaxial_raw(dim: int, material: dict, s: float) -> dict:
    """A unit square / cube on rollers (x = 0, y = 0, z = 0), pulled by s on x = 1: an
    elastic body in uniaxial stress sigma = s e_x (x) e_x."""
    sides = {"left": 0, "bottom": 1} if dim == 2 else {"left": 0, "front": 1, "bottom": 2}
    rollers = {side: [0.0 if k == axis else None for k in range(dim)]
               for side, axis in sides.items()}
    return {"mesh": {"dim": dim, "L1": 1.0, "L2": 1.0, **({"L3": 1.0} if dim == 3 else {}),
                     "n": 2},
            "material": material, "boundaries": {"clamped": [], "contact": []},
            "loads": {"displacement": rollers,
                      "traction": {"right": [s] + [0.0] * (dim - 1)}},
            "time": {"T": 1.0, "N": 1}}


def test_uniaxial_compliances_from_a_run():
    """3D, material axes a1 = y, a2 = z (a3 = x): pulled along x = a3 the run's strains in
    every cell are s/E3 along x, -nu31 s/E3 = -nu13 s/E1 along y = a1, -nu32 s/E3 = -nu23
    s/E2 along z = a2; 2D plane strain (a1 = x): the reduced compliances S11 - S13^2/S33
    and S12 - S13 S23/S33 along x and y."""
    from vpcontact.case import validate
    s = 5.0
    E1, E2, E3 = ORTHO["E"]
    n12, n13, n23 = ORTHO["nu"]
    ortho = {"orthotropic": {**ORTHO, "axes": [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]}}
    res = run_case(validate(_uniaxial_raw(3, {"elasticity": ortho}, s), "uniaxial-3d"))
    eps = res.problem.strain_voigt()          # (11, 22, 33, 23, 13, 12) per cell
    expected = [s / E3, -n13 * s / E1, -n23 * s / E2, 0.0, 0.0, 0.0]
    np.testing.assert_allclose(eps, np.broadcast_to(expected, eps.shape), rtol=0,
                               atol=1e-12 * s / E3)
    ortho = {"orthotropic": {**ORTHO, "axes": [[1.0, 0.0]]}}
    res = run_case(validate(_uniaxial_raw(2, {"elasticity": ortho, "plane": "strain"}, s),
                            "uniaxial-2d"))
    eps = res.problem.strain_voigt()
    S13, S23, S33 = -n13 / E1, -n23 / E2, 1 / E3
    expected = [(1 / E1 - S13 ** 2 / S33) * s, (-n12 / E1 - S13 * S23 / S33) * s, 0.0]
    np.testing.assert_allclose(eps, np.broadcast_to(expected, eps.shape), rtol=0,
                               atol=1e-12 * s / E1)


def test_layered_patch():
    """E(y) = 1000 below y = 1/2, 3000 above (per cell at its midpoint), nu = 0, rollers on
    x = 0 and y = 0, a traction s on y = 1: the stress is s e_y (x) e_y in every cell and
    u_y the closed form s y / 1000 below, s/2000 + s (y - 1/2)/3000 above, to round-off."""
    from vpcontact.case import validate
    s = 4.0
    raw = _uniaxial_raw(2, {"E": "1000 + 2000*min(max((y - 0.5)*1e6, 0), 1)", "nu": 0.0},
                        s)
    raw["mesh"]["n"] = 4
    raw["loads"]["traction"] = {"top": [0.0, s]}
    res = run_case(validate(raw, "layered"))
    p = res.problem
    assert isinstance(p.elasticity, CellElasticity) and len(p.elasticity.mats) == 2
    y = p.disc.V.tabulate_dof_coordinates()[:, 1]
    uy = np.where(y <= 0.5, s * y / 1000.0, s * 0.5 / 1000.0 + s * (y - 0.5) / 3000.0)
    u = p.u.x.array.reshape(-1, 2)
    np.testing.assert_allclose(u[:, 1], uy, rtol=0, atol=1e-12 * np.abs(uy).max())
    np.testing.assert_allclose(u[:, 0], 0.0, atol=1e-12 * np.abs(uy).max())
    sigma = p.sigma.x.array.reshape(-1, 2, 2)
    np.testing.assert_allclose(sigma, np.broadcast_to([[0.0, 0.0], [0.0, s]], sigma.shape),
                               rtol=0, atol=1e-10 * s)


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="serial reference")
def test_orthotropic_3d_snes_vi_equals_condensed():
    """A 3D orthotropic box (the shipped cases/orthotropic_box.yaml, n = 2, two steps):
    both step solvers agree to 1e-8."""
    from conftest import ROOT
    from vpcontact.case import load_case
    path = ROOT / "cases" / "orthotropic_box.yaml"
    runs = [run_case(load_case(path, ["mesh.n=2", "time.N=2", f"solver.method={m}"]))
            for m in ("snes_vi", "condensed")]
    assert isinstance(runs[0].problem.elasticity, MatrixElasticity)
    for a, b in zip(runs[0].summary["steps"], runs[1].summary["steps"], strict=True):
        for key in NORMS:
            assert b[key] == pytest.approx(a[key], rel=1e-8, abs=1e-14), key
    _equal(runs[0], runs[1], 1e-8, "3D orthotropic snes_vi vs condensed")


def test_per_cell_elasticity_under_mpirun(tmp_path):
    """nu(x) per cell (the rows of the ghost cells, m_E reduced over the ranks): mpirun -n 2
    gives the serial run's norms at every step and its diagnostics to 1e-10."""
    import json

    from conftest import run_cli
    from vpcontact.case import load_case
    over = ["mesh.n=8", "time.N=4", "solver.method=condensed", "material.nu=0.05 + 0.4*x*y"]
    serial = run_case(load_case(PAPER_CASE, list(over)))
    out = tmp_path / "mpi"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--quiet",
                    *[a for o in over for a in ("--set", o)]], nprocs=2)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    for a, b in zip(serial.summary["steps"], summary["steps"], strict=True):
        for key in NORMS:
            assert b[key] == pytest.approx(a[key], rel=1e-10, abs=1e-14), key
    for key in ("m_E", "relaxation_rate"):
        assert summary["diagnostics"][key] == pytest.approx(
            serial.summary["diagnostics"][key], rel=1e-14), key
