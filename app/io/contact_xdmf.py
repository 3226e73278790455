"""contact.xdmf (+ contact.h5): the contact boundary Gamma3 as a facet mesh (segments in 2D,
triangles in 3D) carrying the contact table's columns at every output time, one dataset as
solution.xdmf is.

Gamma3 has O(n^(d-1)) nodes: its facets are gathered on rank 0 once and the contact table
at each output time (gather_contact_table, the columns of contact.csv); rank 0 writes the
HDF5 file with h5py and then appends the time's Grid to contact.xdmf (app/io/xdmf.py
TemporalXdmf: O(1) per time, the file complete after every time), so that contact.xdmf
always describes complete data.  Nodes that a Dirichlet condition fixes
entirely are in the facet mesh but not in the table: their values are NaN and their state
"prescribed".  With friction the table's columns are written as they are: slip_state
(Coulomb: -1 separated, 0 stick, 1 slip; app/post/quantities.py SLIP_CODES),
slip_increment and slip_accumulated (Coulomb or a slip law), held (1 where a Dirichlet
condition prescribes a component of u).
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from vpcontact.io.h5files import open_h5
from vpcontact.io.output import OutputError, on_rank0
from vpcontact.io.xdmf import Field, TemporalXdmf, data_item

STATE_CODES = {"separated": 0, "compliance": 1, "bound": 2, "prescribed": 3}
TOPOLOGY = {2: "Polyline", 3: "Triangle", 4: "Quadrilateral"}      # by nodes per facet


def facet_mesh(parts: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The Gamma3 facet mesh from the ranks' facet vertex coordinates.

    Args:
        parts: per rank, shape (facets, vertices per facet, 3)
            (problem.gamma3_facet_coordinates()).

    Returns:
        (points (n, 3) sorted by coordinates as contact.csv's rows, cells (facets, vertices
        per facet), each facet once).
    """
    nv = max((p.shape[1] for p in parts if p.size), default=2)
    x = np.concatenate([p.reshape(-1, 3) for p in parts if p.size] or [np.zeros((0, 3))])
    keys = np.round(x / max(float(np.abs(x).max(initial=0.0)), 1e-300), 9)
    unique, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    cells = inverse.reshape(-1, nv)
    _, keep = np.unique(np.sort(cells, axis=1), axis=0, return_index=True)
    cells = cells[np.sort(keep)]                   # each facet once (shared by two ranks)
    order = np.lexsort((unique[:, 2], unique[:, 1], unique[:, 0]))    # by x, y, z as the CSV
    position = np.empty_like(order)
    position[order] = np.arange(len(order))
    return x[first][order], position[cells]


def node_index(points: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The facet-mesh node of each table row, by coordinates.

    Args:
        points: the facet mesh's points (n, 3).
        x: the table's coordinates (rows, d).

    Returns:
        Indices into points.

    Raises:
        ValueError: a row has no node within 1e-8 of the body's size.
    """
    d = x.shape[1]
    scale = max(float(np.abs(points).max(initial=0.0)), 1e-300)
    if len(points):           # both sorted by their rounded x, y, z: a binary search
        key = np.dtype([(f"c{i}", float) for i in range(d)])
        keys = [np.ascontiguousarray(np.round(a / scale, 9)).view(key).ravel()
                for a in (points[:, :d], x)]
        idx = np.minimum(np.searchsorted(keys[0], keys[1]), len(points) - 1)
        if np.abs(points[idx, :d] - x).max(initial=0.0) <= 1e-8 * scale:
            return idx
    from scipy.spatial import cKDTree  # rounding put a row elsewhere: the nearest node
    dist, idx = cKDTree(points[:, :d]).query(x)
    if len(dist) and dist.max() > 1e-8 * scale:
        raise ValueError("a contact table node is not a vertex of the Gamma3 facets")
    return idx


class ContactWriter:
    """contact.xdmf and contact.h5 in an output directory (collective methods).

    Args:
        comm: the MPI communicator.
        path: the XDMF file (the HDF5 file: the same name with .h5).
        facets: this rank's Gamma3 facet vertex coordinates (problem.gamma3_facet_coordinates()).
        dim: the body's dimension (the table's coordinate columns).

    Raises:
        OutputError: the files cannot be written (on every rank).
    """

    def __init__(self, comm, path: Path, facets: np.ndarray, dim: int):
        self.comm, self.path, self.dim = comm, Path(path), dim
        self.h5 = self.path.with_suffix(".h5")
        self.xml = None
        parts = comm.gather(np.asarray(facets, dtype=float), root=0)
        self.points = self.cells = None
        if comm.rank == 0:
            self.points, self.cells = facet_mesh(parts)
        on_rank0(comm, self._create)

    def _create(self) -> None:
        with open_h5(self.h5, "w") as f:
            f["Mesh/geometry"] = self.points
            f["Mesh/topology"] = self.cells.astype(np.int64)
            f.create_group("Step", track_order=True)     # O(1) per time (FieldWriter)
        nf, nv = self.cells.shape
        topology = ET.Element("Topology", TopologyType=TOPOLOGY[nv], NumberOfElements=str(nf),
                              NodesPerElement=str(nv))
        topology.append(data_item(self.h5.name, "/Mesh/topology", (nf, nv), "Int"))
        geometry = ET.Element("Geometry", GeometryType="XYZ")
        geometry.append(data_item(self.h5.name, "/Mesh/geometry", self.points.shape))
        self.xml = TemporalXdmf(self.path, self.path.stem, topology, geometry)

    def write(self, t: float, data: dict | None) -> None:
        """Append the table at time t (collective; the data is read on rank 0).

        Args:
            t: the time.
            data: the gathered table (gather_contact_table) on rank 0, None elsewhere.

        Raises:
            OutputError: on every rank, if the files cannot be written (contact.xdmf then
                still describes the earlier times).
        """
        on_rank0(self.comm, self._write, t, data)

    def _write(self, t: float, data: dict) -> None:
        try:
            idx = node_index(self.points, np.column_stack([data[a] for a in "xyz"[:self.dim]]))
        except ValueError as exc:
            raise OutputError(f"{self.path}: {exc}") from None
        n, k = len(self.points), self.xml.times
        columns = self._columns(data, idx, n)
        with open_h5(self.h5, "a") as f:
            for name, values in columns.items():
                f[f"Step/{k}/{name}"] = values
        self.xml.add(t, [Field(name, "Vector" if name == "u" else "Scalar", "Node")
                         .attribute(self.h5.name, f"/Step/{k}/{name}", values.shape)
                         for name, values in columns.items()])

    def _columns(self, data: dict, idx: np.ndarray, n: int) -> dict[str, np.ndarray]:
        """The point arrays of one time: u (a 3-vector), the table's scalar columns, state."""
        def full(values, fill=np.nan):
            out = np.full(n, fill, dtype=float)
            out[idx] = values
            return out
        axes = "xyz"[:self.dim]
        u = np.full((n, 3), np.nan)
        for i, a in enumerate(axes):
            u[idx, i] = data[f"u_{a}"]
        u[idx, self.dim:] = 0.0
        columns = {"u": u}
        skip = set(axes) | {f"u_{a}" for a in axes} | {"state"}
        for name, values in data.items():
            if name not in skip and not name.startswith("_"):
                columns[name] = full(values)
        codes = np.array([STATE_CODES[s] for s in data["state"]], dtype=float)
        columns["state"] = full(codes, STATE_CODES["prescribed"])
        return columns
