"""Checkpoint and restart (issue 8): the full state of scheme (3.2)-(3.4) after step n.

Saved: t_n and the step counter, the stepper (adaptive k and history), the step records, and
every field the next step reads: u_n (P1), sigma_n, H_n (DG0 tensors), kappa_n (DG0), and the
active Gamma3 histories (memory term: xi_n, and for the direct sum the stored u_nu^+ history;
slip: s_n).  Values are stored with the coordinates of their nodes / cell midpoints, gathered
on rank 0 into one ``checkpoint.npz`` (written atomically), so a run can restart on any number
of MPI ranks: each rank matches its own nodes and cells by coordinates.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

PATTERN = "checkpoint_*.npz"
KEEP = 2                       # the newest checkpoints kept in an output directory
_DECIMALS = 10


def file_name(n: int) -> str:
    return f"checkpoint_{n:06d}.npz"


def latest(directory: Path) -> Path | None:
    files = sorted(Path(directory).glob(PATTERN))
    return files[-1] if files else None


def case_fingerprint(case) -> str:
    """What must agree between the checkpointed run and the restart: mesh, material, contact,
    loads, initial values, time grid and scheme (not solver or output settings)."""
    raw = case.raw
    keys = ("mesh", "material", "contact", "loads", "initial")
    data = {k: raw.get(k) for k in keys}
    data["times"] = list(case.time.times)
    data["scheme"] = case.time.scheme
    data["adaptive"] = case.time.adaptive
    return hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()


def _owned_rows(function):
    """(coordinates, values) of the owned nodes / cells of a P1 or DG0 Function."""
    V = function.function_space
    n = V.dofmap.index_map.size_local
    bs = V.dofmap.index_map_bs
    x = V.tabulate_dof_coordinates()[:n]
    return x, function.x.array[:n * bs].reshape(n, bs)


def _key(x: np.ndarray) -> list[tuple]:
    return [tuple(r) for r in np.round(x, _DECIMALS)]


def _gather(comm, x, v):
    parts = comm.gather((x, v), root=0)
    if comm.rank != 0:
        return None, None
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


def _fields(problem, history):
    out = {"u": problem.u, "sigma": problem.sigma}
    if problem.H is not None:
        out["H"] = problem.H
    if history is not None:
        out["kappa"] = history.kappa
    return out


def save(outdir: Path, comm, case, problem, history, g3, stepper, n: int, t: float,
         steps: list) -> Path:
    """Write the state after step n to outdir/checkpoint_<n>.npz (collective); older
    checkpoints beyond the newest KEEP are removed."""
    path = Path(outdir) / file_name(n)
    arrays = {}
    for name, f in _fields(problem, history).items():
        x, v = _gather(comm, *_owned_rows(f))
        if comm.rank == 0:
            arrays[f"{name}_x"], arrays[f"{name}_v"] = x, v
    if g3 is not None:
        V = problem.V
        own = problem.gamma3.nodes                       # owned Gamma3 nodes (local index)
        pos = np.searchsorted(problem.gamma3_local_nodes, own)
        xg = V.tabulate_dof_coordinates()[own]
        cols = {}
        if g3.memory is not None:
            cols["xi"] = g3.memory.xi[pos][:, None]
            if not g3.memory.recursion and g3.memory.stored_steps:
                cols["mem_r"] = np.asarray(g3.memory._r)[:, pos].T
        if g3.slip is not None:
            cols["slip_s"] = g3.slip.s[pos][:, None]
        for name, v in cols.items():
            x, vv = _gather(comm, xg, v)
            if comm.rank == 0:
                arrays[f"g3_{name}_x"], arrays[f"g3_{name}_v"] = x, vv
    if comm.rank == 0:
        meta = {"n": n, "t": t, "fingerprint": case_fingerprint(case), "steps": steps,
                "stepper": {"adaptive": stepper.adaptive, "n": getattr(stepper, "n", None),
                            "k": getattr(stepper, "k", None), "history": stepper.history},
                "memory": None if g3 is None or g3.memory is None else
                {"t_prev": g3.memory._t_prev, "k": g3.memory._k}}
        arrays["meta"] = np.array(json.dumps(meta))
        tmp = path.with_name(f".{path.name}.tmp.npz")
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
        for old in sorted(Path(outdir).glob(PATTERN))[:-KEEP]:
            old.unlink()
    comm.barrier()
    return path


class Checkpoint:
    """A loaded checkpoint; ``restore`` puts its state into a freshly set-up run."""

    def __init__(self, path: Path):
        with np.load(path, allow_pickle=False) as data:
            self.arrays = {k: data[k] for k in data.files}
        self.meta = json.loads(str(self.arrays.pop("meta")))
        self.path = path

    @property
    def n(self) -> int:
        return self.meta["n"]

    @property
    def t(self) -> float:
        return self.meta["t"]

    def check(self, case) -> str | None:
        """None if the checkpoint belongs to this case, else the reason it does not."""
        if self.meta["fingerprint"] != case_fingerprint(case):
            return (f"{self.path} was written for a different case (mesh, material, contact, "
                    "loads, initial values or time grid differ)")
        return None

    def _lookup(self, name: str, x_local: np.ndarray) -> np.ndarray:
        values = self.arrays[f"{name}_v"]
        table = dict(zip(_key(self.arrays[f"{name}_x"]), values))
        try:
            rows = [table[k] for k in _key(x_local)]
            return np.array(rows).reshape(len(rows), *values.shape[1:])
        except KeyError:
            raise ValueError(f"{self.path}: the mesh does not match the checkpoint") from None

    def restore(self, problem, history, g3, stepper) -> list:
        """Set the fields and histories; returns the step records up to step n."""
        for name, f in _fields(problem, history).items():
            V = f.function_space
            x = V.tabulate_dof_coordinates()           # owned and ghost: no scatter needed
            f.x.array[:] = self._lookup(name, x).reshape(-1)
        if g3 is not None:
            xg = problem.V.tabulate_dof_coordinates()[problem.gamma3_local_nodes]
            if g3.memory is not None:
                g3.memory.xi = self._lookup("g3_xi", xg)[:, 0].copy()
                mem = self.meta["memory"]
                g3.memory._t_prev, g3.memory._k = list(mem["t_prev"]), list(mem["k"])
                if "g3_mem_r_x" in self.arrays:
                    r = self._lookup("g3_mem_r", xg)          # (m, steps)
                    g3.memory._r = [r[:, j].copy() for j in range(r.shape[1])]
                g3.xi.set(g3.memory.xi)
            if g3.slip is not None:
                g3.slip.s = self._lookup("g3_slip_s", xg)[:, 0].copy()
                g3.theta.set(g3.slip.theta())
        st = self.meta["stepper"]
        if stepper.adaptive:
            stepper.k = st["k"]
        else:
            stepper.n = st["n"]
        stepper.history = list(st["history"])
        problem.update_vm()
        return list(self.meta["steps"])
