"""The cost of the outputs per output step does not grow with the run:
solution.xdmf and contact.xdmf were rewritten whole at every step (and dolfinx's work XML
parsed and saved whole four times a step), 11 -> 73 ms per step from 300 to 3000 steps.

Nothing here is timed: the bytes the process reads and writes per step (``rchar`` and
``wchar`` of /proc/self/io, which count every read and write system call, dolfinx's C++
and HDF5 included) must be the same at step 60 as at step 10."""
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

pytestmark = pytest.mark.skipif(not Path("/proc/self/io").exists(),
                                reason="needs Linux's /proc/self/io")

STEPS = 70


def _io() -> np.ndarray:
    """(bytes read, bytes written) by this process so far."""
    fields = dict(line.split(": ") for line in Path("/proc/self/io").read_text().splitlines())
    return np.array([int(fields["rchar"]), int(fields["wchar"])])


def _per_step(write) -> np.ndarray:
    """The (read, written) bytes of each of STEPS calls write(n)."""
    out = []
    for n in range(STEPS):
        before = _io()
        write(n)
        out.append(_io() - before)
    return np.array(out)


HEAP_BLOCK = 2048    # bytes: HDF5's link-name heap block of a group with < 100 links


def _assert_constant(per_step: np.ndarray, groups: int) -> None:
    """The median bytes of steps 50-70 are those of steps 10-30, up to the one O(1) term
    that grows early in a run: each HDF5 group that gets a link per step (a field's
    datasets, contact.h5's steps) writes and reads the fractal-heap block holding the new
    name, and these blocks double from 512 B to at most 64 KiB (2 KiB up to step 100)."""
    early = np.median(per_step[10:30], axis=0)
    late = np.median(per_step[50:70], axis=0)
    for what, e, l in zip(("read", "written"), early, late):
        assert l <= e + groups * HEAP_BLOCK, f"bytes {what} per step grow: {e:.0f} -> {l:.0f}"


def test_solution_xdmf_costs_the_same_at_every_step(tmp_path):
    from dolfinx import fem
    from dolfinx import mesh as dmesh

    from vpcontact.io.output import FieldWriter
    mesh = dmesh.create_unit_square(MPI.COMM_WORLD, 4, 4)
    u = fem.Function(fem.VectorFunctionSpace(mesh, ("CG", 1)), name="u")
    sigma = fem.Function(fem.TensorFunctionSpace(mesh, ("DG", 0)), name="sigma")
    kappa = fem.Function(fem.FunctionSpace(mesh, ("DG", 0)), name="kappa")
    writer = FieldWriter(MPI.COMM_WORLD, tmp_path / "solution.xdmf", mesh, [u, sigma, kappa])

    def write(n):
        u.x.array[:] = n
        writer.write(0.01 * n)
    per_step = _per_step(write)
    writer.close()
    _assert_constant(per_step, 3)             # and the file is one complete dataset
    import pyvista as pv
    reader = pv.get_reader(str(tmp_path / "solution.xdmf"))
    assert reader.time_values == pytest.approx(0.01 * np.arange(STEPS))
    reader.set_active_time_value(reader.time_values[-1])
    u = reader.read().point_data["u"]
    assert u[:, :2] == pytest.approx(np.full((len(u), 2), STEPS - 1), rel=1e-14)


def test_replaced_columns_cost_the_same_at_every_step(tmp_path):
    """FieldWriter.write's ``columns`` (plane strain's sigma_33 in the written sigma): the
    bytes per step stay constant and the column holds the last values."""
    import h5py
    from dolfinx import fem
    from dolfinx import mesh as dmesh

    from vpcontact.io.output import FieldWriter
    from vpcontact.io.xdmf import dolfinx_time_key
    mesh = dmesh.create_unit_square(MPI.COMM_WORLD, 4, 4)
    sigma = fem.Function(fem.TensorFunctionSpace(mesh, ("DG", 0)), name="sigma")
    writer = FieldWriter(MPI.COMM_WORLD, tmp_path / "solution.xdmf", mesh, [sigma])
    owned = mesh.topology.index_map(2).size_local

    def write(n):
        sigma.x.array[:] = n
        writer.write(0.01 * n, {("sigma", 8): np.full(owned, -float(n))})
    per_step = _per_step(write)
    writer.close()
    _assert_constant(per_step, 1)
    with h5py.File(tmp_path / "solution.h5", "r") as f:
        last = f["Function/sigma"][dolfinx_time_key(0.01 * (STEPS - 1))][:]
    assert np.all(last[:, 8] == -(STEPS - 1)) and np.all(last[:, 0] == STEPS - 1)


