"""Checks of a gmsh mesh's body and boundary groups before dolfinx reads it (rank 0).

- Every element of a boundary group (dimension dim - 1) must be a facet of a body cell:
  dolfinx's ``gmshio.model_to_mesh`` dies with a segmentation fault on a facet that is not
  (a Physical Curve on a curve outside the body's Physical Surface).
- A facet of a boundary group shared by two body cells lies inside the body (an embedded
  curve or surface): it may be a group, but not a boundary part of the problem (Gamma1,
  Gamma2, Gamma3 are parts of the boundary): ``interior_role`` names such a use.
- Every cell must have a measure: a cell of zero (or, relative to its longest edge, about
  rounding-error) area or volume makes the strain-displacement map singular, and the run
  would fail later at sigma_0 with a message about the stress.
"""
from __future__ import annotations

import math

import numpy as np

_PHYSICAL = {0: "Physical Point", 1: "Physical Curve", 2: "Physical Surface", 3: "Physical Volume"}
DEGENERATE = 1e-10        # a cell's measure d! |K| / (longest edge)^d below this is refused


class BodyError(ValueError):
    """A mesh whose groups or cells cannot be used; the message is one line."""


def _elements(gmsh, d: int) -> tuple[np.ndarray, np.ndarray]:
    """(node tags (n, d + 1), physical tag of each) of the groups of dimension d."""
    blocks, owners = [], []
    for _, tag in gmsh.model.getPhysicalGroups(d):
        for entity in gmsh.model.getEntitiesForPhysicalGroup(d, tag):
            types, _, nodes = gmsh.model.mesh.getElements(d, entity)
            if len(types):
                blocks.append(np.asarray(nodes[0], dtype=np.int64).reshape(-1, d + 1))
                owners.append(np.full(len(blocks[-1]), int(tag)))
    if not blocks:
        return np.zeros((0, d + 1), np.int64), np.zeros(0, np.int64)
    return np.concatenate(blocks), np.concatenate(owners)


def _label(gmsh, d: int, tag: int) -> str:
    name = gmsh.model.getPhysicalName(d, tag)
    return f"{_PHYSICAL[d]} {tag} ({name!r})" if name else f"{_PHYSICAL[d]} {tag}"


def check_body(gmsh, path: str, dim: int) -> dict[int, tuple[int, int]]:
    """The three checks of the module docstring, on the body's cells read once from gmsh.

    Args:
        gmsh: the gmsh module with the mesh loaded (linear simplices, checked before).
        path: the mesh file, for the message.
        dim: the space dimension.

    Returns:
        check_facets' {physical tag: (facets inside the body, facets)}.

    Raises:
        BodyError: the first check that fails.
    """
    cells, _ = _elements(gmsh, dim)
    interior = check_facets(gmsh, path, dim, cells)    # model_to_mesh segfaults otherwise
    check_lower_groups(gmsh, path, dim, cells)
    check_cells(gmsh, path, dim, cells)
    return interior


def check_facets(gmsh, path: str, dim: int, cells: np.ndarray) -> dict[int, tuple[int, int]]:
    """Every facet of a boundary group is a facet of a body cell (else BodyError).

    Args:
        gmsh: the gmsh module with the mesh loaded (linear simplices, checked before).
        path: the mesh file, for the message.
        dim: the space dimension.
        cells: the body's cells, node tags (n, dim + 1).

    Returns:
        {physical tag: (facets inside the body, facets)} of the groups of dimension dim - 1
        that have facets inside the body (shared by two cells).

    Raises:
        BodyError: a group has facets that are not facets of any body cell.
    """
    facets, owners = _elements(gmsh, dim - 1)
    if len(facets) == 0:
        return {}
    faces = np.concatenate([np.delete(cells, k, axis=1) for k in range(dim + 1)])
    both = np.sort(np.concatenate([faces, facets]), axis=1)
    _, inverse = np.unique(both, axis=0, return_inverse=True)
    inverse = inverse.ravel()
    cells_at = np.bincount(inverse[:len(faces)], minlength=int(inverse.max()) + 1)
    count = cells_at[inverse[len(faces):]]
    interior = {}
    for tag in np.unique(owners):
        mine = count[owners == tag]
        if np.any(mine == 0):
            raise BodyError(
                f"{path}: {_label(gmsh, dim - 1, int(tag))} has {int(np.sum(mine == 0))} of "
                f"its {len(mine)} elements outside the body (not a facet of any cell of the "
                f"{_PHYSICAL[dim]} groups); a boundary group must lie on the body: remove "
                "those entities from the group or add their cells to the body")
        if np.any(mine >= 2):
            interior[int(tag)] = (int(np.sum(mine >= 2)), len(mine))
    return interior


