"""The ``mesh`` section's rules on the data as given: the keys that do not apply (the
built-in mesh's keys with mesh.file, mesh.size without a .geo, material.plane in 3D), the
mesh file (a readable .msh or .geo, its dimension against mesh.dim), the defaults that
depend on the mesh (boundaries), and the built-in mesh's size and shape.  The rules that
need the loaded mesh run when it is loaded (app/case/values.py, app/model/datapoints.py)."""
from __future__ import annotations

import math
import os
from pathlib import Path

from vpcontact.case.materialrules import material_sections
from vpcontact.io.errors import CaseError

MAX_VERTICES = 1e8           # a mesh larger than this is refused before any computation
MIN_LENGTH, MAX_LENGTH = 1e-30, 1e30   # a side length outside this range is degenerate [m]
MAX_ASPECT = 1e6            # largest ratio of two side lengths
MESH_SUFFIXES = (".msh", ".geo")
# the built-in mesh's keys, not used with mesh.file
BUILTIN_MESH_KEYS = ("L1", "L2", "L3", "kind", "n", "h", "diagonal", "engine")
DEFAULT_BOUNDARIES = {"clamped": ["left"], "contact": ["bottom"]}     # built-in meshes


def check_given(data: dict, source: str) -> Path | None:
    """The keys the user gave (before defaults are filled) that do not apply: the built-in
    mesh's keys with mesh.file, mesh.size without a .geo, material.plane in 3D; mesh.dim of
    a mesh.file: taken from the file when not given (written into ``data``), else refused
    if the file contradicts it (a .msh 4 file is read at once; a .geo only when the case's
    vectors disagree with mesh.dim: meshing it tells the rest).

    Args:
        data: the case mapping as given (after the schema's check).
        source: the case file, for messages; mesh.file is relative to its directory.

    Returns:
        The mesh file's absolute path, or None for the built-in mesh.

    Raises:
        CaseError: for a key that does not apply, or a mesh file that is missing, of
            another kind or of another dimension.
    """
    mesh = data["mesh"]
    path = None
    if "file" not in mesh and "size" in mesh:
        raise CaseError(f"{source}: mesh.size: only with a .geo mesh.file (the built-in "
                        "mesh's cells are set by mesh.n or mesh.h)")
    if "file" in mesh:
        given = [k for k in BUILTIN_MESH_KEYS if k in mesh]
        if given:
            raise CaseError(f"{source}: mesh.{given[0]}: not used with mesh.file (the "
                            f"built-in mesh's keys {', '.join(BUILTIN_MESH_KEYS)} are not "
                            "used with a gmsh file)")
        path = _mesh_path(mesh["file"], source)
        if "size" in mesh and path.suffix.lower() != ".geo":
            raise CaseError(f"{source}: mesh.size: only with a .geo mesh.file (a .msh is "
                            "meshed already)")
        if "dim" in mesh:
            check_file_dimension(mesh["dim"], path, source, cheap=True)
        else:
            mesh["dim"] = _file_dimension(path, source)
    for key, section in material_sections(data):
        if mesh.get("dim", 2) == 3 and "plane" in section:
            raise CaseError(f"{source}: {key}.plane: not used in 3D (plane stress and plane "
                            "strain are the 2D models; a 3D body is a solid)")
    return path


def _file_dimension(path: Path, source: str, cheap: bool = False) -> int | None:
    """The dimension of the mesh file (meshes/fileinfo.py; None if ``cheap`` and gmsh would
    be needed)."""
    from vpcontact.meshes.fileinfo import FileInfoError, file_dimension
    try:
        return file_dimension(path, cheap)
    except FileInfoError as exc:
        raise CaseError(f"{source}: mesh.file: {exc}") from None


def check_file_dimension(dim: int, path: Path, source: str, cheap: bool = False) -> None:
    """Refuse a mesh.dim that contradicts the mesh file; a file whose dimension cannot be
    told is left to the mesh's loading, which says what is wrong with it.

    Args:
        dim: mesh.dim as given.
        path: the mesh file.
        source: the case file, for messages.
        cheap: only if the file tells its dimension without gmsh.

    Raises:
        CaseError: if the file's dimension is another.
    """
    from vpcontact.meshes.fileinfo import FileInfoError, file_dimension
    try:
        found = file_dimension(path, cheap)
    except FileInfoError:
        return
    if found is not None and found != dim:
        what = "tetrahedra, a solid" if found == 3 else "triangles in a plane"
        raise CaseError(f"{source}: mesh.dim: {dim} contradicts mesh.file {path.name}, which "
                        f"is {found}D ({what}); give {found} or leave the key out (the file's "
                        "dimension is taken)")