def test_contact_xdmf_costs_the_same_at_every_step(tmp_path):
    from vpcontact.io.contact_xdmf import ContactWriter
    x = np.linspace(0.0, 1.0, 9)
    facets = np.zeros((8, 2, 3))
    facets[:, 0, 0], facets[:, 1, 0] = x[:-1], x[1:]
    writer = ContactWriter(MPI.COMM_WORLD, tmp_path / "contact.xdmf", facets, 2)

    def write(n):
        writer.write(0.01 * n, {"x": x, "y": 0 * x, "u_x": 0 * x + n, "u_y": 0 * x,
                                "u_nu": 0 * x, "state": np.array(["separated"] * 9)})
    per_step = _per_step(write)
    _assert_constant(per_step, 1)
    import pyvista as pv
    reader = pv.get_reader(str(tmp_path / "contact.xdmf"))
    assert reader.time_values == pytest.approx(0.01 * np.arange(STEPS))
    reader.set_active_time_value(reader.time_values[-1])
    assert np.all(reader.read().point_data["u"][:, 0] == STEPS - 1)


def _temporal(tmp_path):
    import xml.etree.ElementTree as ET

    from vpcontact.io.xdmf import Field, TemporalXdmf, data_item
    topology = ET.Element("Topology", TopologyType="Polyline", NumberOfElements="1",
                          NodesPerElement="2")
    topology.append(data_item("c.h5", "/Mesh/topology", (1, 2), "Int"))
    geometry = ET.Element("Geometry", GeometryType="XYZ")
    geometry.append(data_item("c.h5", "/Mesh/geometry", (2, 3)))
    xml = TemporalXdmf(tmp_path / "c.xdmf", "c", topology, geometry)
    field = Field("u", "Scalar", "Node")
    return xml, lambda n: [field.attribute("c.h5", f"/Step/{n:04d}/u", (2,))]


def _times(path) -> list[float]:
    import xml.etree.ElementTree as ET
    root = ET.parse(path).getroot()
    return [float(g.find("Time").get("Value")) for g in root.iter("Grid") if g.find("Time")
            is not None]


def test_each_time_writes_its_grid_once(tmp_path, monkeypatch):
    """The bytes written per time are the new Grid and the closing tags, the same at the
    60th time as at the 2nd; the file is complete after every time."""
    import os
    xml, attributes = _temporal(tmp_path)
    written = []
    real = os.pwrite
    monkeypatch.setattr(os, "pwrite", lambda fd, data, at: written.append(len(data))
                        or real(fd, data, at))
    for n in range(60):
        xml.add(n / 64, attributes(n))
        assert _times(tmp_path / "c.xdmf") == [k / 64 for k in range(n + 1)]
    from vpcontact.io.xdmf import TAIL
    assert written == [len(xml.grid(n / 64, attributes(n)) + TAIL)     # the first time:
               for n in range(1, 60)]                                  # a rename
    assert max(written) < 800


def test_a_failed_append_leaves_the_earlier_times(tmp_path, monkeypatch):
    """Disk full in the middle of a time's write (a short write, then ENOSPC): the file
    is put back to the earlier times, and the next time is appended after them."""
    import errno
    import os
    xml, attributes = _temporal(tmp_path)
    for n in range(3):
        xml.add(n, attributes(n))
    real = os.pwrite

    def short(fd, data, at):      # half the Grid reaches the disk, once (the closing tags
        monkeypatch.setattr(os, "pwrite", real)       # go back over blocks the file had)
        return real(fd, data[:len(data) // 2], at)
    monkeypatch.setattr(os, "pwrite", short)
    with pytest.raises(OSError) as exc:
        xml.add(3, attributes(3))
    assert exc.value.errno == errno.ENOSPC and exc.value.filename == str(tmp_path / "c.xdmf")
    monkeypatch.setattr(os, "pwrite", real)
    assert _times(tmp_path / "c.xdmf") == [0, 1, 2]
    xml.add(4, attributes(4))
    assert _times(tmp_path / "c.xdmf") == [0, 1, 2, 4]
