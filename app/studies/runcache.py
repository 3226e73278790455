"""Cache of run histories (u, sigma, kappa on the structured grid, or on a refined level of a
mesh.file, at every step) in HDF5.

The key is a hash of everything that determines the discrete solution: the validated case
(physics, mesh, time grid, solver settings, PETSc options) and a format version; the case's
name, description and output settings do not count, nor does the name of a mesh.file (its
content does: a study's refined levels live in temporary files); a python law's --law-module
file counts by its content.  Files are written
atomically, with the signals held back while they are written (an interrupted study keeps
every finished run whole); an entry that does not load (or does not fit its run) is
recomputed and written again.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

from vpcontact.io.canonical import stable_json
from vpcontact.io.checkpoint import law_module
from vpcontact.studies.interrupts import signals_held

FORMAT_VERSION = 1
IGNORED = ("name", "description", "output")


def default_cache_dir() -> Path:
    """The run cache of the convergence study.

    Returns:
        app/cachepaths.py's cache root (``CACHE_SEARCH``, or its replacement).
    """
    from vpcontact.cachepaths import cache_root
    return cache_root()


def cache_key(case) -> str:
    """The key of a run: a hash of what determines its discrete solution.

    Args:
        case: the validated case.

    Returns:
        24 hexadecimal digits of the SHA-256 of the case (without IGNORED; a mesh.file by
        its content; with a python law, the SHA-256 of its --law-module file) and
        FORMAT_VERSION.
    """
    content = {k: v for k, v in case.raw.items() if k not in IGNORED}
    content["petsc"] = case.petsc
    if case.mesh.file is not None:           # the scene is the file's content, not its name
        content["mesh"] = {k: v for k, v in content["mesh"].items() if k != "file"}
        content["mesh_file"] = hashlib.sha256(Path(case.mesh.file).read_bytes()).hexdigest()
    module = law_module(case)
    if module is not None:                   # a python law: its module's bytes count too
        content["law_module"] = module["sha256"]
    text = stable_json({"version": FORMAT_VERSION, "case": content})
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def save(path: Path, times: list, snaps: list[dict], meta: dict) -> None:
    """Write a run's history atomically (temporary file, then rename), with SIGINT and
    SIGTERM held back until it is written (interrupts.signals_held).

    Args:
        path: the HDF5 file.
        times: the time points.
        snaps: per time point, dict(u, sigma, kappa) of grid (or level) arrays.
        meta: the run's data (META_KEYS and more), stored as JSON.
    """
    import h5py

    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    with signals_held():              # a finished run is kept whole, then the signal acts
        try:
            with h5py.File(tmp, "w") as f:
                f.attrs["meta"] = json.dumps(meta)
                f["times"] = np.asarray(times)
                for name in ("u", "sigma", "kappa"):
                    f.create_dataset(name, data=np.stack([s[name] for s in snaps]))
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)


class Unreadable(Exception):
    """A cache entry that cannot be used: damaged, or not the run it is named after."""


META_KEYS = ("dofs", "solve_s", "setup_s", "newton")


def load(path: Path, times=None, shapes: dict | None = None) -> tuple[np.ndarray, list[dict], dict]:
    """Read a cached run.

    Args:
        path: the HDF5 file.
        times: the expected time points, or None.
        shapes: the expected per-step shapes of u, sigma, kappa, or None.

    Returns:
        (times, per-step dict(u, sigma, kappa), meta).

    Raises:
        Unreadable: if the file is damaged or does not fit ``times`` and ``shapes``.
    """
    import h5py

    try:
        with h5py.File(path, "r") as f:
            meta = json.loads(f.attrs["meta"])
            stored = f["times"][...]
            arrays = {name: f[name][...] for name in ("u", "sigma", "kappa")}
    except Exception as exc:                      # noqa: BLE001 (any damage)
        raise Unreadable(f"{type(exc).__name__}: {exc}") from None
    if not isinstance(meta, dict) or not all(
            isinstance(meta.get(k), (int, float)) for k in META_KEYS):
        raise Unreadable(f"meta is not a mapping with {', '.join(META_KEYS)}")
    if times is not None and (stored.shape != (len(times),) or not np.allclose(
            stored, times, rtol=1e-12, atol=0.0)):
        raise Unreadable("its time points are not the run's")
    for name, a in arrays.items():
        if a.dtype.kind != "f" or len(a) != len(stored) or not np.isfinite(a).all() \
                or (shapes is not None and a.shape[1:] != tuple(shapes[name])):
            raise Unreadable(f"'{name}' does not fit the run (shape {a.shape})")
    snaps = [{name: arrays[name][i] for name in arrays} for i in range(len(stored))]
    return stored, snaps, meta
