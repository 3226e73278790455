"""The paper's rectangle Omega = (0, L1) x (0, L2) (Section 4, Fig. 1), built with gmsh.

Facets are tagged per side (``BOUNDARY_TAGS``; ``groups`` maps the side names left, bottom,
right, top to their tags, as a gmsh file's named physical groups do); the case file maps sides
to the boundary parts: Gamma1 = left (clamped), Gamma2 = right and top (tractions), Gamma3 =
bottom (contact, outward normal nu = (0, -1), tangent tau = (1, 0)).

Structured meshes are n x n squares with every square cut along the same diagonal, so a
mesh with 2n cells per side is a refinement of the one with n (each coarse triangle is a union
of fine ones): the convergence study relies on this.  They are built by gmsh as a transfinite
mesh by default (its vertices then put exactly on the grid (L / n) i) or, with
``engine="dolfinx"``, by dolfinx's ``create_rectangle``: the same triangles and bitwise the
same coordinates (tests/unit/test_mesh.py checks both), without the cost of importing gmsh
(docs/performance.md, section 3) and of its meshing.
Unstructured meshes always come from gmsh, which runs on one rank only; the mesh is
distributed as dolfinx's ``gmshio.model_to_mesh`` does.  A mesh gmsh built is kept in the
mesh cache (meshes/meshcache.py), so that a later run with the same rectangle neither imports
gmsh nor meshes it again (the same mesh, bit for bit).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from .extent import mesh_extent
from .meshcache import cache_key
from .partition import cell_partitioner

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
        h: the cell size (L / n when structured, else the target size).
        diagonal: the diagonal of a structured rectangle, else None.
        L3: the side in z (0 for the rectangle).
        h_min: the smallest cell diameter (longest edge of a cell).
        bbox: (lo, hi), the corners of the bounding box of all vertices, each (dim,).
        groups: side name -> facet tag (left bottom right top, and front back in 3D).
        tags: the facet tags of the sides, sorted.
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
    L3: float = 0.0
    h_min: float | None = None
    bbox: tuple[np.ndarray, np.ndarray] | None = None

    # Gamma3 is the bottom side; its outward unit normal and unit tangent(s).
    normal = (0.0, -1.0)
    tangent = ((1.0, 0.0),)

    @property
    def dim(self) -> int:
        """The space dimension (2 for the rectangle, 3 for the box)."""
        return len(self.normal)

    @property
    def groups(self) -> dict[str, int]:
        """Side name -> facet tag, like a gmsh file's named boundary groups."""
        return {name: BOUNDARY_TAGS[name] for name in SIDES[self.dim]}

    @property
    def tags(self) -> tuple[int, ...]:
        """The facet tags of the sides, sorted."""
        return tuple(sorted(self.groups.values()))


def _gmsh_model(L1: float, L2: float, n: int | None, h: float | None, diagonal: str | None):
    from .gmshfile import import_gmsh
    gmsh = import_gmsh()

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


def dolfinx_structured(comm: MPI.Comm, L, n: int, diagonal: str | None = None):
    """The structured rectangle or box by dolfinx, tagged like the gmsh meshes; collective.

    Args:
        comm: the communicator the mesh is distributed over.
        L: the sides (L1, L2) or (L1, L2, L3).
        n: squares (cubes) per side.
        diagonal: "right" or "left" in 2D (each square's cut); unused in 3D.

    Returns:
        (mesh, cell tags, facet tags): DOMAIN_TAG on the cells, BOUNDARY_TAGS on the sides.
    """
    from dolfinx import mesh as dmesh

    d = len(L)
    corners = [np.zeros(d), np.array(L, dtype=float)]
    if d == 2:
        msh = dmesh.create_rectangle(comm, corners, [n, n], dmesh.CellType.triangle,
                                     partitioner=cell_partitioner(comm),
                                     diagonal=getattr(dmesh.DiagonalType, diagonal))
    else:
        msh = dmesh.create_box(comm, corners, [n, n, n], dmesh.CellType.tetrahedron,
                               partitioner=cell_partitioner(comm))
    return (msh,) + tag_sides(msh, L)


def tag_sides(msh, L) -> tuple:
    """The rectangle's or box's tags, found geometrically: DOMAIN_TAG on the owned cells,
    BOUNDARY_TAGS on the sides; collective.  Also tags a refinement of such a mesh (its
    sides are the same planes).

    Args:
        msh: a dolfinx mesh of (0, L1) x (0, L2) [x (0, L3)].
        L: the sides (L1, L2) or (L1, L2, L3).

    Returns:
        (cell tags, facet tags).
    """
    from dolfinx import mesh as dmesh

    d, tdim = len(L), msh.topology.dim
    # the axis and the end of each side; vertex coordinates along an axis carry round-off
    # relative to that axis' length
    where = {"left": (0, 0), "right": (0, 1), "bottom": (d - 1, 0), "top": (d - 1, 1),
             "front": (1, 0), "back": (1, 1)}
    facets, values = [], []
    for name in SIDES[d]:
        axis, end = where[name]
        value, tol = end * L[axis], 1e-8 * L[axis]
        f = dmesh.locate_entities_boundary(
            msh, tdim - 1, lambda x, a=axis, v=value, t=tol: np.abs(x[a] - v) <= t)
        facets.append(f)
        values.append(np.full(len(f), BOUNDARY_TAGS[name], dtype=np.int32))
    facets, values = np.concatenate(facets), np.concatenate(values)
    order = np.argsort(facets)
    ft = dmesh.meshtags(msh, tdim - 1, facets[order], values[order])
    cells = np.arange(msh.topology.index_map(tdim).size_local, dtype=np.int32)
    ct = dmesh.meshtags(msh, tdim, cells, np.full(len(cells), DOMAIN_TAG, dtype=np.int32))
    return ct, ft


