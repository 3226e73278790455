"""XDMF files that ParaView and VTK open as one dataset: one temporal collection whose Grid
at each time carries the mesh's Topology and Geometry and every field of that time.

dolfinx (XDMFFile.write_function) writes the mesh as one Grid and each function as its own
temporal collection, so readers show one block per function (ParaView's Xdmf3 readers,
pyvista.read: a MultiBlock of 5).  solution.xdmf is therefore our own XML over dolfinx's
HDF5 datasets, and contact.xdmf over ours (app/io/contact_xdmf.py).  The file grows as
the run goes (TemporalXdmf): each time's Grid is written once, in place before the closing
tags, so writing a time costs the same at step 3000 as at step 3.

Every DataItem states Precision="8": dolfinx writes float64 and int64 but leaves XDMF's
default (4), with which VTK's XDMF reader reads float32.
"""
from __future__ import annotations

import errno
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from vpcontact.io.files import atomic_write


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


TAIL = b"    </Grid>\n  </Domain>\n</Xdmf>\n"    # closes the collection and the file


class TemporalXdmf:
    """An XDMF file of one temporal collection over one mesh, grown a time at a time.

    The file is complete after every time added, and adding a time costs O(1) whatever the
    number of times before it: the first time's Grid replaces the mesh-only Grid by an
    atomic rewrite (temporary file and rename); every later Grid is written, followed by the
    closing tags, over the old closing tags by one ``pwrite`` at their offset, so the
    earlier times are never rewritten.  A failed write (disk full) puts the closing tags
    back: the file then still describes the earlier times.

    Args:
        path: the XDMF file (written at once with the mesh alone).
        name: the collection's and its Grids' name (the dataset's name in ParaView).
        topology, geometry: the mesh's Topology and Geometry elements.

    Raises:
        OSError: the file cannot be written.
    """

    def __init__(self, path, name: str, topology: ET.Element, geometry: ET.Element):
        self.path, self.name = Path(path), name
        self._mesh = _text(topology, 4) + _text(geometry, 4)
        self.times = 0
        self._tail_at = None            # the closing tags' byte offset (after a time)
        grid = (f'      <Grid Name="{self.name}" GridType="Uniform">\n'
                f"{self._mesh}      </Grid>\n")
        _publish(self.path, self._head() + grid.encode() + TAIL)

    def _head(self) -> bytes:
        return ('<?xml version="1.0"?>\n<Xdmf Version="3.0">\n  <Domain>\n'
                f'    <Grid Name="{self.name}" GridType="Collection" '
                'CollectionType="Temporal">\n').encode()

    def grid(self, t: float, attributes: list[ET.Element]) -> bytes:
        """The Grid of time t (the mesh and the attributes), UTF-8.

        Args:
            t: the time.
            attributes: its Attribute elements.

        Returns:
            The Grid's XML, indented as in the file.
        """
        body = "".join(_text(a, 4) for a in attributes)
        return (f'      <Grid Name="{self.name}" GridType="Uniform">\n{self._mesh}'
                f'        <Time Value="{float(t)!r}" />\n{body}      </Grid>\n').encode()

    def add(self, t: float, attributes: list[ET.Element]) -> None:
        """Append the Grid of time t to the file (O(1) bytes written).

        Args:
            t: the time.
            attributes: its Attribute elements.

        Raises:
            OSError: the file cannot be written (it then describes the earlier times).
        """
        grid = self.grid(t, attributes)
        if self._tail_at is None:
            head = self._head() + grid
            _publish(self.path, head + TAIL)
            self._tail_at = len(head)
        else:
            self._append(grid)
        self.times += 1

    def _append(self, grid: bytes) -> None:
        """Write ``grid`` and the closing tags over the closing tags, in one write."""
        data = grid + TAIL
        fd = os.open(self.path, os.O_WRONLY)
        try:
            if os.pwrite(fd, data, self._tail_at) != len(data):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self.path))
        except OSError as exc:
            _restore_tail(fd, self._tail_at)
            if exc.filename is None:
                exc.filename = str(self.path)
            raise
        finally:
            os.close(fd)
        self._tail_at += len(grid)


def _restore_tail(fd: int, offset: int) -> None:
    """After a failed append: the file ends with the closing tags at ``offset`` again (the
    blocks there were the file's before; best effort)."""
    try:
        os.ftruncate(fd, offset)
        os.pwrite(fd, TAIL, offset)
    except OSError:
        pass


def _publish(path: Path, data: bytes) -> None:
    """Replace the file by a rename, unsynced (the HDF5 data it points at is not synced either)."""
    atomic_write(path, data, sync=False)


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
