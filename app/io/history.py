"""history.csv: one row per accepted step (time, norms, force resultants, contact node
counts, iterations, step wall time), for spreadsheets, the csv module, numpy and
ParaView's CSV reader.

Rank 0 writes the header and the rows of the steps a restart restored at the start (by an
atomic rename), then appends one complete line per step with a single write, so the file
holds whole rows whenever a run stops.

For a law with m > 1 internal variables (Chaboche's kappa = (X, R, p)), norm_kappa_Y is the
L2 norm over the body of the Euclidean norm of kappa's m components per cell, and max_kappa
the largest value of any component in any cell (app/post/quantities.py, cell_norm and
cell_max), as in summary.json's steps; for m = 1 (Perzyna's kappa, Norton's p) they are the
norm and the largest value of kappa.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from vpcontact.io.files import atomic_write
from vpcontact.io.output import csv_text, on_rank0

STATES = ("bound", "compliance", "separated", "prescribed")


def rigid_columns(dim: int, cap: str) -> list[str]:
    """The columns of a rigid cap: its displacement, rotation, force and moment.

    Args:
        dim: the body's dimension.
        cap: the cap's group.

    Returns:
        rigid_<cap>_u_x, ..., rigid_<cap>_theta (3D: theta_x, ...), rigid_<cap>_F_x, ...,
        rigid_<cap>_M (3D: M_x, ...).
    """
    axes = "xyz"[:dim]
    turns = [""] if dim == 2 else [f"_{a}" for a in axes]
    return [f"rigid_{cap}_{q}" for q in [f"u_{a}" for a in axes] + [f"theta{a}" for a in turns]
            + [f"F_{a}" for a in axes] + [f"M{a}" for a in turns]]


def history_columns(dim: int, groups: list[str], contact: bool,
                    pairs: list[tuple[str, str]] = (), caps: list[str] = ()) -> list[str]:
    """The columns of history.csv.

    Args:
        dim: the body's dimension.
        groups: the Dirichlet groups' names (their reaction resultants).
        contact: the case has Gamma3 (contact force and node counts).
        pairs: (surface, target) of each contact pair (two bodies), or none.
        caps: the rigid caps' groups (loads.rigid), or none.

    Returns:
        n, t, k, the norms of u_n, sigma_n, kappa_n, max von Mises and kappa, the contact
        force on the body (contact_force_x, ...; with pairs, on the surfaces summed over
        the pairs: several pairs' surfaces are different bodies) and, per pair, on its
        surface's and its target's body (pair<i>_<group>_x, ...), the reaction
        on each group (reaction_<group>_x, ...), each rigid cap's motion and resultant
        (rigid_columns), the Gamma3 node counts (nodes_bound, ...), the error estimate
        (app/post/estimators.py: est_time, est_space, est_total, est_max, est_space's
        parts, est_time's Gamma3 part, the step's local time error est_time_local), Newton
        and linear iterations, the step's wall time.
    """
    axes = "xyz"[:dim]
    cols = ["n", "t", "k", "norm_u_V", "norm_sigma_Q", "norm_kappa_Y", "max_vm", "max_kappa"]
    if contact:
        cols += [f"contact_force_{a}" for a in axes]
    cols += [f"pair{i}_{g}_{a}" for i, pair in enumerate(pairs) for g in pair for a in axes]
    cols += [f"reaction_{g}_{a}" for g in groups for a in axes]
    cols += [c for cap in caps for c in rigid_columns(dim, cap)]
    if contact:
        cols += [f"nodes_{s}" for s in STATES]
    cols += ["est_time", "est_space", "est_total", "est_max", "est_space_sigma_Q",
             "est_space_u_V", "est_space_kappa_Y", "est_space_contact", "est_time_gamma3",
             "est_time_local"]
    return cols + ["newton_iterations", "linear_iterations", "wall_s"]


def history_row(record: dict, dim: int) -> dict:
    """A step record (app/records.py) as a row of history.csv.

    Args:
        record: the step's record.
        dim: the body's dimension.

    Returns:
        Column name -> value (missing columns stay empty).
    """
    axes = "xyz"[:dim]
    row = {k: v for k, v in record.items() if not isinstance(v, (dict, list))}
    for i, a in enumerate(axes):
        if record.get("contact_force") is not None:
            row[f"contact_force_{a}"] = record["contact_force"][i]
        for g, force in record.get("reactions", {}).items():
            row[f"reaction_{g}_{a}"] = force[i]
    for i, pair in enumerate(record.get("pair_forces", ())):
        for g, key in ((pair["surface"], "on_surface"), (pair["target"], "on_target")):
            row.update({f"pair{i}_{g}_{a}": pair[key][j] for j, a in enumerate(axes)})
    for cap, q in record.get("rigid", {}).items():
        values = [v for key in ("displacement", "rotation", "force", "moment")
                  for v in np.atleast_1d(q[key])]
        row.update(zip(rigid_columns(dim, cap), values))
    states = record.get("contact_states")
    if states is not None:
        row.update({f"nodes_{s}": states.get(s, 0) for s in STATES})
    return row


class HistoryWriter:
    """history.csv in an output directory (collective methods).

    Args:
        comm: the MPI communicator.
        path: the CSV file.
        columns: history_columns(...).
        dim: the body's dimension.
        records: the step records so far (a restart's restored steps; else empty).

    Raises:
        OutputError: on every rank, if the file cannot be written.
    """

    def __init__(self, comm, path: Path, columns: list[str], dim: int, records=()):
        self.comm, self.path, self.columns, self.dim = comm, Path(path), columns, dim
        text = csv_text(columns, [history_row(r, dim) for r in records])
        on_rank0(comm, atomic_write, self.path, text)

    def append(self, record: dict) -> None:
        """Append the row of an accepted step (one write of a whole line).

        Args:
            record: the step's record.

        Raises:
            OutputError: on every rank, if the line cannot be written.
        """
        line = csv_text(self.columns, [history_row(record, self.dim)]).split("\n", 1)[1]
        on_rank0(self.comm, self._append, line.encode())

    def _append(self, data: bytes) -> None:
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        try:
            os.write(fd, data)
        finally:
            os.close(fd)
