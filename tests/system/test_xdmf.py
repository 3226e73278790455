"""solution.xdmf as one dataset: VTK (pyvista's XDMF reader) reads one UnstructuredGrid per
time carrying every field, for a 2D and a 3D run, serial and under mpirun -n 2; and the
one-dataset rewrite of dolfinx's XML (app/io/xdmf.py)."""
import csv
import json

import numpy as np
import pytest
import pyvista as pv

from conftest import PAPER_CASE, ROOT, run_cli
from vpcontact.io.xdmf import Field, TemporalXdmf, XdmfLayoutError, dolfinx_layout

RUNS = {"2d": (PAPER_CASE, ["mesh.n=8"]), "3d": (ROOT / "cases" / "box3d.yaml", ["mesh.n=4"])}


def _run(tmp_path, dim, nprocs, extra=()):
    case, sets = RUNS[dim]
    out = tmp_path / "o"
    args = ["run", case, "--out", out, "--set", "time.N=2", *extra]
    for s in sets:
        args += ["--set", s]
    proc = run_cli(args, nprocs=nprocs)
    assert proc.returncode == 0, proc.stderr
    return out, json.loads((out / "summary.json").read_text())


def _contact_rows(out):
    with open(out / "contact.csv") as fh:
        return list(csv.DictReader(fh))


def _at_contact_nodes(points, rows, d):
    """The indices of contact.csv's nodes among ``points`` (by coordinates; checked)."""
    x = np.array([[float(r[a]) for a in "xyz"[:d]] for r in rows])
    pts = np.asarray(points)[:, :d]
    nearest = np.argmin(np.linalg.norm(pts[None, :, :] - x[:, None, :], axis=2), axis=1)
    assert np.allclose(pts[nearest], x, atol=1e-12)
    return nearest


@pytest.fixture(scope="module", params=[("2d", 1), ("2d", 2), ("3d", 1), ("3d", 2)],
                ids=["2d-serial", "2d-np2", "3d-serial", "3d-np2"])
def run_out(request, tmp_path_factory):
    """(dimension, out, summary) of a two-step run, serial and under mpirun -n 2."""
    dim, nprocs = request.param
    return (dim, *_run(tmp_path_factory.mktemp(f"{dim}-{nprocs}"), dim, nprocs))


def test_solution_xdmf_is_one_dataset_with_every_field(run_out):
    dim, out, s = run_out
    reader = pv.get_reader(str(out / "solution.xdmf"))
    assert reader.time_values == pytest.approx([0.0, 0.5, 1.0])
    nv, nc = s["mesh"]["vertices"], s["mesh"]["cells"]
    for t in reader.time_values:
        reader.set_active_time_value(t)
        grid = reader.read()
        assert isinstance(grid, pv.UnstructuredGrid), type(grid)
        assert (grid.n_points, grid.n_cells) == (nv, nc)
        assert grid.point_data["u"].shape == (nv, 3)
        assert grid.cell_data["sigma"].shape == (nc, 9)
        assert grid.cell_data["sigma_vm"].shape == (nc,)
        assert grid.cell_data["kappa"].shape == (nc,)
        assert np.all(np.isfinite(grid.cell_data["sigma_vm"]))
    # the last Grid is the final state: u at the Gamma3 nodes equals contact.csv's
    d = 2 if dim == "2d" else 3
    rows = _contact_rows(out)
    u = np.array([[float(r[f"u_{a}"]) for a in "xyz"[:d]] for r in rows])
    nearest = _at_contact_nodes(grid.points, rows, d)
    assert np.abs(grid.point_data["u"][nearest, :d] - u).max() <= 1e-12 * np.abs(u).max()
    assert np.abs(u).max() > 0


def test_pyvista_read_gives_one_grid(tmp_path):
    """pyvista.read (what a user types first) gives one UnstructuredGrid, not a MultiBlock."""
    out, _ = _run(tmp_path, "2d", 1)
    grid = pv.read(str(out / "solution.xdmf"))
    assert isinstance(grid, pv.UnstructuredGrid)
    assert {"u"} <= set(grid.point_data) and {"sigma_vm", "kappa"} <= set(grid.cell_data)


