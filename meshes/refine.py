"""Uniform refinement of the user's gmsh mesh: nested meshes for the convergence study.

Each refinement splits every triangle into 4 and every tetrahedron into 8 by the midpoints
of its edges (the "red" refinement; a tetrahedron's inner octahedron is cut along its
shortest diagonal), so a coarse P1 function is a fine P1 function and every fine cell lies in
one coarse cell.  New vertices stay on the straight edges: a curved boundary keeps the
polygon of the mesh that was refined (refining is not re-meshing, which would not nest).
The physical groups of dimension dim (the body) and dim - 1 (the boundary parts) are carried
over: a child cell or facet keeps its parent's tag, and the groups keep their names.

Numbering of level r + 1: the vertices of level r first (same order), then one vertex per
edge of level r (``midpoints``: the two level-r vertices of that edge); the children of cell
c are the cells ``k c, ..., k c + k - 1`` (k = 4 in 2D, 8 in 3D).  So P1 values prolong by
appending edge averages and DG0 values by repeating each value k times (``prolong_p1``,
``prolong_dg0``).

Gmsh runs on rank 0 only; ``write_msh`` saves a level as a ``.msh`` (format 4.1) that
``meshes.gmshfile.load_mesh_file`` reads, with node tags 1..N in this numbering (so
dolfinx's input indices of the geometry nodes are the level's vertex indices).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .gmshfile import MeshFileError, _read, file_failure, on_root

_LINEAR = {1: 1, 2: 2, 3: 4}          # gmsh element type of the linear simplex of each dim
# the triangle (a, b, c) with edge midpoints (ab, bc, ca) -> 4 triangles, as local indices of
# (a, b, c, ab, bc, ca)
_TRIANGLE = np.array([[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]])
# the tetrahedron's edges (local vertex pairs) and its 4 corner children, as local indices of
# (v0, v1, v2, v3, m01, m02, m03, m12, m13, m23)
_TET_EDGES = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
_TET_CORNERS = np.array([[0, 4, 5, 6], [4, 1, 7, 8], [5, 7, 2, 9], [6, 8, 9, 3]])


@dataclass
class MeshLevel:
    """One mesh of a nested hierarchy (rank 0 only).

    Attributes:
        x: (nv, dim) vertex coordinates.
        cells: (nc, dim + 1) vertex indices of the cells (triangles or tetrahedra).
        cell_tags: (nc,) the physical tag of each cell (a body group).
        facets: (nf, dim) vertex indices of the tagged facets (the boundary parts).
        facet_tags: (nf,) the physical tag of each facet.
        names: {(dimension, tag): name} of the named physical groups.
        midpoints: (nv - nv_parent, 2) the parent level's vertices of each new vertex (the
            ends of the edge it halves), or None on the first level.
        level: the number of refinements of the first level.
    """

    x: np.ndarray
    cells: np.ndarray
    cell_tags: np.ndarray
    facets: np.ndarray
    facet_tags: np.ndarray
    names: dict = field(default_factory=dict)
    midpoints: np.ndarray | None = None
    level: int = 0

    @property
    def dim(self) -> int:
        """The space dimension (2 or 3)."""
        return self.x.shape[1]

    @property
    def children(self) -> int:
        """Children per cell at each refinement: 4 (triangles) or 8 (tetrahedra)."""
        return 4 if self.dim == 2 else 8

    def diameter(self) -> float:
        """The largest cell diameter (longest edge).

        Returns:
            h_max of the level.
        """
        pts = self.x[self.cells]
        d = self.dim + 1
        return float(max(np.linalg.norm(pts[:, i] - pts[:, j], axis=1).max()
                         for i in range(d) for j in range(i + 1, d)))


# ----------------------------------------------------------------------------- refinement
def _edges(cells: np.ndarray, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """(unique edges (ne, 2) sorted within rows, per cell its edges' indices (nc, 3 or 6))."""
    pairs = [(0, 1), (1, 2), (2, 0)] if dim == 2 else _TET_EDGES
    ends = np.stack([np.sort(cells[:, [a, b]], axis=1) for a, b in pairs], axis=1)
    edges, inverse = np.unique(ends.reshape(-1, 2), axis=0, return_inverse=True)
    return edges, inverse.reshape(len(cells), len(pairs))


def _edge_lookup(edges: np.ndarray, nv: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The indices in ``edges`` (sorted rows, as from np.unique) of the edges (a, b)."""
    keys = edges[:, 0] * nv + edges[:, 1]
    query = np.minimum(a, b) * nv + np.maximum(a, b)
    pos = np.minimum(np.searchsorted(keys, query), len(keys) - 1)
    if len(keys) == 0 or np.any(keys[pos] != query):
        raise MeshFileError("a tagged facet is not made of edges of the body's cells; every "
                            "boundary group must lie on the body's mesh")
    return pos


def _split_tets(local: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The 8 children of each tetrahedron from its 10 local vertices (nc, 10) -> (nc, 8, 4):
    4 corners and the inner octahedron cut along its shortest diagonal."""
    mids = local[:, 4:]                                       # m01 m02 m03 m12 m13 m23
    # the diagonals (m01, m23), (m02, m13), (m03, m12): opposite midpoints
    diag = [(0, 5), (1, 4), (2, 3)]
    length = np.stack([np.linalg.norm(x[mids[:, a]] - x[mids[:, b]], axis=1)
                       for a, b in diag], axis=1)
    choice = np.argmin(length, axis=1)
    # for each diagonal, the other 4 midpoints in cyclic order (neighbours share a vertex)
    rings = {0: (1, 2, 4, 3), 1: (0, 2, 5, 3), 2: (0, 1, 5, 4)}
    out = np.empty((len(local), 8, 4), dtype=local.dtype)
    out[:, :4] = local[:, _TET_CORNERS]
    for c, (a, b) in enumerate(diag):
        sel = choice == c
        ring = rings[c]
        for k in range(4):
            out[sel, 4 + k] = mids[sel][:, [a, b, ring[k], ring[(k + 1) % 4]]]
    return out


def refine(level: MeshLevel) -> MeshLevel:
    """One uniform refinement (triangles into 4, tetrahedra into 8, facets alike).

    Args:
        level: the mesh to refine.

    Returns:
        The refined MeshLevel (numbering in the module docstring).

    Raises:
        MeshFileError: a tagged facet does not lie on the cells' edges.
    """
    dim, nv = level.dim, len(level.x)
    edges, cell_edges = _edges(level.cells, dim)
    x = np.vstack([level.x, 0.5 * (level.x[edges[:, 0]] + level.x[edges[:, 1]])])
    local = np.concatenate([level.cells, nv + cell_edges], axis=1)
    if dim == 2:
        cells = local[:, _TRIANGLE].reshape(-1, 3)
    else:
        cells = _split_tets(local, x).reshape(-1, 4)
    facets, ftags = _refine_facets(level.facets, level.facet_tags, edges, nv, dim)
    return MeshLevel(x, cells, np.repeat(level.cell_tags, level.children), facets, ftags,
                     dict(level.names), edges, level.level + 1)


def level_vertices(level: MeshLevel, levels: int) -> list[int]:
    """The vertex counts of a mesh refined 0, 1, ..., ``levels`` times, without refining:
    each refinement adds a vertex per edge, and the edges, faces and cells of the next
    level follow from this level's (V' = V + E; 2D: E' = 2E + 3F, F' = 4F; 3D: E' = 2E + 3F
    + T (one inner diagonal per tetrahedron), F' = 4F + 8T, T' = 8T).

    Args:
        level: the mesh read (level 0).
        levels: the number of refinements.

    Returns:
        The ``levels + 1`` vertex counts (exact; Python integers, however many levels).
    """
    V, E = len(level.x), len(_edges(level.cells, level.dim)[0])
    out = [V]
    if level.dim == 2:
        F = len(level.cells)
        for _ in range(levels):
            V, E, F = V + E, 2 * E + 3 * F, 4 * F
            out.append(V)
        return out
    T = len(level.cells)
    faces = np.sort(level.cells[:, [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]], axis=2)
    F = len(np.unique(faces.reshape(-1, 3), axis=0))
    for _ in range(levels):
        V, E, F, T = V + E, 2 * E + 3 * F + T, 4 * F + 8 * T, 8 * T
        out.append(V)
    return out


def _refine_facets(facets, tags, edges, nv: int, dim: int):
    """Split the tagged facets like the cells: a segment into 2, a triangle into 4."""
    if len(facets) == 0:
        return facets.copy(), tags.copy()
    if dim == 2:
        m = nv + _edge_lookup(edges, nv, facets[:, 0], facets[:, 1])
        out = np.stack([np.column_stack([facets[:, 0], m]), np.column_stack([m, facets[:, 1]])],
                       axis=1)
        return out.reshape(-1, 2), np.repeat(tags, 2)
    a, b, c = facets.T
    local = np.column_stack([facets, nv + _edge_lookup(edges, nv, a, b),
                             nv + _edge_lookup(edges, nv, b, c),
                             nv + _edge_lookup(edges, nv, c, a)])
    return local[:, _TRIANGLE].reshape(-1, 3), np.repeat(tags, 4)


def prolong_p1(values: np.ndarray, levels: list[MeshLevel], start: int, stop: int) -> np.ndarray:
    """Prolong vertex values (a P1 field) from level ``start`` to level ``stop`` (exact).

    Args:
        values: (nv of level start, ...) vertex values.
        levels: the hierarchy, levels[r] refined r times.
        start: the coarse level.
        stop: the fine level (>= start).

    Returns:
        (nv of level stop, ...) the same P1 function's vertex values on the fine level.
    """
    for r in range(start + 1, stop + 1):
        mid = levels[r].midpoints
        values = np.concatenate([values, 0.5 * (values[mid[:, 0]] + values[mid[:, 1]])])
    return values


def prolong_dg0(values: np.ndarray, levels: list[MeshLevel], start: int,
                stop: int) -> np.ndarray:
    """Prolong cell values (a DG0 field) from level ``start`` to level ``stop`` (exact).

    Args:
        values: (nc of level start, ...) cell values.
        levels: the hierarchy.
        start: the coarse level.
        stop: the fine level (>= start).

    Returns:
        (nc of level stop, ...): each fine cell takes its ancestor's value.
    """
    k = levels[start].children ** (stop - start)
    return np.repeat(values, k, axis=0)


# ----------------------------------------------------------------------------- gmsh files
def read_level(gmsh, path, dim: int, size: float = 1.0) -> MeshLevel:
    """Rank 0: read (or mesh) a gmsh file with gmsh's API and return it as level 0.

    Only the elements of the physical groups of dimension dim and dim - 1 are kept (what
    dolfinx reads); vertices no cell uses are dropped.

    Args:
        gmsh: the gmsh module, initialised.
        path: the .msh or .geo file.
        dim: the space dimension.
        size: the factor on a .geo's characteristic lengths.

    Returns:
        The MeshLevel.

    Raises:
        MeshFileError: the file cannot be used (see load_mesh_file), or a tagged facet has a
            vertex no cell has.
    """
    _read(gmsh, str(path), dim, size)
    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    index = np.full(int(node_tags.max()) + 1, -1, dtype=np.int64)
    index[node_tags.astype(np.int64)] = np.arange(len(node_tags))
    xyz = coords.reshape(-1, 3)
    found = {}
    names = {}
    for d in (dim, dim - 1):
        blocks, tags = [], []
        for _, tag in gmsh.model.getPhysicalGroups(d):
            name = gmsh.model.getPhysicalName(d, tag)
            if name:
                names[(d, int(tag))] = name
            for entity in gmsh.model.getEntitiesForPhysicalGroup(d, tag):
                types, _, nodes = gmsh.model.mesh.getElements(d, entity)
                if len(types):
                    blocks.append(index[nodes[0].astype(np.int64)].reshape(-1, d + 1))
                    tags.append(np.full(len(blocks[-1]), int(tag)))
        found[d] = (np.concatenate(blocks) if blocks else np.zeros((0, d + 1), np.int64),
                    np.concatenate(tags) if tags else np.zeros(0, np.int64))
    cells, cell_tags = found[dim]
    facets, facet_tags = found[dim - 1]
    used, compact = np.unique(cells, return_inverse=True)
    renumber = np.full(len(node_tags), -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    facets = renumber[facets]
    if np.any(facets < 0):
        raise MeshFileError(f"{path}: a boundary group has a facet with a vertex that no cell "
                            "of the body has; every boundary group must lie on the body")
    return MeshLevel(xyz[used, :dim].copy(), compact.reshape(cells.shape), cell_tags, facets,
                     facet_tags, names)


def write_msh(gmsh, level: MeshLevel, path) -> None:
    """Rank 0: save a level as a binary gmsh .msh 4.1: node tags 1..nv in the level's order,
    one discrete entity per physical group, the groups' tags and names.

    Args:
        gmsh: the gmsh module, initialised.
        level: the mesh.
        path: the file to write (replaced).
    """
    dim = level.dim
    gmsh.model.add(f"level{level.level}")
    xyz = np.zeros((len(level.x), 3))
    xyz[:, :dim] = level.x
    entity = 0
    for d, elements, tags in ((dim, level.cells, level.cell_tags),
                              (dim - 1, level.facets, level.facet_tags)):
        for tag in np.unique(tags):
            entity += 1
            gmsh.model.addDiscreteEntity(d, entity)
            if entity == 1:      # every node on the first body entity
                gmsh.model.mesh.addNodes(dim, 1, np.arange(1, len(xyz) + 1), xyz.ravel())
            sel = np.flatnonzero(tags == tag)
            first = 1 + (0 if d == dim else len(level.cells))
            gmsh.model.mesh.addElementsByType(entity, _LINEAR[d], first + sel,
                                              (elements[sel] + 1).ravel())
            gmsh.model.addPhysicalGroup(d, [entity], int(tag))
            if (d, int(tag)) in level.names:
                gmsh.model.setPhysicalName(d, int(tag), level.names[(d, int(tag))])
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 1)
    gmsh.option.setNumber("Mesh.SaveAll", 0)
    gmsh.write(str(path))
    gmsh.model.remove()


# refine_file's peak memory per vertex of the finest level [bytes] (peak RSS: the hierarchy,
# the edge search and gmsh's copy written as .msh), with a margin over what it was found to
# be (docs/performance.md, section 9)
REFINE_BYTES = {2: 700, 3: 2000}


def available_memory() -> float | None:
    """The memory this machine can still give [bytes] (MemAvailable), or None if unknown.

    Returns:
        /proc/meminfo's MemAvailable in bytes, or None (no /proc, or no such line).
    """
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def too_large(vertices: list[int], dim: int, max_vertices: float,
              memory: float | None) -> tuple[int, str] | None:
    """The first level of a hierarchy over the vertex limit, or that cannot be refined in
    the memory there is.

    Args:
        vertices: the vertex counts of the levels (``level_vertices``).
        dim: the space dimension.
        max_vertices: the most vertices a level may have.
        memory: the memory available [bytes], or None (not checked).

    Returns:
        (the level, why: "would have ... vertices (limit ...)" or "would need about ... GB
        of memory to refine (... GB available)"), or None if every level fits.
    """
    for r, v in enumerate(vertices):
        if v > max_vertices:
            return r, f"would have {v:.3g} vertices (limit {max_vertices:.0e})"
        need = REFINE_BYTES[dim] * v
        if memory is not None and need > memory:
            return r, (f"would need about {need / 1e9:.3g} GB of memory to refine "
                       f"({memory / 1e9:.3g} GB available)")
    return None


def check_level_sizes(path, vertices: list[int], dim: int, max_vertices: float) -> None:
    """Refuse a hierarchy whose finest level would be too large, before refining.

    Args:
        path: the mesh file, for the message.
        vertices: the vertex counts of the levels (``level_vertices``).
        dim: the space dimension.
        max_vertices: the most vertices a level may have.

    Raises:
        MeshFileError: naming the first level over the limits (``too_large``) and the most
            refinements allowed.
    """
    over = too_large(vertices, dim, max_vertices, available_memory())
    if over:
        r, why = over
        raise MeshFileError(f"{path} refined {r} times {why}; allowed: at most {r - 1} "
                            "refinements of this mesh, or a coarser mesh")


def read_sizes(comm, path, dim: int, size: float, levels: int) -> list[int]:
    """The vertex counts of the user's gmsh file refined 0..``levels`` times, from the mesh
    read (or meshed) once, without refining it; collective, gmsh on rank 0.

    Args:
        comm: the MPI communicator.
        path: the .msh or .geo file.
        dim: the space dimension.
        size: the factor on a .geo's characteristic lengths.
        levels: the number of refinements.

    Returns:
        The ``levels + 1`` vertex counts, on every rank.

    Raises:
        MeshFileError: on every rank, if the file cannot be used.
    """
    return on_root(comm, lambda gmsh: level_vertices(read_level(gmsh, path, dim, size), levels),
                   file_failure(path, "read"))


def refine_file(comm, path, dim: int, size: float, levels: int, out_dir,
                max_vertices: float = float("inf")) -> tuple[list[Path], list[MeshLevel] | None]:
    """Read (or mesh) the user's gmsh file once, refine it ``levels`` times and save every
    level as ``out_dir/level<r>.msh``; collective, gmsh on rank 0.

    Args:
        comm: the MPI communicator.
        path: the .msh or .geo file.
        dim: the space dimension.
        size: the factor on a .geo's characteristic lengths.
        levels: the number of refinements (level 0 is the file's own mesh).
        out_dir: the directory of the level files (on rank 0's file system).
        max_vertices: the most vertices a level may have.

    Returns:
        (the level files, on every rank; the MeshLevels on rank 0, None elsewhere).

    Raises:
        MeshFileError: on every rank, if the file cannot be used or refined, or a level
            would have more than ``max_vertices`` vertices (found before refining).
    """
    def work(gmsh):
        out = [read_level(gmsh, path, dim, size)]
        check_level_sizes(path, level_vertices(out[0], levels), dim, max_vertices)
        for _ in range(levels):
            out.append(refine(out[-1]))
        Path(out_dir).mkdir(parents=True, exist_ok=True)
        for level in out:
            write_msh(gmsh, level, Path(out_dir) / f"level{level.level}.msh")
        return out

    out = on_root(comm, work, file_failure(path, "refine"), share=False)
    return [Path(out_dir) / f"level{r}.msh" for r in range(levels + 1)], out
