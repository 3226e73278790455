"""solution.xdmf as one dataset: VTK (pyvista's XDMF reader) reads one UnstructuredGrid per
time carrying every field, for a 2D and a 3D run, serial and under mpirun -n 2; and the
one-dataset rewrite of dolfinx's XML (app/io/xdmf.py)."""
import csv
import json

import numpy as np
import pytest
import pyvista as pv

from app.io.xdmf import XdmfLayoutError, one_dataset
from conftest import PAPER_CASE, ROOT, run_cli

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


@pytest.mark.parametrize("nprocs", [1, 2])
@pytest.mark.parametrize("dim", ["2d", "3d"])
def test_solution_xdmf_is_one_dataset_with_every_field(tmp_path, dim, nprocs):
    out, s = _run(tmp_path, dim, nprocs)
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
    axes = "xyz"[:d]
    x = np.array([[float(r[a]) for a in axes] for r in rows])
    u = np.array([[float(r[f"u_{a}"]) for a in axes] for r in rows])
    pts = np.asarray(grid.points)[:, :d]
    nearest = np.argmin(np.linalg.norm(pts[None, :, :] - x[:, None, :], axis=2), axis=1)
    assert np.allclose(pts[nearest], x, atol=1e-12)
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
    def item(dims, path):
        return f'<DataItem Dimensions="{dims}" Format="HDF">w.h5:{path}</DataItem>'

    def collection(name, center, dims):
        grids = "".join(
            f'<Grid Name="{name}" GridType="Uniform"><xi:include xpointer="x" />'
            f'<Time Value="{t}" /><Attribute Name="{name}" Center="{center}">'
            f'{item(dims, f"/Function/{name}/{key}")}</Attribute></Grid>'
            for t, key in (("0", "0"), ("0.5", "0_5")))
        return f'<Grid Name="{name}" GridType="Collection" CollectionType="Temporal">{grids}</Grid>'

    return ('<?xml version="1.0"?>\n<Xdmf Version="3.0" xmlns:xi="http://www.w3.org/2001/XInclude">'
            '<Domain><Grid Name="mesh" GridType="Uniform">'
            '<Topology TopologyType="Triangle" NumberOfElements="2" NodesPerElement="3">'
            f'{item("2 3", "/Mesh/mesh/topology")}</Topology>'
            f'<Geometry GeometryType="XY">{item("4 2", "/Mesh/mesh/geometry")}</Geometry></Grid>'
            f'{collection("u", "Node", "4 3")}{collection("k", "Cell", "2 1")}</Domain></Xdmf>')


def test_one_dataset_groups_the_functions_by_time_and_renames_the_h5_file():
    import xml.etree.ElementTree as ET
    root = ET.fromstring(one_dataset(_dolfinx_xml(), "solution", "w.h5", "s.h5"))
    top = root.find("Domain").findall("Grid")
    assert [(g.get("Name"), g.get("CollectionType")) for g in top] == [("solution", "Temporal")]
    grids = top[0].findall("Grid")
    assert [g.find("Time").get("Value") for g in grids] == ["0", "0.5"]
    for g, t in zip(grids, ["0", "0_5"]):
        assert g.find("Topology") is not None and g.find("Geometry") is not None
        items = [a.find("DataItem").text for a in g.findall("Attribute")]
        assert items == [f"s.h5:/Function/u/{t}", f"s.h5:/Function/k/{t}"]
    assert root.find(".//Geometry/DataItem").text == "s.h5:/Mesh/mesh/geometry"
    assert "include" not in ET.tostring(root, encoding="unicode")
    assert {i.get("Precision") for i in root.iter("DataItem")} == {"8"}   # float64, int64


def test_one_dataset_refuses_another_layout():
    with pytest.raises(XdmfLayoutError, match="mesh Grid"):
        one_dataset('<Xdmf Version="3.0"><Domain></Domain></Xdmf>')