def _dolfinx_xml() -> str:
    """What dolfinx 0.5.2 writes: the mesh Grid, then a temporal collection per function."""
    def item(dims, path, extra=""):      # extra: the topology's NumberType
        return f'<DataItem Dimensions="{dims}"{extra} Format="HDF">w.h5:{path}</DataItem>'

    def collection(name, kind, center, dims):
        grids = "".join(
            f'<Grid Name="{name}" GridType="Uniform"><xi:include xpointer="x" />'
            f'<Time Value="{t}" /><Attribute Name="{name}" AttributeType="{kind}" '
            f'Center="{center}">'
            f'{item(dims, f"/Function/{name}/{key}")}</Attribute></Grid>'
            for t, key in (("0", "0"), ("0.5", "0_5")))
        return f'<Grid Name="{name}" GridType="Collection" CollectionType="Temporal">{grids}</Grid>'

    return ('<?xml version="1.0"?>\n<Xdmf Version="3.0" xmlns:xi="http://www.w3.org/2001/XInclude">'
            '<Domain><Grid Name="mesh" GridType="Uniform">'
            '<Topology TopologyType="Triangle" NumberOfElements="2" NodesPerElement="3">'
            + item("2 3", "/Mesh/mesh/topology", ' NumberType="Int"') + "</Topology>"
            f'<Geometry GeometryType="XY">{item("4 2", "/Mesh/mesh/geometry")}</Geometry></Grid>'
            f'{collection("u", "Vector", "Node", "4 3")}{collection("k", "Scalar", "Cell", "2 1")}'
            "</Domain></Xdmf>")


def test_dolfinx_layout_and_one_collection_over_the_mesh(tmp_path):
    """The mesh items (renamed HDF5 file, Precision 8) and the fields from dolfinx's XML;
    TemporalXdmf: one temporal collection, every field in the Grid of its time."""
    import xml.etree.ElementTree as ET
    topology, geometry, fields = dolfinx_layout(_dolfinx_xml(), "s.h5")
    assert fields == [Field("u", "Vector", "Node"), Field("k", "Scalar", "Cell")]
    xml = TemporalXdmf(tmp_path / "s.xdmf", "solution", topology, geometry)
    for t, key in ((0.0, "0"), (0.5, "0_5")):
        xml.add(t, [f.attribute("s.h5", f"/Function/{f.name}/{key}", (4, 3)) for f in fields])
    root = ET.parse(tmp_path / "s.xdmf").getroot()
    top = root.find("Domain").findall("Grid")
    assert [(g.get("Name"), g.get("CollectionType")) for g in top] == [("solution", "Temporal")]
    grids = top[0].findall("Grid")
    assert [float(g.find("Time").get("Value")) for g in grids] == [0.0, 0.5]
    for g, key in zip(grids, ["0", "0_5"]):
        assert g.find("Topology").get("TopologyType") == "Triangle"
        items = [a.find("DataItem").text for a in g.findall("Attribute")]
        assert items == [f"s.h5:/Function/u/{key}", f"s.h5:/Function/k/{key}"]
        assert g.find("Geometry/DataItem").text == "s.h5:/Mesh/mesh/geometry"
    assert {i.get("Precision") for i in root.iter("DataItem")} == {"8"}   # float64, int64
    assert root.find(".//Topology/DataItem").get("NumberType") == "Int"


def test_dolfinx_layout_refuses_another_layout():
    with pytest.raises(XdmfLayoutError, match="mesh Grid"):
        dolfinx_layout('<Xdmf Version="3.0"><Domain></Domain></Xdmf>', "s.h5")


FACETS = {"2d": 8, "3d": 2 * 4 * 4}          # Gamma3: the bottom edge / face at n = 8 / 4


