"""Outputs of a run: solution.xdmf (+ .h5), summary.json, contact.csv (contact.xdmf:
app/io/contact_xdmf.py, history.csv: app/io/history.py).

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

from vpcontact.io.files import atomic_write, overwrite_in_place
from vpcontact.io.h5files import open_h5
from vpcontact.io.xdmf import TemporalXdmf, XdmfLayoutError, dolfinx_layout, dolfinx_time_key
from vpcontact.native import loaded_libraries

HDF5_MARGIN = 64 * 1024      # bytes of HDF5 metadata a time's datasets may add (B-trees, heaps)
OUTPUT_FILES = ("solution.xdmf", "solution.h5", "summary.json", "contact.csv", "contact.xdmf",
                "contact.h5", "history.csv")


def csv_text(columns, rows) -> str:
    """A CSV table (header and one line per row; floats at full precision, None empty).

    Args:
        columns: the column names, in order.
        rows: mappings from column name to value (missing names are empty).

    Returns:
        The CSV text, lines ending in a newline.
    """
    buf = io.StringIO()
    w = csv.DictWriter(buf, columns, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: "" if r.get(k) is None else repr(float(r[k]))
                    if isinstance(r[k], float) else r[k] for k in columns})
    return buf.getvalue()


class OutputError(OSError):
    """Writing an output file failed (disk full, read-only file system, ...): the same
    error on every rank, so that no rank waits in a collective for one that gave up."""


def write_xdmf(comm, path: Path, mode: str, action, describe) -> None:
    """``action(f)`` on dolfinx's XDMFFile ``path``, closed after (collective).

    A file whose HDF5 write or close failed (a disk full, a file size limit) is never
    destroyed: dolfinx 0.5's XDMFFile destructor closes the HDF5 file again, and HDF5 then
    dies -- a segmentation fault in H5F__close serially, std::terminate (abort) from the
    destructor under mpirun -- before the run could record its failure.  It is leaked
    instead (one more reference, never released: a list would be emptied at interpreter
    exit), and HDF5's termination is disarmed (``_disarm_hdf5_termination``).

    Args:
        comm: the MPI communicator.
        path: the XDMF file.
        mode: "w" or "a".
        action: called with the open file.
        describe: the OutputError's message from dolfinx's RuntimeError.

    Raises:
        OutputError: dolfinx's HDF5 layer failed.
    """
    _quiet_hdf5()
    f = None
    try:
        f = dio.XDMFFile(comm, str(path), mode)
        with f:
            action(f)
    except RuntimeError as exc:
        if f is not None:
            import ctypes
            ctypes.pythonapi.Py_IncRef(ctypes.py_object(f))
            _disarm_hdf5_termination()
        raise OutputError(describe(exc)) from None


def check_space(comm, path: Path, describe, need: int) -> None:
    """Refuse a collective HDF5 write that the file system has no room for (collective;
    rank 0 measures): parallel HDF5 that runs out of space on one rank leaves the others
    waiting in the write's collectives for ever (mpirun -n 2 on a full tmpfs: hung at
    H5D__mpio_opt_possible's MPI_Allreduce), so the write is not begun.  Best effort: the
    disk may still fill during the write (another process), then write_xdmf's error holds.

    Args:
        comm: the MPI communicator.
        path: the file to be written.
        describe: the OutputError's message from the free bytes.
        need: the bytes the write needs at least.

    Raises:
        OutputError: on every rank, if fewer than ``need`` bytes are free.
    """
    free = None
    if comm.rank == 0:
        try:
            st = os.statvfs(path.parent)       # root may write the reserved blocks too
            free = (st.f_bfree if os.geteuid() == 0 else st.f_bavail) * st.f_frsize
        except OSError:
            free = None            # unknown: the write itself tells
    free = comm.bcast(free, root=0)
    if free is not None and free < need:
        raise OutputError(describe(free))


def written_values(fn) -> int:
    """The numbers dolfinx 0.5's XDMFFile writes for a function at one time: every value is
    padded to 3D (a 2D vector to 3 components, a 2D tensor to 9), one per dof block.

    Args:
        fn: a dolfinx Function (scalar, vector or tensor valued).

    Returns:
        The count of float64 values of its dataset.
    """
    blocks = fn.vector.getSize() // fn.function_space.dofmap.index_map_bs
    return blocks * 3 ** len(fn.ufl_shape)


def _disarm_hdf5_termination() -> None:
    """After an HDF5 file failed to close, HDF5 keeps a half-destroyed file object, and its
    termination closes every open file: parallel HDF5 terminates in MPI_Finalize (a delete
    callback on MPI_COMM_SELF), where that file crashes it (segmentation fault in
    H5F__close_cb, after the run recorded its failure: exit 139 for 1).  The process ends
    soon after, and the OS closes the files: parallel HDF5 is marked not initialised
    (HDF5 1.10's global H5_libinit_g), so that its termination does nothing.  Best effort."""
    import ctypes
    for lib in _parallel_hdf5():
        try:
            ctypes.c_bool.in_dll(lib, "H5_libinit_g").value = False
        except ValueError:
            continue


def _quiet_hdf5() -> None:
    """Parallel HDF5 (dolfinx's) prints its whole error stack to stderr on a failure (140
    lines for a full disk); the failure is reported as one OutputError line instead
    (H5Eset_auto2 with no handler: dolfinx still raises).  Once per process."""
    global _HDF5_QUIET
    if _HDF5_QUIET:
        return
    _HDF5_QUIET = True
    import ctypes
    for lib in _parallel_hdf5():
        try:
            lib.H5Eset_auto2(ctypes.c_int64(0), None, None)     # H5E_DEFAULT
        except (AttributeError, OSError):
            continue


_HDF5_QUIET = False


def _parallel_hdf5() -> list:
    """The parallel HDF5 libraries this process has loaded (ctypes), none where unknown."""
    import ctypes
    libs = []
    for path in loaded_libraries("libhdf5"):
        name = Path(path).name
        if "_hl" in name or "_cpp" in name:
            continue
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        if hasattr(lib, "H5Pset_fapl_mpio"):             # parallel HDF5 only
            libs.append(lib)
    return libs


def on_rank0(comm, action, *args):
    """Run ``action(*args)`` on rank 0 only (collective).

    Args:
        comm: the MPI communicator.
        action: the function to call.
        *args: its arguments.

    Returns:
        Its result on rank 0, None elsewhere.

    Raises:
        OutputError: on every rank, if ``action`` raised an OSError on rank 0.
    """
    result, error = None, None
    if comm.rank == 0:
        try:
            result = action(*args)
        except OSError as exc:
            error = describe_os_error(exc)
    error = comm.bcast(error, root=0)
    if error is not None:
        raise OutputError(error)
    return result


def describe_os_error(exc: OSError) -> str:
    """One line for an OSError.

    Args:
        exc: the error.

    Returns:
        '<file>: <reason>' (or the message of an error without a file).
    """
    name = exc.filename or ""
    reason = exc.strerror or str(exc)
    return f"{name}: {reason}" if name else reason


def _json_default(value):
    """numpy scalars and arrays in summaries (np.bool_, np.float64, ...) as plain JSON."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def to_json(data) -> str:
    """The JSON text of a summary: numpy types as plain numbers, non-finite numbers kept
    as JSON's NaN/Infinity extension (Python's json reads them back).

    Args:
        data: the summary (dicts, lists, numbers, strings, numpy values).

    Returns:
        The indented JSON text with a final newline.
    """
    return json.dumps(data, indent=2, default=_json_default) + "\n"


def write_json(comm, path: Path, data: dict) -> None:
    """Write ``data`` to ``path`` atomically on rank 0 (collective).

    Args:
        comm: the MPI communicator.
        path: the JSON file.
        data: the content (see to_json).

    Raises:
        OutputError: on every rank, if the file could not be written.
    """
    text = to_json(data) if comm.rank == 0 else None
    on_rank0(comm, atomic_write, path, text)


class FieldWriter:
    """solution.xdmf: u (P1 vector), sigma (DG0 tensor), sigma_vm, kappa (DG0) per time, as
    one dataset (app/io/xdmf.py: one temporal collection, every field in the Grid of its
    time) over the HDF5 datasets dolfinx writes (in parallel) into solution.h5.

    Crash safety: dolfinx rewrites its XML file when it closes it, so a run killed
    during a write would leave a truncated XDMF.  dolfinx therefore writes to a work file
    ``.solution.work.xdmf`` whose HDF5 name ``.solution.work.h5`` is a symlink to
    solution.h5; after every output step the file is closed (HDF5 flushed), and rank 0
    appends the new datasets' Grid to solution.xdmf (TemporalXdmf: in place, before the
    closing tags).  solution.xdmf is thus always a complete description of the steps
    written so far.

    Cost: O(1) per output step.  dolfinx parses its XML file when it opens it and saves it
    whole after every function written, so rank 0 puts the work file back to the mesh
    alone after every step (dolfinx's Grids reference the mesh by an XPath, and its
    datasets are named by the time only): neither XML file is rewritten whole.

    Args:
        comm: the MPI communicator.
        path: the XDMF file (its HDF5 file is the same name with .h5).
        mesh: the dolfinx mesh, written once.
        fields: the Functions written at every output time.

    Raises:
        OutputError: the files could not be created or the mesh not written.
    """

    def __init__(self, comm, path: Path, mesh, fields):
        self.fields, self.comm, self.path = fields, comm, Path(path)
        stem = self.path.stem
        self.work = self.path.with_name(f".{stem}.work.xdmf")
        self.h5 = self.path.with_suffix(".h5")
        self.work_h5 = self.work.with_suffix(".h5")
        on_rank0(comm, self._fresh_files)
        write_xdmf(comm, self.work, "w", lambda f: f.write_mesh(mesh),
                   lambda exc: f"{self.h5}: cannot write the mesh ({exc})")
        self.xml, self._layout, self._mesh_xml = None, None, None
        on_rank0(comm, self._start_xml)

    def _fresh_files(self) -> None:
        for p in (self.work, self.work_h5, self.h5):
            if p.is_symlink() or p.exists():
                p.unlink()
        self.work_h5.symlink_to(self.h5.name)

    def _start_xml(self) -> None:
        """The mesh's items from dolfinx's XML; solution.xdmf with the mesh alone."""
        self._mesh_xml = self.work.read_bytes()
        try:
            topology, geometry, _ = dolfinx_layout(self._mesh_xml, self.h5.name)
        except XdmfLayoutError as exc:           # an OSError: every rank raises it (on_rank0)
            raise OutputError(f"{self.work}: {exc}") from None
        self.xml = TemporalXdmf(self.path, self.path.stem, topology, geometry)
        self._function_groups()

    def _function_groups(self) -> None:
        """Create solution.h5's group of each field (dolfinx adds its datasets, one a time)
        with new-style link storage (link creation order tracked): an old-style group, as
        dolfinx creates it, keeps its datasets' names in one local heap that HDF5 reads and
        writes whole whenever a dataset is added, O(n) bytes at step n; the new-style
        fractal heap writes one direct block (at most 64 KiB) and its B-tree nodes."""
        with open_h5(self.h5, "a") as f:
            for field in self.fields:
                f.create_group(f"Function/{field.name}", track_order=True)

    def _add_time(self, t: float) -> None:
        """Append the Grid of time t (its datasets: dolfinx's names, dolfinx_time_key)."""
        if self._layout is None:
            self._layout = self._first_layout(t)
        key = dolfinx_time_key(t)
        self.xml.add(t, [field.attribute(self.h5.name, f"/Function/{field.name}/{key}", shape)
                         for field, shape in self._layout])
        overwrite_in_place(self.work, self._mesh_xml)      # dolfinx's XML back to the mesh alone

    def _first_layout(self, t: float) -> list:
        """The fields (types and centres from dolfinx's XML) with their datasets' shapes,
        read from solution.h5 once: this checks that dolfinx named the datasets of time t
        dolfinx_time_key(t); later times use that name without opening the file."""
        import h5py
        fields = dolfinx_layout(self.work.read_text(), self.h5.name)[2]
        key = dolfinx_time_key(t)
        with h5py.File(self.h5, "r") as f:
            missing = [field.name for field in fields if key not in f["Function"][field.name]]
            if missing:
                raise OutputError(f"{self.h5}: no dataset {key!r} of {', '.join(missing)} "
                                  "(not the naming of dolfinx 0.5)")
            return [(field, f["Function"][field.name][key].shape) for field in fields]

    def write(self, t: float, columns: dict | None = None) -> None:
        """Append the fields at time t and republish solution.xdmf (collective).

        Args:
            t: the time t_n the fields belong to.
            columns: components of cell fields to replace after dolfinx wrote them,
                {(field name, component): values of the owned cells in local order} (a 2D
                tensor's sigma_33, which dolfinx writes 0: ``_write_columns``), or None.

        Raises:
            OutputError: HDF5 or the file system refused (solution.xdmf then still
                describes the earlier steps).
        """
        def fields(f):
            for fn in self.fields:
                f.write_function(fn, t)
        need = 8 * sum(written_values(fn) for fn in self.fields) + HDF5_MARGIN
        check_space(self.comm, self.h5,
                    lambda free: f"{self.h5}: cannot write the fields at t = {t:g} (No space "
                                 f"left on device: {free} bytes free, {need} needed)", need)
        write_xdmf(self.comm, self.work, "a", fields,    # disk full, read-only
                   lambda exc: f"{self.h5}: cannot write the fields at t = {t:g} ({exc})")
        if columns:
            self._write_columns(t, columns)
        on_rank0(self.comm, self._add_time, t)

    def _write_columns(self, t: float, columns: dict) -> None:
        """Replace components of the cell datasets of time t (collective): dolfinx 0.5
        writes a DG0 field's owned cells in their local order at the rank's global offset
        (the order of the mesh's cells in the file), so the ranks' values gathered in rank
        order are the dataset's rows; rank 0 writes them (one column each)."""
        gathered = {k: self.comm.gather(np.ascontiguousarray(v, dtype=float), root=0)
                    for k, v in columns.items()}

        def put():
            import h5py
            key = dolfinx_time_key(t)
            with h5py.File(self.h5, "r+") as f:
                for (name, component), parts in gathered.items():
                    f["Function"][name][key][:, component] = np.concatenate(parts)
        on_rank0(self.comm, put)

    def close(self) -> None:
        """Remove the work file and its link (solution.xdmf and solution.h5 stay)."""
        self.comm.barrier()
        if self.comm.rank == 0:
            for p in (self.work, self.work_h5):
                if p.is_symlink() or p.exists():
                    p.unlink()
        self.comm.barrier()


# separated: p_n <= SEPARATED_RATIO max p_n (the forces' round-off: classify, and
# slip_states of app/post/quantities.py)
SEPARATED_RATIO = 1e-6
# the displacements' round-off, relative to their largest value on Gamma3
U_ROUNDOFF = 1e-9


def classify(data: dict, g: float | None, compliance: bool | tuple = True,
             length: float = 0.0) -> np.ndarray:
    """Node state from the columns of the contact table: 'bound' (u_nu = g), 'compliance'
    (0 < u_nu < g), 'separated' (u_nu <= 0), 'prescribed' (the Dirichlet data fix u_nu).

    The tolerances come from the solution and the body, not from g: u_nu counts as positive
    beyond the round-off of the displacement and of the distances measured on the mesh,
    U_ROUNDOFF (1e-9, as slip_threshold's) times the largest of the largest displacement
    component on Gamma3 and the body's length scale L (with contact.pairs u_nu is measured
    from the initial distance d, whose round-off ~ eps L differs with the partition: at
    t = 0, u = 0, a touching node's d = +-2e-16 classed it bound with one rank count and
    separated with another), or when the node carries a contact pressure -sigma_nu above
    the round-off of the forces (SEPARATED_RATIO = 1e-6 of the largest force density, as
    slip_state's): a stiff normal compliance (large c_nu) holds the load with a penetration
    far below the displacement's round-off.  The bound u_nu <= g is imposed exactly, so
    'bound' is u_nu >= g up to the same round-off (or 1e-9 of g where that is larger).

    Args:
        data: the columns of the contact table (u_nu, the u_* and neg_sigma* columns).
        g: the bound of the unilateral constraint (None: no bound; an expression: the
            table's column g).
        compliance: the foundation has a normal compliance (else a node below its bound is
            'separated': the unilateral bound alone, Signorini contact); with laws per
            pair, one per pair (a tuple, read through the table's column ``pair``).
        length: the body's length scale L (problem.disc.length_scale; 0: the solution's
            round-off alone).

    Returns:
        The state of each node (an object array of strings).
    """
    if isinstance(compliance, tuple):      # laws per pair
        compliance = np.asarray(compliance, dtype=bool)[np.asarray(data["pair"], dtype=int)]
    u_nu = data["u_nu"]
    u_cols = [v for k, v in data.items() if k.startswith("u_") and k not in ("u_nu",)]
    u_scale = max((float(np.abs(v).max(initial=0.0)) for v in u_cols), default=0.0)
    f_cols = [v for k, v in data.items() if k.startswith("neg_sigma")]
    f_scale = max((float(np.abs(v).max(initial=0.0)) for v in f_cols), default=0.0)
    pressure = data.get("neg_sigma_nu", np.zeros_like(u_nu))
    scale = max(u_scale, length)
    touching = (u_nu > U_ROUNDOFF * scale) | ((u_nu > 0) & (pressure > SEPARATED_RATIO * f_scale))
    state = np.where(touching & compliance, "compliance", "separated").astype(object)
    if "g" in data:                   # a gap that varies along Gamma3 (may be 0 somewhere)
        gap = data["g"]
        state[u_nu >= gap - U_ROUNDOFF * np.maximum(gap, scale)] = "bound"
    elif g is not None:
        state[u_nu >= g - U_ROUNDOFF * max(g, scale)] = "bound"
    if "_prescribed" in data:          # u_nu is Dirichlet data: the force is a reaction
        state[np.asarray(data["_prescribed"], dtype=bool)] = "prescribed"
    return state


def gather_contact_table(comm, table: dict, g: float | None,
                         compliance: bool = True, length: float = 0.0) -> dict | None:
    """The contact table of all ranks on rank 0, sorted by coordinates, with the node
    states (collective; O(Gamma3 nodes) data).

    Args:
        comm: the MPI communicator.
        table: this rank's columns (post.quantities.contact_table).
        g: the bound of the unilateral constraint (None: no bound).
        compliance: the foundation has a normal compliance (see classify).
        length: the body's length scale (see classify).

    Returns:
        On rank 0: column -> values, the table's columns then ``state``; None elsewhere.
    """
    local = {k: np.asarray(v) for k, v in table.items()}
    parts = comm.gather(local, root=0) if comm.size > 1 else [local]     # no pickling
    if comm.rank != 0:
        return None
    data = {k: np.concatenate([p[k] for p in parts]) for k in local}
    # sort on rounded coordinates: dof coordinates carry rank-dependent round-off
    scale = max(np.abs(data[k]).max(initial=0.0) for k in ("x", "y", "z") if k in data)
    keys = [np.round(data[k] / max(scale, 1e-300), 9) for k in ("z", "y", "x") if k in data]
    order = np.lexsort(tuple(keys))
    data = {k: v[order] for k, v in data.items()}
    data["state"] = classify(data, g, compliance, length)
    return data


def state_counts(data: dict) -> dict:
    """The node counts of a gathered contact table (gather_contact_table).

    Args:
        data: the table with its ``state`` column.

    Returns:
        {"bound", "compliance", "separated"(, "prescribed" where some are), "nodes"(,
        "pairs": the counts of each contact pair, where there are several)}.
    """
    counts = {s: int(np.sum(data["state"] == s)) for s in ("bound", "compliance", "separated")}
    if "_prescribed" in data and np.any(data["_prescribed"]):
        counts["prescribed"] = int(np.sum(data["state"] == "prescribed"))
    counts["nodes"] = int(len(data["state"]))
    if "pair" in data and len(np.unique(data["pair"])) > 1:     # two bodies, several pairs
        counts["pairs"] = [state_counts({k: v[data["pair"] == i] for k, v in data.items()})
                           for i in range(int(data["pair"].max()) + 1)]
    return counts


def write_contact_csv(comm, path: Path, table: dict, g: float | None,
                      compliance: bool = True, length: float = 0.0) -> dict:
    """Gather the per-node contact table on rank 0, sorted by coordinates, and write it
    (columns in the table's order, then ``state``).  In 2D the columns are x, y, u_x, u_y, u_nu,
    u_tau (along the nodal tangent), neg_sigma_nu (the contact pressure, the bound's reaction
    included), neg_sigma_tau; in 3D z, u_z, the components in the nodal frame (u_tau1,
    u_tau2, neg_sigma_tau1, neg_sigma_tau2) and the slip magnitude u_tau appear, and xi
    (memory) / theta (slip dependence) / g (a gap expression) when the case has them.
    Collective.

    Args:
        comm: the MPI communicator.
        path: the CSV file.
        table: this rank's columns (post.quantities.contact_table).
        g: the bound of the unilateral constraint (None: no bound).
        compliance: the foundation has a normal compliance (see classify).
        length: the body's length scale (see classify).

    Returns:
        The counts of node states (state_counts) on every rank.

    Raises:
        OutputError: on every rank, if the file could not be written.
    """
    data = gather_contact_table(comm, table, g, compliance, length)
    counts = text = None
    if comm.rank == 0:
        columns = [k for k in table if not k.startswith("_")] + ["state"]
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(columns)
        for i in range(len(data["state"])):
            writer.writerow([repr(float(data[c][i])) if c != "state" else data[c][i]
                             for c in columns])
        counts, text = state_counts(data), buf.getvalue()
    on_rank0(comm, lambda: atomic_write(path, text))    # OutputError on every rank
    return comm.bcast(counts, root=0)
