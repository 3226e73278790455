"""The paper's rectangle Omega = (0, L1) x (0, L2) (Section 4, Fig. 1), built with gmsh.

Facets are tagged per side (``BOUNDARY_TAGS``); the case file maps sides to the boundary
parts: Gamma1 = left (clamped), Gamma2 = right and top (tractions), Gamma3 = bottom (contact,
outward normal nu = (0, -1), tangent tau = (1, 0)).

Structured meshes are n x n squares with every square cut along the same diagonal, so a
mesh with 2n cells per side is a refinement of the one with n (each coarse triangle is a union
of fine ones): the convergence study relies on this.  They are built by dolfinx's
``create_rectangle`` by default (importing gmsh alone costs 0.6 s, a third of a whole
benchmark run's set-up) or, with ``engine="gmsh"``, as the identical transfinite gmsh mesh
(tests/unit/test_mesh.py checks both).  Unstructured meshes always come from gmsh, which runs on
one rank only; dolfinx's ``gmshio.model_to_mesh`` distributes the mesh.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

BOUNDARY_TAGS = {"left": 1, "bottom": 2, "right": 3, "top": 4, "front": 5, "back": 6}
# 2D uses left/bottom/right/top; the 3D box (meshes/box.py) adds front {y = 0}, back {y = L2}.
SIDES = {2: ("left", "bottom", "right", "top"),
         3: ("left", "bottom", "right", "top", "front", "back")}
DOMAIN_TAG = 10
# Our diagonal names follow dolfinx's create_rectangle: "right" cuts each square from
# (x0, y0) to (x1, y1), "left" from (x0, y1) to (x1, y0).  Gmsh's transfinite arrangement
# names agree with ours when the corners are given counter-clockwise from (0, 0)
# (checked by tests/unit/test_mesh.py).
_GMSH_ARRANGEMENT = {"right": "Right", "left": "Left"}


@dataclass
class RectangleMesh:
    """A distributed dolfinx mesh with its cell and facet tags and geometry data.

    Attributes:
        mesh: the dolfinx mesh.
        cell_tags: the cell tags (DOMAIN_TAG).
        facet_tags: the boundary facet tags (BOUNDARY_TAGS).
        L1, L2: the sides in x and y.
        structured: built as n x n squares (or blocks).
        n: cells per side of a structured mesh, else None.
        h: the cell size (L / n when structured).
        diagonal: the diagonal of a structured rectangle, else None.
    """

    mesh: object
    cell_tags: object
    facet_tags: object
    L1: float
    L2: float
    structured: bool
    n: int | None
    h: float | None
    diagonal: str | None

    # Gamma3 is the bottom side; its outward unit normal and unit tangent(s).
    normal = (0.0, -1.0)
    tangent = ((1.0, 0.0),)

    @property
    def dim(self) -> int:
        """The space dimension (2 for the rectangle, 3 for the box)."""
        return len(self.normal)


def _gmsh_model(L1: float, L2: float, n: int | None, h: float | None, diagonal: str | None):
    import gmsh

    gmsh.model.add("rectangle")
    geo = gmsh.model.geo
    size = h if h is not None else max(L1, L2) / max(n or 1, 1)
    p = [geo.addPoint(0, 0, 0, size), geo.addPoint(L1, 0, 0, size),
         geo.addPoint(L1, L2, 0, size), geo.addPoint(0, L2, 0, size)]
    bottom = geo.addLine(p[0], p[1])
    right = geo.addLine(p[1], p[2])
    top = geo.addLine(p[2], p[3])
    left = geo.addLine(p[3], p[0])
    loop = geo.addCurveLoop([bottom, right, top, left])
    surface = geo.addPlaneSurface([loop])
    if n is not None:
        for line in (bottom, right, top, left):
            geo.mesh.setTransfiniteCurve(line, n + 1)
        geo.mesh.setTransfiniteSurface(surface, _GMSH_ARRANGEMENT[diagonal], p)
    geo.synchronize()
    for name, line in (("left", left), ("bottom", bottom), ("right", right), ("top", top)):
        gmsh.model.addPhysicalGroup(1, [line], BOUNDARY_TAGS[name])
        gmsh.model.setPhysicalName(1, BOUNDARY_TAGS[name], name)
    gmsh.model.addPhysicalGroup(2, [surface], DOMAIN_TAG)
    gmsh.model.mesh.generate(2)


def _dolfinx_structured(comm, L1: float, L2: float, n: int, diagonal: str):
    """The structured n x n mesh by dolfinx, with the same cell and facet tags as gmsh's."""
    from dolfinx import mesh as dmesh

    msh = dmesh.create_rectangle(comm, [np.zeros(2), np.array([L1, L2])], [n, n],
                                 dmesh.CellType.triangle,
                                 diagonal=getattr(dmesh.DiagonalType, diagonal))
    tdim = msh.topology.dim
    # vertex coordinates along an axis carry round-off relative to that axis' length
    tx, ty = 1e-8 * L1, 1e-8 * L2
    sides = {"left": lambda x: np.abs(x[0]) <= tx, "bottom": lambda x: np.abs(x[1]) <= ty,
             "right": lambda x: np.abs(x[0] - L1) <= tx, "top": lambda x: np.abs(x[1] - L2) <= ty}
    facets, values = [], []
    for name, where in sides.items():
        f = dmesh.locate_entities_boundary(msh, tdim - 1, where)
        facets.append(f)
        values.append(np.full(len(f), BOUNDARY_TAGS[name], dtype=np.int32))
    facets, values = np.concatenate(facets), np.concatenate(values)
    order = np.argsort(facets)
    ft = dmesh.meshtags(msh, tdim - 1, facets[order], values[order])
    cells = np.arange(msh.topology.index_map(tdim).size_local, dtype=np.int32)
    ct = dmesh.meshtags(msh, tdim, cells, np.full(len(cells), DOMAIN_TAG, dtype=np.int32))
    return msh, ct, ft