def build_rectangle(comm: MPI.Comm, L1: float = 1.0, L2: float = 1.0, *, n: int | None = None,
                    h: float | None = None, diagonal: str = "right",
                    engine: str = "gmsh") -> RectangleMesh:
    """Build the rectangle mesh; collective on ``comm``.

    Args:
        comm: the communicator the mesh is distributed over.
        L1, L2: the sides in x and y.
        n: squares per side of a structured mesh, or None.
        h: target cell size of an unstructured (gmsh) mesh, or None.
        diagonal: "right" or "left", the cut of every square of a structured mesh.
        engine: "gmsh" (default) or "dolfinx", which builds a structured mesh (the same
            triangles).

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
        msh, ct, ft = dolfinx_structured(comm, (L1, L2), n, diagonal)
    else:
        # gmsh sees the rectangle scaled to unit size (its tolerances are absolute)
        s = max(L1, L2)
        args = (L1 / s, L2 / s, n, None if h is None else h / s, diagonal)
        msh, ct, ft = gmsh_mesh(comm, 2, lambda: _gmsh_model(*args), s,
                                cache_key("rectangle", args, Path(__file__)))
        if n is not None:
            snap_to_grid(msh, (L1, L2), n)
    h_min, _, bbox = mesh_extent(msh)
    return RectangleMesh(msh, ct, ft, float(L1), float(L2), n is not None, n,
                         h if n is None else max(L1, L2) / n,
                         diagonal if n is not None else None, 0.0, h_min, bbox)


def snap_to_grid(msh, L, n: int) -> None:
    """Put a structured mesh's vertices exactly on the grid x_a = (L_a / n) i.

    Gmsh places transfinite nodes to about 1e-12 L; dolfinx's create_rectangle/create_box
    compute (L_a / n) i, so after this both engines give bitwise the same coordinates.

    Args:
        msh: the dolfinx mesh (its geometry is changed in place).
        L: the sides (L1, L2) or (L1, L2, L3).
        n: cells per side.
    """
    x = msh.geometry.x
    for a, length in enumerate(L):
        step = length / n
        x[:, a] = step * np.rint(x[:, a] / step)


def gmsh_mesh(comm: MPI.Comm, gdim: int, build, scale: float, key: str | None = None):
    """The dolfinx mesh of a gmsh model built on rank 0; collective on ``comm``.

    Gmsh's geometric tolerances are absolute, so models are built at unit size and scaled
    afterwards.  With a ``key`` the model's arrays come from the mesh cache when it has
    them (meshes/meshcache.py: gmsh is then not even imported) and are stored there after
    gmsh built them.

    Args:
        comm: the communicator the mesh is distributed over.
        gdim: the geometric dimension.
        build: called on rank 0 (gmsh initialised) to create the model and generate its mesh.
        scale: the factor applied to the coordinates.
        key: the mesh cache's key of the model (``meshcache.cache_key``), or None: no cache.

    Returns:
        (mesh, cell tags, facet tags).
    """
    from . import meshcache
    arrays = meshcache.load(key) if key is not None and comm.rank == 0 else None
    if not comm.bcast(arrays is not None, root=0):
        arrays = _gmsh_arrays(comm, build)
        if key is not None and comm.rank == 0:
            meshcache.store(key, arrays)
    msh, ct, ft = meshcache.to_mesh(comm, arrays, gdim)
    if scale != 1.0:
        msh.geometry.x[:, :gdim] *= scale
    return msh, ct, ft


def _gmsh_arrays(comm: MPI.Comm, build) -> dict | None:
    """gmsh's model built on rank 0 and read as meshcache.model_arrays (None elsewhere)."""
    from . import meshcache
    from .gmshfile import _interruptible, import_gmsh, on_root
    gmsh = import_gmsh()              # before gmshio, whose import of gmsh resets SIGINT
    # SIGINT/SIGTERM stop the wait for gmsh at once (_interruptible); rank 0 raises build's
    # own error, the other ranks a RuntimeError
    on_root(comm, lambda _: _interruptible(build),
            lambda err: f"rank 0 could not build the mesh: {type(err).__name__}: {err}",
            keep=True, share=False, error=RuntimeError, reraise=True)
    if comm.rank != 0:
        return None
    try:
        return meshcache.model_arrays(gmsh.model)
    finally:
        gmsh.finalize()
