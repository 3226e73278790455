"""The space dimension of a gmsh file, known before the mesh is loaded (the case needs it to
check its vectors' lengths).

A ``.msh`` of format 4 (ASCII or binary) says it in its ``$Entities`` section, which gmsh
writes near the top: the numbers of points, curves, surfaces and volumes; the dimension is
that of the highest kind present.  It is read here without gmsh.  Any other file (a ``.geo``,
whose geometry exists only once gmsh has run the script, or a ``.msh`` of format 2) is
scanned first (meshes/geoscan.py: nothing a case may not do) and opened by gmsh in a child
process (``python meshes/geomesh.py --dimension``: it dies with its parent and may add at
most half the machine's memory), which prints ``gmsh.model.getDimension()``: the script
runs out of this process, and SIGINT/SIGTERM stop it at once (the child is killed,
KeyboardInterrupt raised again).
Answers are kept per file (path, size and modification time).
"""
from __future__ import annotations

import struct
from pathlib import Path

from .geomesh import memory_budget, refusal, run_child
from .geoscan import GeoScanError, mesh_files

_HEADER_LINES = 10_000            # lines read before $Entities (the physical names)
_cache: dict = {}


class FileInfoError(ValueError):
    """A gmsh file whose dimension cannot be told; the one-line message says why."""


def file_dimension(path, cheap: bool = False) -> int | None:
    """The space dimension of the mesh or geometry in a gmsh file.

    Args:
        path: a .msh or .geo file.
        cheap: only what can be read without gmsh (a .msh of format 4); None otherwise.

    Returns:
        2 or 3 (None when ``cheap`` and gmsh would be needed).

    Raises:
        FileInfoError: the file cannot be read, gmsh cannot open it, or it holds neither
            surfaces nor volumes.
        KeyboardInterrupt: SIGINT/SIGTERM while gmsh runs (the child is killed).
    """
    p = Path(path)
    try:
        st = p.stat()
    except OSError as err:
        raise FileInfoError(f"cannot read {p}: {err.strerror}") from None
    key = (str(p.resolve()), st.st_size, st.st_mtime_ns)
    if key not in _cache:
        dim = _msh4_dimension(p) if p.suffix.lower() == ".msh" else None
        if dim is None and cheap:
            return None
        if dim is None:
            dim = _gmsh_dimension(p)
        if dim not in (2, 3):
            raise FileInfoError(f"{p} holds no surface or volume (its highest entities have "
                                f"dimension {dim}); give a 2D or 3D gmsh mesh or geometry")
        _cache[key] = dim
    return _cache[key]


def _msh4_dimension(p: Path) -> int | None:
    """The highest dimension with entities in a .msh 4 file's $Entities; None for another
    format or a file without that section."""
    try:
        with open(p, "rb") as f:
            if f.readline().strip() != b"$MeshFormat":
                return None
            head = f.readline().split()
            if len(head) < 3 or not head[0].startswith(b"4"):
                return None
            binary, size = head[1] == b"1", int(head[2])
            order = "<"
            if binary:
                order = "<" if struct.unpack("<i", f.read(4))[0] == 1 else ">"
            for _ in range(_HEADER_LINES):
                line = f.readline()
                if not line or line.strip() in (b"$Nodes", b"$Elements"):
                    return None
                if line.strip() == b"$Entities":
                    break
            else:
                return None
            if binary:
                fmt = {4: "i", 8: "q"}.get(size)
                counts = struct.unpack(f"{order}4{fmt}", f.read(4 * size)) if fmt else ()
            else:
                counts = tuple(int(c) for c in f.readline().split()[:4])
    except (OSError, ValueError, struct.error):
        return None
    if len(counts) != 4:
        return None
    return max((d for d, c in enumerate(counts) if c > 0), default=-1)


def _gmsh_dimension(p: Path) -> int:
    """gmsh.model.getDimension() of the file opened by gmsh in a child process, after the
    scan of every script it makes gmsh read."""
    try:
        mesh_files(p)
    except GeoScanError as err:
        raise FileInfoError(str(err)) from None
    code, out, err = run_child(["--dimension", str(p)], memory_budget())
    lines = out.split()
    if code != 0 or not lines or not lines[-1].lstrip("-").isdigit():
        said = refusal(err) or next((ln for ln in reversed(err.splitlines()) if ln.strip()),
                                    f"exit status {code}")
        raise FileInfoError(f"gmsh cannot read {p}: {said}")
    return int(lines[-1])