def check_lower_groups(gmsh, path: str, dim: int, cells: np.ndarray) -> None:
    """Every node of a physical group of dimension below dim - 1 (a Physical Point; a
    Physical Curve in 3D) is a vertex of a body cell: dolfinx's model_to_mesh reads these
    groups too, and dies with a segmentation fault on a point off the body.

    Args:
        gmsh: the gmsh module with the mesh loaded.
        path: the mesh file, for the message.
        dim: the space dimension.
        cells: the body's cells, node tags (n, dim + 1).

    Raises:
        BodyError: naming the first such group off the body.
    """
    used = np.unique(cells)
    for d in range(dim - 1):
        for _, tag in gmsh.model.getPhysicalGroups(d):
            nodes = [np.asarray(n[0], dtype=np.int64) for n in
                     (gmsh.model.mesh.getElements(d, e)[2]
                      for e in gmsh.model.getEntitiesForPhysicalGroup(d, tag)) if len(n)]
            nodes = np.unique(np.concatenate(nodes)) if nodes else np.zeros(0, np.int64)
            off = np.setdiff1d(nodes, used)
            if off.size:
                raise BodyError(f"{path}: {_label(gmsh, d, int(tag))} has {off.size} of its "
                                f"{nodes.size} nodes off the body (not a vertex of any body "
                                "cell); a group must lie on the body: remove it or those "
                                "entities from it")


def check_cells(gmsh, path: str, dim: int, cells: np.ndarray) -> None:
    """Every body cell has finite vertices and a measure (module docstring).

    Args:
        gmsh: the gmsh module with the mesh loaded.
        path: the mesh file, for the message.
        dim: the space dimension.
        cells: the body's cells, node tags (n, dim + 1).

    Raises:
        BodyError: naming the first degenerate cell and its vertices.
    """
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    where = np.zeros(int(np.max(tags)) + 1, dtype=np.int64)
    where[np.asarray(tags, dtype=np.int64)] = np.arange(len(tags))
    x = np.asarray(xyz).reshape(-1, 3)[:, :dim][where[cells]]        # (nc, dim + 1, dim)
    if not np.all(np.isfinite(x)):
        k = int(np.flatnonzero(~np.isfinite(x).all(axis=(1, 2)))[0])
        raise BodyError(f"{path}: cell {k + 1} has a vertex with a non-finite coordinate "
                        f"({_points(x[k])}); fix the mesh")
    edges = x[:, 1:] - x[:, :1]
    volume = np.abs(np.linalg.det(edges))                            # d! |K|
    pairs = [(i, j) for i in range(dim + 1) for j in range(i + 1, dim + 1)]
    longest = np.max([np.linalg.norm(x[:, i] - x[:, j], axis=1) for i, j in pairs], axis=0)
    ratio = volume / np.maximum(longest, np.finfo(float).tiny) ** dim
    bad = np.flatnonzero(~(ratio > DEGENERATE))
    if bad.size:
        k = int(bad[0])
        what = "area" if dim == 2 else "volume"
        raise BodyError(
            f"{path}: {bad.size} cell(s) have zero {what}, e.g. the cell with vertices "
            f"{_points(x[k])} ({what} {volume[k] / math.factorial(dim):.3g}, longest edge "
            f"{longest[k]:.3g}); a degenerate cell (vertices on one "
            f"{'line' if dim == 2 else 'plane'}) makes the strains undefined: fix the mesh")


def _points(x: np.ndarray) -> str:
    return ", ".join("(" + ", ".join(f"{v:.6g}" for v in p) + ")" for p in x)


def interior_role(body, key: str, ref, tag: int) -> str | None:
    """Why a boundary role cannot be given to a group, or None.

    Args:
        body: the mesh (a FileMesh has ``interior``; the built-in meshes have none).
        key: the case key giving the role (e.g. "boundaries.contact").
        ref: the group's name or number, as the case gives it.
        tag: its physical tag.

    Returns:
        A one-line reason naming the key, the group and its facets inside the body.
    """
    inside, total = getattr(body, "interior", {}).get(tag, (0, 0))
    if not inside:
        return None
    return (f"{key}: group {ref!r} has {inside} of its {total} facets inside the body "
            "(shared by two cells, e.g. an embedded curve or surface); a boundary condition, "
            "load or contact needs facets on the body's boundary")
