"""materials: one material per physical group of cells of a mesh.file.

- Two materials in series: a bar (0, L1 + L2) x (0, h) of two cell groups side by side along
  the load, plane stress, pulled by a traction T on its right end, held by rollers on its
  left end and its bottom.  With nu1 / E1 = nu2 / E2 the uniform uniaxial stress sigma = T
  e_x (x) e_x is compatible, so the exact solution is u_x = T x / E1 (x <= L1), T L1 / E1 +
  T (x - L1) / E2 (beyond: the springs in series), u_y = -nu_i T y / E_i: piecewise linear
  in the cells, so P1 elements on a mesh that follows the interface reproduce it.
- A Perzyna group in series with an elastic one (nu = 0, rollers on the top and bottom): group
  b is one material point under sigma_xx = T with eps_yy = 0; the explicit scheme written in
  the test (its own projection by the secular equation) gives u_end, H and kappa.
- Both groups given the same (viscoplastic) material: the run equals the one-material run.
- The refusals: both keys, neither, materials without mesh.file, two plane models, a law's
  key inside materials (named with its group), a group the mesh does not have, cells in no
  group, a group given by its name and its tag.
- The shipped case cases/bimaterial_punch.yaml: serial SNES VI = the condensed solver under
  mpirun -n 2 (one mpirun run), and its contact force relaxes.
"""
import json

import numpy as np
import pytest
from mpi4py import MPI

from conftest import ROOT, run_cli

L1, L2, H, T = 0.6, 0.4, 0.2, 3.0
E1, NU1, E2, NU2 = 1000.0, 0.2, 2000.0, 0.4          # nu1 / E1 = nu2 / E2
BAR = f"""// a bar of two cell groups along x: "a" (0, L1) x (0, H) and "b" (L1, L1 + L2) x (0, H)
s = 0.05;
Point(1) = {{0, 0, 0, s}}; Point(2) = {{{L1}, 0, 0, s}}; Point(3) = {{{L1 + L2}, 0, 0, s}};
Point(4) = {{{L1 + L2}, {H}, 0, s}}; Point(5) = {{{L1}, {H}, 0, s}}; Point(6) = {{0, {H}, 0, s}};
Line(1) = {{1, 2}}; Line(2) = {{2, 3}}; Line(3) = {{3, 4}}; Line(4) = {{4, 5}};
Line(5) = {{5, 6}}; Line(6) = {{6, 1}}; Line(7) = {{2, 5}};
Curve Loop(1) = {{1, 7, 5, 6}}; Plane Surface(1) = {{1}};
Curve Loop(2) = {{2, 3, 4, -7}}; Plane Surface(2) = {{2}};
Physical Curve("left", 1) = {{6}}; Physical Curve("right", 2) = {{3}};
Physical Curve("bottom", 3) = {{1, 2}}; Physical Curve("top", 4) = {{4, 5}};
Physical Surface("a", 11) = {{1}}; Physical Surface("b", 12) = {{2}};
"""


@pytest.fixture(scope="module")
def bar_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("bar") / "bar.geo"
    path.write_text(BAR)
    return path


def bar_raw(path, materials=None, **extra):
    raw = {"mesh": {"file": str(path), "dim": 2},
           "materials": materials or {"a": {"E": E1, "nu": NU1}, "b": {"E": E2, "nu": NU2}},
           "boundaries": {"clamped": []},
           "loads": {"traction": {"right": [T, 0.0]},
                     "displacement": {"left": [0.0, None], "bottom": [None, 0.0]}},
           "time": {"T": 1.0, "N": 1}}
    raw.update(extra)
    return raw


def validate(raw):
    from vpcontact.case import validate as _validate
    return _validate(raw, "test-case")