def _mesh_path(file: str, source: str) -> Path:
    """mesh.file relative to the case file's directory: a .msh or .geo regular file."""
    if Path(file).suffix.lower() not in MESH_SUFFIXES:
        raise CaseError(f"{source}: mesh.file: {file!r} is not a gmsh mesh or geometry file "
                        f"(allowed: a file ending in {' or '.join(MESH_SUFFIXES)})")
    path = Path(os.path.abspath(Path(source).parent / file))   # an absolute file stays
    try:
        found = path.is_file() and os.access(path, os.R_OK)
        exists = found or path.exists()
    except (OSError, ValueError):        # e.g. a NUL character or a name too long
        found = exists = False
    if not found:
        why = "not a readable regular file" if exists else "no such file"
        raise CaseError(f"{source}: mesh.file: {file!r}: {why} (looked for {path}; a relative "
                        "path is relative to the case file's directory)")
    return path


def settle_defaults(data: dict, mesh_file: Path | None) -> None:
    """After the schema's defaults are filled: drop the defaults that do not apply (the
    built-in mesh's keys and mesh.engine with mesh.file, mesh.size without a .geo,
    material.plane in 3D), make mesh.file absolute, fill boundaries (built-in mesh: clamped
    [left], contact [bottom]; mesh.file: []) and write physical tags as integers.  The
    result validates to the same case again (the studies validate case.raw with changed
    keys).

    Args:
        data: the default-filled case mapping (changed in place).
        mesh_file: the mesh file's absolute path (``check_given``), or None.
    """
    mesh = data["mesh"]
    if mesh_file is not None:
        for key in BUILTIN_MESH_KEYS:
            mesh.pop(key, None)
        mesh["file"] = str(mesh_file)
    if mesh_file is None or mesh_file.suffix.lower() != ".geo":
        mesh.pop("size", None)
    if mesh["dim"] == 3:
        for _, section in material_sections(data):
            section.pop("plane", None)
    bounds = data.setdefault("boundaries", {})
    for role, default in DEFAULT_BOUNDARIES.items():
        refs = bounds.get(role, default if mesh_file is None else [])
        bounds[role] = [r if isinstance(r, str) else int(r) for r in refs]


def check_mesh(mesh: dict, source: str) -> None:
    """The built-in mesh: its size within MAX_VERTICES; lengths neither degenerate nor too
    flat.

    Args:
        mesh: the default-filled ``mesh`` section of a built-in mesh.
        source: the case file, for messages.

    Raises:
        CaseError: for a missing h, a degenerate or too thin side, or too many vertices.
    """
    dim = mesh["dim"]
    if mesh["kind"] == "unstructured" and "h" not in mesh:
        raise CaseError(f"{source}: mesh.h: required when mesh.kind is 'unstructured'")
    lengths = [mesh["L1"], mesh["L2"], mesh["L3"]][:dim]
    for i, L in enumerate(lengths):
        if not MIN_LENGTH <= L <= MAX_LENGTH:
            raise CaseError(f"{source}: mesh.L{i + 1}: {L:g} m is a degenerate length "
                            f"(allowed: {MIN_LENGTH:g} to {MAX_LENGTH:g})")
    if max(lengths) > MAX_ASPECT * min(lengths):
        i = lengths.index(min(lengths))
        raise CaseError(f"{source}: mesh.L{i + 1}: {lengths[i]:g} m is too thin next to "
                        f"{max(lengths):g} m (allowed: side ratios up to {MAX_ASPECT:g})")
    if mesh["kind"] == "structured":
        vertices, key = float(mesh["n"] + 1) ** dim, "mesh.n"
    else:
        vertices, key = math.prod(L / mesh["h"] + 1 for L in lengths), "mesh.h"
    if vertices > MAX_VERTICES:
        raise CaseError(f"{source}: {key}: the mesh would have about {vertices:.3g} vertices "
                        f"(limit {MAX_VERTICES:.0e}); use a coarser mesh")

