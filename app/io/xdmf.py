"""XDMF files that ParaView and VTK open as one dataset: one temporal collection whose Grid
at each time carries the mesh's Topology and Geometry and every field of that time.

dolfinx (XDMFFile.write_function) writes the mesh as one Grid and each function as its own
temporal collection, so readers show one block per function (ParaView's Xdmf3 readers,
pyvista.read: a MultiBlock of 5).  solution.xdmf is therefore our own XML over dolfinx's
HDF5 datasets, and contact.xdmf over ours (app/io/contact_xdmf.py).  The XML is built as
the run goes, one Grid's text per time, so writing step n costs O(n) string joining and
never re-parses the file.

Every DataItem states Precision="8": dolfinx writes float64 and int64 but leaves XDMF's
default (4), with which VTK's XDMF reader reads float32.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass


class XdmfLayoutError(ValueError):
    """The XML is not the layout dolfinx writes (a mesh Grid, temporal collections)."""


def data_item(h5: str, path: str, shape, number: str = "Float") -> ET.Element:
    """A DataItem pointing at an HDF5 dataset.

    Args:
        h5: the HDF5 file's name (relative to the XDMF file).
        path: the dataset's path in it.
        shape: its shape.
        number: "Float" (float64) or "Int" (int64).

    Returns:
        The element.
    """
    item = ET.Element("DataItem", Dimensions=" ".join(map(str, shape)), NumberType=number,
                      Precision="8", Format="HDF")
    item.text = f"{h5}:{path}"
    return item


@dataclass(frozen=True)
class Field:
    """A field of the dataset: its name, XDMF AttributeType (Scalar, Vector, Tensor) and
    Center (Node, Cell)."""

    name: str
    kind: str
    center: str

    def attribute(self, h5: str, path: str, shape) -> ET.Element:
        """The Attribute of this field at one time.

        Args:
            h5: the HDF5 file's name.
            path: the dataset of this time.
            shape: its shape.

        Returns:
            The element.
        """
        att = ET.Element("Attribute", Name=self.name, AttributeType=self.kind,
                         Center=self.center)
        att.append(data_item(h5, path, shape))
        return att


class TemporalXml:
    """The XML text of one temporal collection over one mesh, built a time at a time.

    Args:
        name: the collection's and its Grids' name (the dataset's name in ParaView).
        topology, geometry: the mesh's Topology and Geometry elements.
    """

    def __init__(self, name: str, topology: ET.Element, geometry: ET.Element):
        self.name = name
        self._mesh = _text(topology, 4) + _text(geometry, 4)
        self._grids: list[str] = []

    def add(self, t: float, attributes: list[ET.Element]) -> None:
        """Append the Grid of time t.

        Args:
            t: the time.
            attributes: its Attribute elements.
        """
        body = "".join(_text(a, 4) for a in attributes)
        self._grids.append(f'      <Grid Name="{self.name}" GridType="Uniform">\n{self._mesh}'
                           f'        <Time Value="{float(t)!r}" />\n{body}      </Grid>\n')

    @property
    def times(self) -> int:
        """The number of times added."""
        return len(self._grids)

    def text(self) -> str:
        """The whole XML file.

        Returns:
            The text (the mesh alone in one Grid while no time was added).
        """
        grids = self._grids or [f'      <Grid Name="{self.name}" GridType="Uniform">\n'
                                f"{self._mesh}      </Grid>\n"]
        return ('<?xml version="1.0"?>\n<Xdmf Version="3.0">\n  <Domain>\n'
                f'    <Grid Name="{self.name}" GridType="Collection" '
                f'CollectionType="Temporal">\n{"".join(grids)}    </Grid>\n'
                "  </Domain>\n</Xdmf>\n")


def dolfinx_time_key(t: float) -> str:
    """The name dolfinx 0.5 gives a function's dataset at time t (FieldWriter checks it at
    the first time written).

    Args:
        t: the time.

    Returns:
        boost::lexical_cast of t (17 significant digits, %.17g) with '.' replaced by '_'.
    """
    return f"{t:.17g}".replace(".", "_")


def _text(element: ET.Element, level: int) -> str:
    """An element's XML indented at ``level`` (two spaces each), ending in a newline."""
    ET.indent(element, "  ", level)
    return "  " * level + ET.tostring(element, encoding="unicode").rstrip() + "\n"


def dolfinx_layout(text: str, h5: str) -> tuple[ET.Element, ET.Element, list[Field]]:
    """The mesh and the fields of the XML dolfinx wrote (read once, at the first time).

    Args:
        text: dolfinx's XML (a Uniform mesh Grid, then one temporal collection per function).
        h5: the HDF5 name the mesh's DataItems get (the published file's).

    Returns:
        (Topology, Geometry, the fields in the order of their collections).

    Raises:
        XdmfLayoutError: no mesh Grid with Topology and Geometry.
    """
    domain = ET.fromstring(text).find("Domain")
    grids = [] if domain is None else domain.findall("Grid")
    mesh = next((g for g in grids if g.get("GridType") == "Uniform"), None)
    if mesh is None or mesh.find("Topology") is None or mesh.find("Geometry") is None:
        raise XdmfLayoutError("no mesh Grid with Topology and Geometry")
    parts = []
    for tag in ("Topology", "Geometry"):
        element = mesh.find(tag)
        old = element.find("DataItem")
        path = old.text.strip().split(":", 1)[1]
        element.remove(old)
        element.append(data_item(h5, path, old.get("Dimensions").split(),
                                 old.get("NumberType", "Float")))
        parts.append(element)
    fields = []
    for coll in (g for g in grids if g.get("CollectionType") == "Temporal"):
        att = coll.find("Grid/Attribute")
        if att is not None:
            fields.append(Field(att.get("Name"), att.get("AttributeType"), att.get("Center")))
    return parts[0], parts[1], fields