def test_two_materials_in_series(bar_file):
    from vpcontact.simulation import run
    result = run(validate(bar_raw(bar_file)), MPI.COMM_WORLD)
    assert result.status == "completed"
    p = result.problem
    x = p.disc.V.tabulate_dof_coordinates()[:, :2]
    u = p.u.x.array.reshape(-1, 2)
    exact_x = np.where(x[:, 0] <= L1, T * x[:, 0] / E1, T * L1 / E1 + T * (x[:, 0] - L1) / E2)
    exact_y = -NU1 / E1 * T * x[:, 1]
    u_end = T * L1 / E1 + T * L2 / E2                  # springs in series, per unit area
    assert np.abs(u[:, 0] - exact_x).max() <= 1e-9 * u_end
    assert np.abs(u[:, 1] - exact_y).max() <= 1e-9 * u_end
    right = np.isclose(x[:, 0], L1 + L2)
    assert right.any() and np.allclose(u[right, 0], u_end, rtol=1e-9, atol=0)
    sigma = p.sigma.x.array.reshape(-1, 2, 2)          # uniform uniaxial stress T
    assert np.abs(sigma - np.array([[T, 0.0], [0.0, 0.0]])).max() <= 1e-8 * T


def _projection(s, kappa):
    """P_K(kappa) of a stress (s_xx, s_yy) (no shear) for nu = 0, where the energy inner
    product is E times the Euclidean one: the closest point of the ellipse s^T M s <=
    kappa^2, M = [[1, -1/2], [-1/2, 1]] (eigenvalues 1/2 along (1, 1), 3/2 along (1, -1)),
    by its secular equation."""
    from scipy.optimize import brentq
    M = np.array([[1.0, -0.5], [-0.5, 1.0]])
    if s @ M @ s <= kappa ** 2:
        return s
    lam, V = np.array([0.5, 1.5]), np.array([[1.0, 1.0], [1.0, -1.0]]) / np.sqrt(2.0)
    z = V.T @ s
    mu = brentq(lambda mu: np.sum(lam * z ** 2 / (1 + mu * lam) ** 2) - kappa ** 2, 0.0, 1e12,
                xtol=1e-300, rtol=1e-15)
    return V @ (z / (1 + mu * lam))


@pytest.mark.parametrize("Eb_given", [1000.0, "1000 + 0 * x"])     # E per cell: its rows
def test_viscoplastic_group_in_series(bar_file, Eb_given):
    """Group b Perzyna, group a elastic, nu = 0, rollers u_y = 0 on the top and bottom: u_y =
    0, sigma_xy = 0 and sigma_xx = T hold exactly, so group b is one material point with
    eps_yy = 0 (sigma_yy = H_yy) under sigma_xx = T: the explicit scheme (3.2)-(3.3) written
    here gives H_n, kappa_n and eps_xx = (T - H_xx) / E_b, u_end = T L1 / E_a + L2 eps_xx."""
    from vpcontact.simulation import run
    Ea, Eb, lam1, lam2, kappa0, N, k = 3000.0, 1000.0, 100.0, 50.0, 1.0, 10, 0.05
    law = {"lambda1": lam1, "lambda2": lam2, "kappa0": kappa0}
    raw = bar_raw(bar_file, {"a": {"E": Ea, "nu": 0.0},
                             "b": {"E": Eb_given, "nu": 0.0, "viscoplastic": law}},
                  time={"T": N * k, "N": N})
    raw["loads"]["displacement"] = {"left": [0.0, None], "bottom": [None, 0.0],
                                    "top": [None, 0.0]}
    result = run(validate(raw), MPI.COMM_WORLD)
    assert result.status == "completed"
    sigma, H, kappa = np.zeros(2), np.zeros(2), kappa0      # sigma_0 = 0 (u0 = 0, H_0 = 0)
    for _ in range(N):
        excess = sigma - _projection(sigma, kappa)
        H = H - k * Eb / (2.0 * lam1) * excess
        kappa = kappa + k * 2.0 / (3.0 * lam2) * np.sqrt(excess @ np.array(
            [[1.0, -0.5], [-0.5, 1.0]]) @ excess)
        sigma = np.array([T, H[1]])
    assert kappa > kappa0 + 1e-3 and H[1] > 1e-3 * T           # it flowed
    u_end = T * L1 / Ea + L2 * (T - H[0]) / Eb
    p = result.problem
    x = p.disc.V.tabulate_dof_coordinates()[:, :2]
    u = p.u.x.array.reshape(-1, 2)
    right = np.isclose(x[:, 0], L1 + L2)
    assert np.allclose(u[right, 0], u_end, rtol=1e-10, atol=0) and np.abs(u[:, 1]).max() \
        <= 1e-10 * u_end
    groups = {g.ref: g for g in p.materials.groups}
    Hc = p.H.x.array.reshape(-1, 2, 2)
    kc = p.state.kappa_cells[:, 0]
    b, a = groups["b"].rows, groups["a"].rows
    assert np.allclose(Hc[b], np.array([[H[0], 0.0], [0.0, H[1]]]), rtol=0, atol=1e-10 * T)
    assert np.allclose(kc[b], kappa, rtol=1e-12) and (kc[a] == 0.0).all()
    assert np.abs(Hc[a]).max() <= 1e-12 * T                    # the elastic group: H_0 = 0


