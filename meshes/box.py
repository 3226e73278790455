"""The 3D analogue of the paper's scene: the box (0, L1) x (0, L2) x (0, L3), built with gmsh.

Faces are tagged per side (``BOUNDARY_TAGS``): Gamma1 = left {x = 0} (clamped), Gamma3 =
bottom {z = 0} (contact, nu = (0, 0, -1)), Gamma2 = right {x = L1}, top {z = L3}, front
{y = 0}, back {y = L2}; ``groups`` maps these names to their tags.  Structured meshes are
n x n x n blocks cut into six tetrahedra each: by gmsh's transfinite volume (the default) or,
with ``engine="dolfinx"``, by dolfinx's ``create_box``.  Both have the same vertices, blocks
and face tags, but not the same tetrahedra: the two cut the blocks differently (so results on
them differ by the discretisation error, not by round-off).  Unstructured meshes have target
size h and come from gmsh.
"""
from __future__ import annotations

from pathlib import Path

from mpi4py import MPI

from .extent import mesh_extent
from .meshcache import cache_key
from .rectangle import (
    BOUNDARY_TAGS,
    DOMAIN_TAG,
    RectangleMesh,
    dolfinx_structured,
    gmsh_mesh,
    snap_to_grid,
)

_FACES = {"left": (0, 0.0), "right": (0, 1.0), "front": (1, 0.0), "back": (1, 1.0),
          "bottom": (2, 0.0), "top": (2, 1.0)}


class BoxMesh(RectangleMesh):
    """A distributed 3D mesh with its tags; Gamma3 is the bottom face."""

    normal = (0.0, 0.0, -1.0)
    tangent = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))


def _gmsh_model(L, n, h):
    from .gmshfile import import_gmsh
    gmsh = import_gmsh()

    gmsh.model.add("box")
    vol = gmsh.model.occ.addBox(0, 0, 0, *L)
    gmsh.model.occ.synchronize()
    if n is not None:
        for _, c in gmsh.model.getEntities(1):
            gmsh.model.mesh.setTransfiniteCurve(c, n + 1)
        for _, s in gmsh.model.getEntities(2):
            gmsh.model.mesh.setTransfiniteSurface(s)
        gmsh.model.mesh.setTransfiniteVolume(vol)
    else:
        gmsh.option.setNumber("Mesh.MeshSizeMin", h)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    for _, s in gmsh.model.getEntities(2):
        # a face is told by its centre (exact; OCC's bounding boxes are padded by 1e-7)
        centre = gmsh.model.occ.getCenterOfMass(2, s)
        for name, (axis, frac) in _FACES.items():
            if abs(centre[axis] - frac * L[axis]) <= 1e-6 * L[axis]:
                gmsh.model.addPhysicalGroup(2, [s], BOUNDARY_TAGS[name])
                gmsh.model.setPhysicalName(2, BOUNDARY_TAGS[name], name)
    gmsh.model.addPhysicalGroup(3, [vol], DOMAIN_TAG)
    gmsh.model.mesh.generate(3)


def build_box(comm: MPI.Comm, L1: float = 1.0, L2: float = 1.0, L3: float = 1.0, *,
              n: int | None = None, h: float | None = None, engine: str = "gmsh") -> BoxMesh:
    """Build the box mesh; collective on ``comm``.

    Args:
        comm: the communicator the mesh is distributed over.
        L1, L2, L3: the box's sides (x, y, z).
        n: cells per side of a structured mesh (n x n x n blocks of tetrahedra), or None.
        h: target cell size of an unstructured mesh, or None.
        engine: "gmsh" (default) or "dolfinx", which builds a structured mesh (the same
            vertices and face tags; the blocks are cut into other tetrahedra).

    Returns:
        The BoxMesh.

    Raises:
        ValueError: unless exactly one of n and h is given, or for an unknown engine.
    """
    if (n is None) == (h is None):
        raise ValueError("give exactly one of n (structured) or h (unstructured)")
    if engine not in ("dolfinx", "gmsh"):
        raise ValueError(f"engine must be 'dolfinx' or 'gmsh', got {engine!r}")
    L = (float(L1), float(L2), float(L3))
    if n is not None and engine == "dolfinx":
        msh, ct, ft = dolfinx_structured(comm, L, n)
    else:
        s = max(L)      # gmsh sees the box scaled to unit size (its tolerances are absolute)
        args = (tuple(x / s for x in L), n, None if h is None else h / s)
        msh, ct, ft = gmsh_mesh(comm, 3, lambda: _gmsh_model(*args), s,
                                cache_key("box", args, Path(__file__)))
        if n is not None:
            snap_to_grid(msh, L, n)
    h_min, _, bbox = mesh_extent(msh)
    return BoxMesh(msh, ct, ft, L[0], L[1], n is not None, n,
                   h if n is None else max(L) / n, None, L[2], h_min, bbox)
