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

    The file is closed after every write and reopened in append mode for the next one, so the
    HDF5 data are flushed and the XDMF/HDF5 pair stays readable up to the last written step
    even if the process is killed (issue 8); the cost is one open/close per output step."""

    def __init__(self, comm, path: Path, mesh, fields):
        self.fields, self.comm, self.path = fields, comm, str(path)
        with dio.XDMFFile(comm, self.path, "w") as f:
            f.write_mesh(mesh)

    def write(self, t: float) -> None:
        with dio.XDMFFile(self.comm, self.path, "a") as f:
            for fn in self.fields:
                f.write_function(fn, t)

    def close(self) -> None:
        pass


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