def build_rectangle(comm: MPI.Comm, L1: float = 1.0, L2: float = 1.0, *, n: int | None = None,
                    h: float | None = None, diagonal: str = "right",
                    engine: str = "dolfinx") -> RectangleMesh:
    """Build the rectangle mesh; collective on ``comm``.

    Args:
        comm: the communicator the mesh is distributed over.
        L1, L2: the sides in x and y.
        n: squares per side of a structured mesh, or None.
        h: target cell size of an unstructured (gmsh) mesh, or None.
        diagonal: "right" or "left", the cut of every square of a structured mesh.
        engine: "dolfinx" or "gmsh", which builds a structured mesh.

    Returns:
        The RectangleMesh.

    Raises:
        ValueError: unless exactly one of n and h is given, or for an unknown diagonal or
            engine.
    """
    if (n is None) == (h is None):
        raise ValueError("give exactly one of n (structured) or h (unstructured)")
    if n is not None and diagonal not in _GMSH_ARRANGEMENT:
        raise ValueError(f"diagonal must be one of {sorted(_GMSH_ARRANGEMENT)}, got {diagonal!r}")
    if engine not in ("dolfinx", "gmsh"):
        raise ValueError(f"engine must be 'dolfinx' or 'gmsh', got {engine!r}")
    if n is not None and engine == "dolfinx":
        msh, ct, ft = _dolfinx_structured(comm, L1, L2, n, diagonal)
        return RectangleMesh(msh, ct, ft, float(L1), float(L2), True, n, max(L1, L2) / n,
                             diagonal)
    # gmsh sees the rectangle scaled to unit size (its tolerances are absolute)
    s = max(L1, L2)
    msh, ct, ft = gmsh_mesh(comm, 2, lambda: _gmsh_model(L1 / s, L2 / s, n,
                                                         None if h is None else h / s,
                                                         diagonal), s)
    return RectangleMesh(msh, ct, ft, float(L1), float(L2), n is not None, n,
                         h if n is None else max(L1, L2) / n, diagonal if n is not None else None)


def gmsh_mesh(comm: MPI.Comm, gdim: int, build, scale: float):
    """The dolfinx mesh of a gmsh model built on rank 0; collective on ``comm``.

    Gmsh's geometric tolerances are absolute, so models are built at unit size and scaled
    afterwards.

    Args:
        comm: the communicator the mesh is distributed over.
        gdim: the geometric dimension.
        build: called on rank 0 (gmsh initialised) to create the model and generate its mesh.
        scale: the factor applied to the coordinates.

    Returns:
        (mesh, cell tags, facet tags).
    """
    import gmsh
    from dolfinx.io import gmshio

    if comm.rank == 0:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            build()
            msh, ct, ft = gmshio.model_to_mesh(gmsh.model, comm, 0, gdim=gdim)
        finally:
            gmsh.finalize()
    else:
        msh, ct, ft = gmshio.model_to_mesh(None, comm, 0, gdim=gdim)
    if scale != 1.0:
        msh.geometry.x[:, :gdim] *= scale
    return msh, ct, ft