def punch_raw(material, both: bool, N: int = 4) -> dict:
    from vpcontact.case import load_raw
    raw = load_raw(ROOT / "cases" / "bimaterial_punch.yaml")
    raw.pop("materials")
    if both:
        raw["materials"] = {"foot": dict(material), "cap": dict(material)}
    else:
        raw["material"] = dict(material)
    raw["mesh"]["file"] = str(ROOT / "cases" / "bimaterial_punch.geo")
    raw["mesh"]["size"] = 2.0
    raw["time"].update({"T": 0.1 * N, "N": N})          # k = 0.1: k r_max = 0.96 < 2
    return raw


KEYS = ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y", "max_vm", "max_kappa")


@pytest.mark.parametrize("method, scheme", [("condensed", "explicit"), ("snes_vi", "explicit"),
                                            ("snes_vi", "implicit")])
def test_one_material_for_both_groups_equals_material(method, scheme):
    from vpcontact.simulation import run
    soft = {"E": 1000.0, "nu": 0.3, "plane": "strain",
            "viscoplastic": {"lambda1": 100.0, "lambda2": 100.0, "kappa0": 1.0}}
    runs = []
    for both in (False, True):
        raw = punch_raw(soft, both)
        raw["solver"] = {"method": method}
        raw["time"]["scheme"] = scheme
        result = run(validate(raw), MPI.COMM_WORLD)
        assert result.status == "completed"
        runs.append(result)
    one, two = (r.summary["steps"] for r in runs)
    assert len(one) == len(two) == 4
    assert max(s["max_kappa"] for s in one) > 1.0 + 1e-3         # the law flowed
    for a, b in zip(one, two):
        for key in KEYS:
            assert b[key] == pytest.approx(a[key], rel=1e-12, abs=0), key
        assert b["contact_force"][1] == pytest.approx(a["contact_force"][1], rel=1e-12)
    ua, ub = (r.problem.u.x.array for r in runs)
    assert np.abs(ub - ua).max() <= 1e-12 * np.abs(ua).max()


def _refusal(raw) -> str:
    from vpcontact.case import CaseError
    with pytest.raises(CaseError) as err:
        validate(raw)
    return str(err.value)


def test_case_refusals(bar_file):
    raw = bar_raw(bar_file, material={"E": 1.0, "nu": 0.3})
    assert "materials: give either material" in _refusal(raw)
    raw = bar_raw(bar_file)
    raw.pop("materials")
    assert "'material' is a required property" in _refusal(raw)
    builtin = bar_raw(bar_file)
    builtin["mesh"] = {"n": 4}
    builtin["loads"] = {}
    assert "materials: only with mesh.file" in _refusal(builtin)
    planes = bar_raw(bar_file, {"a": {"E": 1.0, "nu": 0.3, "plane": "strain"},
                                "b": {"E": 1.0, "nu": 0.3}})
    assert "one 2D model" in _refusal(planes)
    law = bar_raw(bar_file, {"a": {"E": 1.0, "nu": 0.3},
                             "b": {"E": 1.0, "nu": 0.3, "viscoplastic": {
                                 "lambda1": 1.0, "lambda2": 1.0, "law": "power"}}})
    assert "materials.b.viscoplastic.s_ref: required with law power" in _refusal(law)


@pytest.fixture(scope="module")
def bar_body(bar_file):
    from dolfinx import fem

    from vpcontact.meshes.gmshfile import load_mesh_file
    body = load_mesh_file(MPI.COMM_WORLD, bar_file, 2)
    return body, fem.TensorFunctionSpace(body.mesh, ("DG", 0))


