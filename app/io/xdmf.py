"""One XDMF dataset from dolfinx's XDMF file: the XML that ParaView and VTK open as one mesh
with every field at every time.

dolfinx (XDMFFile.write_function) writes the mesh as one Grid and each function as its own
temporal collection, so readers show one block per function (ParaView's Xdmf3 readers,
pyvista.read: a MultiBlock of 5).  ``one_dataset`` rewrites that XML, not the heavy data:
one temporal collection whose Grid at each time carries the mesh's Topology and Geometry
and every function written at that time as an Attribute; the DataItems still point at the
datasets dolfinx wrote (in parallel) into the HDF5 file.
"""
from __future__ import annotations

import copy
import xml.etree.ElementTree as ET

XINCLUDE = "http://www.w3.org/2001/XInclude"
ET.register_namespace("xi", XINCLUDE)


class XdmfLayoutError(ValueError):
    """The XML is not the layout dolfinx writes (mesh Grid, then temporal collections)."""


def one_dataset(text: str, name: str = "solution", h5_from: str | None = None,
                h5_to: str | None = None) -> str:
    """The one-dataset form of a dolfinx XDMF file's XML.

    Args:
        text: the XML dolfinx wrote (a Uniform mesh Grid, then one temporal collection per
            function, each Grid with a Time and Attributes).
        name: the name of the collection and of its Grids (the dataset's name in ParaView).
        h5_from, h5_to: the HDF5 file name in the DataItems, and its replacement (the work
            file's name and the published one); None: unchanged.

    Returns:
        The XML: one temporal collection; per time (in the order first written) one Uniform
        Grid with the mesh's Topology and Geometry and the Attributes of that time, in the
        order of the functions.  Every DataItem states Precision="8": dolfinx writes float64
        and int64 but leaves XDMF's default (4), so VTK's XDMF reader read float32.

    Raises:
        XdmfLayoutError: no mesh Grid, or a function's Grid without Time.
    """
    root = ET.fromstring(text)
    domain = root.find("Domain")
    grids = [] if domain is None else list(domain.findall("Grid"))
    meshes = [g for g in grids if g.get("GridType") == "Uniform"]
    if not meshes or meshes[0].find("Topology") is None or meshes[0].find("Geometry") is None:
        raise XdmfLayoutError("no mesh Grid with Topology and Geometry")
    mesh = meshes[0]
    times: dict[str, list[ET.Element]] = {}
    for coll in (g for g in grids if g.get("CollectionType") == "Temporal"):
        for g in coll.findall("Grid"):
            t = g.find("Time")
            if t is None:
                raise XdmfLayoutError(f"a Grid of {coll.get('Name')!r} has no Time")
            times.setdefault(t.get("Value"), []).extend(g.findall("Attribute"))
    out_root = ET.Element("Xdmf", root.attrib)
    out_domain = ET.SubElement(out_root, "Domain")
    collection = ET.SubElement(out_domain, "Grid", Name=name, GridType="Collection",
                               CollectionType="Temporal")
    for value, attributes in times.items():
        grid = ET.SubElement(collection, "Grid", Name=name, GridType="Uniform")
        grid.append(copy.deepcopy(mesh.find("Topology")))
        grid.append(copy.deepcopy(mesh.find("Geometry")))
        ET.SubElement(grid, "Time", Value=value)
        grid.extend(copy.deepcopy(a) for a in attributes)
    if not times:                                   # the mesh alone (nothing written yet)
        grid = ET.SubElement(collection, "Grid", Name=name, GridType="Uniform")
        grid.extend([copy.deepcopy(mesh.find("Topology")), copy.deepcopy(mesh.find("Geometry"))])
    for item in out_root.iter("DataItem"):
        item.set("Precision", "8")          # dolfinx's datasets: float64 and int64
        if h5_from is not None and item.text and item.text.strip().startswith(f"{h5_from}:"):
            item.text = h5_to + item.text.strip()[len(h5_from):]
    ET.indent(out_root, "  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(out_root, encoding="unicode") + "\n"
