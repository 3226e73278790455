"""The native libraries this process has loaded, for the few C calls the Python bindings do
not wrap (PETSc's raw matrix arrays in app/solvers/levels.py, HDF5's error stack and
termination in app/io/output.py)."""
from __future__ import annotations

from pathlib import Path


def loaded_libraries(prefix: str) -> list[str]:
    """The paths of the loaded shared libraries whose file name starts with ``prefix``
    (read from /proc/self/maps).

    Args:
        prefix: the start of the file name, e.g. "libpetsc".

    Returns:
        The absolute paths, sorted; none where the memory map cannot be read.
    """
    try:
        maps = Path("/proc/self/maps").read_text()
    except OSError:
        return []
    paths = {line.split()[-1] for line in maps.splitlines() if "/" in line}
    return sorted(p for p in paths if p.startswith("/") and Path(p).name.startswith(prefix))
