"""Outputs of a run: solution.xdmf (+ .h5), summary.json, contact.csv.

JSON and CSV are written atomically (temporary file + rename) by rank 0; the XDMF file is
written collectively, its mesh once and the fields at every output time.
"""
from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

import numpy as np
from dolfinx import io as dio

OUTPUT_FILES = ("solution.xdmf", "solution.h5", "summary.json", "contact.csv")
# 2D columns; in 3D z, u_z and two tangential components (u_tau1, u_tau2, neg_sigma_tau1,
# neg_sigma_tau2) appear, and xi (memory) / theta (slip dependence) when the case has them.
CONTACT_COLUMNS = ("x", "y", "u_x", "u_y", "u_nu", "u_tau", "neg_sigma_nu", "neg_sigma_tau",
                   "state")


def atomic_write(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename."""
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    with open(tmp, "w") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def write_json(comm, path: Path, data: dict) -> None:
    if comm.rank == 0:
        atomic_write(path, json.dumps(data, indent=2) + "\n")
    comm.barrier()


class FieldWriter:
    """solution.xdmf: u (P1 vector), sigma (DG0 tensor), sigma_vm, kappa (DG0) per time.

    Crash safety (issue 8): dolfinx rewrites its XML file when it closes it, so a run killed
    during a write would leave a truncated XDMF.  dolfinx therefore writes to a work file
    ``.solution.work.xdmf`` whose HDF5 name ``.solution.work.h5`` is a symlink to
    solution.h5; after every output step the file is closed (HDF5 flushed) and its XML is
    published as solution.xdmf by an atomic rename, pointing at solution.h5.  solution.xdmf
    is thus always a complete description of the steps written so far."""

    def __init__(self, comm, path: Path, mesh, fields):
        self.fields, self.comm, self.path = fields, comm, Path(path)
        stem = self.path.stem
        self.work = self.path.with_name(f".{stem}.work.xdmf")
        self.h5 = self.path.with_suffix(".h5")
        self.work_h5 = self.work.with_suffix(".h5")
        if comm.rank == 0:
            for p in (self.work, self.work_h5, self.h5):
                if p.is_symlink() or p.exists():
                    p.unlink()
            self.work_h5.symlink_to(self.h5.name)
        comm.barrier()
        with dio.XDMFFile(comm, str(self.work), "w") as f:
            f.write_mesh(mesh)
        self._publish()

    def _publish(self) -> None:
        if self.comm.rank == 0:
            text = self.work.read_text().replace(f"{self.work_h5.name}:", f"{self.h5.name}:")
            atomic_write(self.path, text)
        self.comm.barrier()

    def write(self, t: float) -> None:
        with dio.XDMFFile(self.comm, str(self.work), "a") as f:
            for fn in self.fields:
                f.write_function(fn, t)
        self._publish()

    def close(self) -> None:
        self.comm.barrier()
        if self.comm.rank == 0:
            for p in (self.work, self.work_h5):
                if p.is_symlink() or p.exists():
                    p.unlink()
        self.comm.barrier()


def classify(u_nu: np.ndarray, g: float | None, tol: float) -> np.ndarray:
    """Node state from u_nu: 'bound' (u_nu = g), 'compliance' (0 < u_nu < g), 'separated'."""
    state = np.where(u_nu > tol, "compliance", "separated").astype(object)
    if g is not None:
        state[u_nu >= g - tol] = "bound"
    return state


def write_contact_csv(comm, path: Path, table: dict, g: float | None) -> dict:
    """Gather the per-node contact table on rank 0, sort by coordinates and write it (columns
    in the table's order, then ``state``).  Returns counts of node states (on every rank)."""
    tol = 1e-9 * (g if g else 1.0)
    local = {k: np.asarray(v) for k, v in table.items()}
    parts = comm.gather(local, root=0)
    counts = None
    if comm.rank == 0:
        data = {k: np.concatenate([p[k] for p in parts]) for k in local}
        # sort on rounded coordinates: dof coordinates carry rank-dependent round-off
        scale = max(np.abs(data[k]).max(initial=0.0) for k in ("x", "y", "z") if k in data)
        keys = [np.round(data[k] / max(scale, 1e-300), 9) for k in ("z", "y", "x") if k in data]
        order = np.lexsort(tuple(keys))
        data = {k: v[order] for k, v in data.items()}
        data["state"] = classify(data["u_nu"], g, tol)
        columns = list(local) + ["state"]
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(columns)
        for i in range(len(data["x"])):
            writer.writerow([repr(float(data[c][i])) if c != "state" else data[c][i]
                             for c in columns])
        atomic_write(path, buf.getvalue())
        counts = {s: int(np.sum(data["state"] == s)) for s in ("bound", "compliance", "separated")}
        counts["nodes"] = int(len(data["x"]))
    return comm.bcast(counts, root=0)