def test_contact_xdmf_has_the_gamma3_facets_and_the_table_at_every_time(run_out):
    dim, out, _ = run_out
    reader = pv.get_reader(str(out / "contact.xdmf"))
    assert reader.time_values == pytest.approx([0.0, 0.5, 1.0])
    for t in reader.time_values:
        reader.set_active_time_value(t)
        grid = reader.read()
        assert isinstance(grid, pv.UnstructuredGrid)
        assert grid.n_cells == FACETS[dim]
        assert {"u", "u_nu", "neg_sigma_nu", "state"} <= set(grid.point_data)
        assert grid.point_data["u"].shape == (grid.n_points, 3)
    # the last time against contact.csv, by coordinates; fully clamped nodes: NaN, prescribed
    rows = _contact_rows(out)
    nearest = _at_contact_nodes(grid.points, rows, 2 if dim == "2d" else 3)
    for col in ("u_nu", "neg_sigma_nu"):
        csv_values = np.array([float(r[col]) for r in rows])
        assert np.array_equal(grid.point_data[col][nearest], csv_values), col
    codes = {"separated": 0, "compliance": 1, "bound": 2, "prescribed": 3}
    assert list(grid.point_data["state"][nearest]) == [codes[r["state"]] for r in rows]
    others = np.setdiff1d(np.arange(grid.n_points), nearest)
    assert np.all(np.isnan(grid.point_data["u_nu"][others]))
    assert np.all(grid.point_data["state"][others] == 3)


@pytest.mark.parametrize("nprocs", [1, 2])
def test_history_csv_has_a_row_per_step(tmp_path, nprocs):
    out, s = _run(tmp_path, "2d", nprocs, ["--set", "time.N=4"])
    with open(out / "history.csv") as fh:
        rows = list(csv.DictReader(fh))
    steps = s["steps"]
    assert [int(r["n"]) for r in rows] == [st["n"] for st in steps] == [1, 2, 3, 4]
    for r, st in zip(rows, steps):
        assert float(r["t"]) == st["t"] and float(r["norm_u_V"]) == st["norm_u_V"]
        assert int(r["newton_iterations"]) == st["newton_iterations"]
        assert [float(r["contact_force_x"]), float(r["contact_force_y"])] == st["contact_force"]
        for group, force in st["reactions"].items():
            assert [float(r[f"reaction_{group}_x"]), float(r[f"reaction_{group}_y"])] == force
    states = [r["state"] for r in _contact_rows(out)]     # the final counts, as contact.csv
    last = rows[-1]
    for state in ("bound", "compliance", "separated", "prescribed"):
        assert int(last[f"nodes_{state}"]) == states.count(state), state
    assert s["steps"][-1]["contact_states"]["nodes"] == len(states)


def test_user_guide_pyvista_snippet_runs_verbatim(tmp_path):
    """The user guide's Python example (docs/user-guide.md), on a run's output: it reads the
    last time, warps by u and writes vm.png coloured by sigma_vm (in a process of its own,
    as the guide says)."""
    import subprocess
    import sys
    text = (ROOT / "docs" / "user-guide.md").read_text()
    block = text.split("```python\nimport pyvista as pv", 1)[1].split("```", 1)[0]
    out, _ = _run(tmp_path, "2d", 1)
    code = "import pyvista as pv" + block.replace("results/wang_cheng_2021", str(out))
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "vm.png").stat().st_size > 10_000


def test_node_index_by_coordinates():
    """The table rows' nodes: a binary search where both are sorted by their rounded
    coordinates (as facet_mesh and gather_contact_table sort them), the nearest node
    otherwise; a row off every node is refused."""
    from vpcontact.io.contact_xdmf import node_index
    rng = np.random.default_rng(3)
    points = np.column_stack([np.sort(rng.random(20)), rng.random(20), np.zeros(20)])
    assert np.array_equal(node_index(points, points[:, :2]), np.arange(20))
    some = np.sort(rng.permutation(20)[:12])
    assert np.array_equal(node_index(points, points[some, :2]), some)
    rows = rng.permutation(20)[:12]                  # not sorted: the nearest nodes
    assert np.array_equal(node_index(points, points[rows, :2] * (1 + 1e-12)), rows)
    with pytest.raises(ValueError, match="not a vertex"):
        node_index(points, points[rows, :2] + 1e-3)