def _groups_refusal(bar_file, bar_body, materials) -> str:
    from vpcontact.case import CaseError
    from vpcontact.model.materials import material_groups
    body, Q = bar_body
    with pytest.raises(CaseError) as err:
        material_groups(validate(bar_raw(bar_file, materials)), body, Q)
    return str(err.value)


def test_groups_on_the_mesh(bar_file, bar_body):
    from vpcontact.model.materials import material_groups
    body, Q = bar_body
    ct = body.cell_tags
    n_b = MPI.COMM_WORLD.allreduce(int(np.count_nonzero(
        ct.values[ct.indices < body.mesh.topology.index_map(2).size_local] == 12)))
    assert n_b > 0
    msg = _groups_refusal(bar_file, bar_body, {"a": {"E": 1.0, "nu": 0.3}})
    assert f"{n_b} cell(s) of the body are in no group" in msg and "without a material: 12" \
        in msg
    msg = _groups_refusal(bar_file, bar_body, {"a": {"E": 1.0, "nu": 0.3},
                                               "c": {"E": 1.0, "nu": 0.3}})
    assert "materials.c: no physical group of cells 'c'" in msg and "names: a, b" in msg
    msg = _groups_refusal(bar_file, bar_body, {"a": {"E": 1.0, "nu": 0.3},
                                               "left": {"E": 1.0, "nu": 0.3}})
    assert "'left' is a group of dimension 1" in msg
    msg = _groups_refusal(bar_file, bar_body, {"a": {"E": 1.0, "nu": 0.3},
                                               11: {"E": 1.0, "nu": 0.3}})
    assert "the same group (physical tag 11)" in msg
    groups = material_groups(validate(bar_raw(bar_file, {12: {"E": 2.0, "nu": 0.3},
                                                         "a": {"E": 1.0, "nu": 0.3}})), body, Q)
    rows = np.concatenate([g.rows for g in groups])        # every local cell once
    assert np.array_equal(np.sort(rows), np.arange(len(Q.dofmap.list.array)))
    tags = np.empty(len(rows), dtype=int)
    tags[Q.dofmap.list.array[ct.indices]] = ct.values
    assert all((tags[g.rows] == g.tag).all() for g in groups)
    from vpcontact.model.materials import BodyMaterials
    owned = body.mesh.topology.index_map(2).size_local
    n_a = MPI.COMM_WORLD.allreduce(int(np.count_nonzero(ct.values[ct.indices < owned] == 11)))
    assert BodyMaterials(groups, None).cell_counts(owned, MPI.COMM_WORLD) == \
        [(12, 12, n_b), ("a", 11, n_a)]                      # check's line


def test_bimaterial_punch_serial_equals_two_ranks(tmp_path):
    """The shipped case: SNES VI serially, the condensed solver on two ranks."""
    from vpcontact.case import load_case
    from vpcontact.simulation import run
    case = ROOT / "cases" / "bimaterial_punch.yaml"
    short = ["time.T=0.6", "time.N=6"]      # k = 0.1 as the case's; 0.2 of loading, 0.4 held
    serial = run(load_case(case, short + ["solver.method=snes_vi"]), MPI.COMM_WORLD).summary
    out = tmp_path / "mpi"
    proc = run_cli(["run", case, "--out", out, "--quiet", "--set", short[0], "--set",
                    short[1]], nprocs=2)
    assert proc.returncode == 0, proc.stderr
    parallel = json.loads((out / "summary.json").read_text())
    assert parallel["mpi_ranks"] == 2 and parallel["status"] == "completed"
    assert (serial["solver"]["used"], parallel["solver"]["used"]) == ("snes_vi", "condensed")
    assert len(serial["steps"]) == len(parallel["steps"]) == 6
    for a, b in zip(serial["steps"], parallel["steps"]):
        for key in KEYS:
            assert b[key] == pytest.approx(a[key], rel=1e-8, abs=1e-14), key
        assert b["contact_force"][1] == pytest.approx(a["contact_force"][1], rel=1e-8)
    force = [s["contact_force"][1] for s in serial["steps"]]
    assert force[1] > 0 and all(b < a for a, b in zip(force[1:], force[2:]))   # relaxation
