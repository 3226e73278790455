"""Cache of run histories (u, sigma, kappa on the structured grid at every step) in HDF5.

The key is a hash of everything that determines the discrete solution: the validated case
(physics, mesh, time grid, solver settings, PETSc options) and a format version; the case's
name, description and output settings do not count.  Files are written atomically.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

FORMAT_VERSION = 1
IGNORED = ("name", "description", "output")


def default_cache_dir() -> Path:
    return Path(os.environ.get("VPCONTACT_CACHE", Path.home() / ".cache" / "vpcontact"))


def cache_key(case) -> str:
    content = {k: v for k, v in case.raw.items() if k not in IGNORED}
    content["petsc"] = case.petsc
    text = json.dumps({"version": FORMAT_VERSION, "case": content}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def save(path: Path, times: list, snaps: list[dict], meta: dict) -> None:
    import h5py

    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    with h5py.File(tmp, "w") as f:
        f.attrs["meta"] = json.dumps(meta)
        f["times"] = np.asarray(times)
        for name in ("u", "sigma", "kappa"):
            f.create_dataset(name, data=np.stack([s[name] for s in snaps]))
    os.replace(tmp, path)


def load(path: Path) -> tuple[np.ndarray, list[dict], dict]:
    import h5py

    with h5py.File(path, "r") as f:
        meta = json.loads(f.attrs["meta"])
        times = f["times"][...]
        arrays = {name: f[name][...] for name in ("u", "sigma", "kappa")}
    snaps = [{name: arrays[name][i] for name in arrays} for i in range(len(times))]
    return times, snaps, meta
