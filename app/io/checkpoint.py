"""Checkpoint and restart: the full state of scheme (3.2)-(3.4) after step n.

Saved: t_n and the step counter, the stepper's state (the adaptive k and its decisions,
stored under the key "history" of the file's meta data), the step records, and every field
the next step reads: u_n (P1), sigma_n, H_n (DG0 tensors), kappa_n (DG0, the law's m
columns: 8 for Chaboche's (X, R, p)), and the active Gamma3 history terms as their
``state()`` gives them (memory term: xi_n, and for the direct sum the stored u_nu^+ history;
slip: s_n; Coulomb friction: the contact pressure p_n its next fixed point starts from;
with either, the slip path: u_{n-1,tau} and the accumulated slip; a checkpoint without it
restarts the path at the restart), and the error estimate's propagated time error (delta H,
delta kappa per cell, app/post/estimators.py ``TimeError.state``; a checkpoint without it
restarts that error from zero).
Values are stored with the coordinates of their
nodes / cell midpoints, gathered on rank 0 into one ``checkpoint.npz`` (written
atomically), so a run can restart on any number of MPI ranks: each rank matches its own
nodes and cells by coordinates (within 1e-6 of the smallest distance between two of them,
whatever the body's size: ``match_points``).  The fields are the State's
(app/model/state.py: ``fields()`` and its Gamma3 history's ``state()``), and a restart puts
them back through the same interface.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
from pathlib import Path

import numpy as np

from vpcontact.io.canonical import stable_json
from vpcontact.io.casekey import SECTIONS, group_map, normalised_sections
from vpcontact.io.errors import CaseError
from vpcontact.io.lawfile import law_module_digest, python_law_classes
from vpcontact.io.output import on_rank0

PATTERN = "checkpoint_*.npz"
KEEP = 2                       # the newest checkpoints kept in an output directory
# stored and restarted points match within this fraction of the smallest distance between
# two stored points (match_points)
MATCH_TOLERANCE = 1e-6


def file_name(n: int) -> str:
    """The checkpoint file name of a step.

    Args:
        n: the step number.

    Returns:
        checkpoint_<n, six digits>.npz, e.g. checkpoint_000012.npz.
    """
    return f"checkpoint_{n:06d}.npz"


def latest(directory: Path) -> Path | None:
    """The newest checkpoint (highest step) in a directory.

    Args:
        directory: an output directory.

    Returns:
        The path of its checkpoint_<n>.npz with the largest n, or None if it holds none.
    """
    files = sorted(Path(directory).glob(PATTERN))
    return files[-1] if files else None


def case_fingerprint(case, laws: dict | None = None) -> str:
    """What must agree between the checkpointed run and the restart: mesh, material, contact,
    loads, initial values, time grid and scheme (not solver or output settings), the laws
    given through the Python API (``api_laws``) and, with a ``python`` law of the case, the
    SHA-256 of the --law-module file's bytes (``law_module``); each added only when there
    is one, so a case without them keeps its fingerprint.

    Args:
        case: the validated Case.
        laws: ``api_laws`` of the run, or None.

    Returns:
        A SHA-256 hex digest of those sections.
    """
    raw = case.raw
    data = {k: raw.get(k) for k in SECTIONS}
    if "materials" in raw:                 # one material per group of cells
        data["materials"] = raw["materials"]
    return _fingerprint(case, data, laws)


def case_key(case, groups: dict, laws: dict | None = None) -> str:
    """The fingerprint of the normalised case (app/io/casekey.py): the sections of
    ``case_fingerprint`` with defaults filled, numbers as floats and groups by their tags,
    so that equivalent spellings of a case restart from each other's checkpoints; the same
    time grid, mesh files, API laws and law module as ``case_fingerprint``.

    Args:
        case: the validated Case.
        groups: ``casekey.group_map`` of the mesh the checkpoint is (was) written on.
        laws: ``api_laws`` of the run, or None.

    Returns:
        A SHA-256 hex digest.
    """
    return _fingerprint(case, normalised_sections(case, groups), laws)


def _fingerprint(case, data: dict, laws: dict | None) -> str:
    """SHA-256 of the case's sections ``data`` with its time grid, mesh files, API laws and
    law module (``case_fingerprint``)."""
    data = dict(data)
    data["times"] = list(case.time.times)
    data["scheme"] = case.time.scheme
    data["adaptive"] = case.time.adaptive
    if case.mesh.file is not None:           # the scene is the files' content, not their names
        data["mesh_file"] = _mesh_files_digest(case)
    if laws:
        data["api_laws"] = laws
    module = law_module(case)
    if module is not None:
        data["law_module"] = module["sha256"]
    return hashlib.sha256(stable_json(data).encode()).hexdigest()


def law_module(case) -> dict | None:
    """The --law-module file of a case that names a ``python`` law (viscoplastic or contact).

    Args:
        case: the validated Case.

    Returns:
        {"path", "sha256"} of the loaded module (app/io/lawfile.py), or None: the case
        names no python law, or no module is loaded (laws given through the API instead).
    """
    return law_module_digest() if python_law_classes(case.raw) else None


def _plain(v):
    """A value for a law's identity: numbers, text, booleans and None as they are, arrays
    and sequences of them as lists, dicts of them; anything else None (not comparable)."""
    if v is None or isinstance(v, (bool, str)):
        return v
    if isinstance(v, (int, float, np.integer, np.floating)):
        return float(v)
    if isinstance(v, np.ndarray) and v.dtype.kind in "biuf":
        return v.astype(float).tolist()
    if isinstance(v, (list, tuple)):
        items = [_plain(x) for x in v]
        return None if any(x is None and y is not None for x, y in zip(items, v)) else items
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    return None


def law_identity(law) -> dict:
    """What identifies a law given through the Python API: its class (module and qualified
    name), ``name``, ``constants()`` where it has them, and its attributes that are numbers,
    text or arrays of numbers (a user's law that keeps its constants in attributes).  A
    viscoplastic law in the user protocol is identified by the user's object, not by the
    UserLaw around it (app/model/userlaw.py).

    Args:
        law: the law object the run uses.

    Returns:
        {"class", "name", "constants", "attributes"}.
    """
    user = getattr(law, "user", None)
    obj = user if user is not None and callable(getattr(user, "G", None)) else law
    kind = type(obj)
    consts = obj.constants() if callable(getattr(obj, "constants", None)) else {}
    attrs = {k: _plain(v) for k, v in sorted(vars(obj).items())
             if not k.startswith("_")} if hasattr(obj, "__dict__") else {}
    return {"class": f"{kind.__module__}.{kind.__qualname__}",
            "name": str(getattr(obj, "name", kind.__name__)),
            "constants": {str(k): _plain(v[0] if isinstance(v, tuple) else v)
                          for k, v in consts.items()},
            "attributes": {k: v for k, v in attrs.items() if v is not None}}


def api_laws(sim) -> dict | None:
    """The identities (``law_identity``) of the laws a Simulation was given through the
    Python API: its viscoplastic law (``law=``) and its contact laws (``contact_laws=``).

    Args:
        sim: the Simulation (set up: its problem holds the laws built).

    Returns:
        {"viscoplastic": ..., "contact.normal": ..., "contact.friction": ...} with the laws
        given, or None if none was.
    """
    laws = {}
    if getattr(sim, "law", None) is not None:
        laws["viscoplastic"] = law_identity(sim.problem.law)
    for part, law in sorted((getattr(sim, "contact_laws", None) or {}).items()):
        laws[f"contact.{part}"] = law_identity(law)
    return laws or None


def _laws_text(laws: dict | None) -> str:
    """'viscoplastic: mod.Class (c = 1)' of each law of ``api_laws``, or 'none'."""
    if not laws:
        return "none"
    out = []
    for part, ident in laws.items():
        consts = {**ident.get("attributes", {}), **ident.get("constants", {})}
        text = ", ".join(f"{k} = {v}" for k, v in consts.items())
        out.append(f"{part}: {ident.get('class')}" + (f" ({text})" if text else ""))
    return "; ".join(out)


def _mesh_files_digest(case) -> str | list[str]:
    """SHA-256 of each file the mesh is made of: the .msh or .geo and every file a .geo
    includes or merges (meshes.geoscan.mesh_files), in the order gmsh reads them (one file:
    its digest alone, as checkpoints written before included files counted have it)."""
    from vpcontact.meshes.geoscan import GeoScanError, mesh_files
    try:
        files = mesh_files(case.mesh.file)
    except GeoScanError as exc:
        raise CaseError(f"{case.source}: mesh.file: {exc}") from None
    digests = [hashlib.sha256(f.read_bytes()).hexdigest() for f in files]
    return digests[0] if len(digests) == 1 else digests


def points(problem, V) -> np.ndarray:
    """The coordinates that identify V's local dofs (owned and ghost) in a checkpoint.  With
    contact pairs the bodies may touch at the start, their interface nodes coinciding: a
    fourth column, the node's pair label (1 surface, 2 target, 0 neither;
    app/model/pairs.py ``node_labels``) times the body's size, tells them apart.

    Args:
        problem: the ContactProblem.
        V: the space of a State field (P1 or DG0).

    Returns:
        (local dofs, 3 or 4) coordinates.
    """
    x, disc = V.tabulate_dof_coordinates(), problem.disc
    if disc.pairs is None or V.ufl_element().degree() != 1:
        return x
    return np.column_stack([x, disc.pair_node_labels * disc.length_scale])


def _owned_rows(problem, function):
    """(coordinates, values) of the owned nodes / cells of a P1 or DG0 Function."""
    V = function.function_space
    n = V.dofmap.index_map.size_local
    bs = V.dofmap.index_map_bs
    return points(problem, V)[:n], function.x.array[:n * bs].reshape(n, bs)


def match_points(stored: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """For each wanted point, the row of ``stored`` at the same place, with a tolerance
    relative to the mesh: MATCH_TOLERANCE times the smallest distance between two stored
    points (a node spacing or cell size, scale-free: a body of 1e-9 m matches as one of
    1 m, whose coordinates an absolute rounding to 1e-10 m would merge), and at least
    round-off of the coordinates' magnitude.

    Args:
        stored: (m, dim) coordinates of the checkpoint's nodes or cell midpoints.
        wanted: (k, dim) coordinates of this rank's nodes or cells.

    Returns:
        (k,) indices into ``stored``.

    Raises:
        ValueError: two stored points coincide (relative to the body's size), or a wanted
            point has no stored point within the tolerance (the message says which).
    """
    from scipy.spatial import cKDTree
    tree = cKDTree(stored)
    magnitude = float(np.abs(stored).max(initial=0.0))
    size = float(np.ptp(stored, axis=0).max()) if len(stored) else 0.0
    spacing = float(tree.query(stored, k=2)[0][:, 1].min()) if len(stored) > 1 else size
    roundoff = 64 * np.finfo(float).eps * magnitude
    if len(stored) > 1 and spacing <= max(1e-12 * size, roundoff):
        raise ValueError(f"two of its points coincide (spacing {spacing:.3g} m, body "
                         f"{size:.3g} m)")
    tol = max(MATCH_TOLERANCE * spacing, roundoff)
    if len(wanted) == 0:
        return np.zeros(0, dtype=np.int64)
    dist, index = tree.query(wanted)
    far = int(np.argmax(dist))
    if dist[far] > tol:
        raise ValueError(f"a point of the mesh, {wanted[far].tolist()}, is {dist[far]:.3g} m "
                         f"from the nearest stored one (tolerance {tol:.3g} m)")
    return index


def _gather(comm, x, v):
    parts = comm.gather((x, v), root=0)
    if comm.rank != 0:
        return None, None
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


def save(outdir: Path, sim) -> Path:
    """Write the state after step n to outdir/checkpoint_<n>.npz (collective); older
    checkpoints beyond the newest KEEP are removed.

    Args:
        outdir: the run's output directory.
        sim: the Simulation (its comm, case, problem and its State, stepper, n, t and step
            records).

    Returns:
        The checkpoint's path.

    Raises:
        OutputError: the file could not be written (on every rank).
    """
    comm, problem, state = sim.comm, sim.problem, sim.problem.state
    path = Path(outdir) / file_name(sim.n)
    laws = api_laws(sim) if comm.rank == 0 else None
    arrays = {}
    for name, f in state.fields().items():
        x, v = _gather(comm, *_owned_rows(problem, f))
        if comm.rank == 0:
            arrays[f"{name}_x"], arrays[f"{name}_v"] = x, v
    g3 = state.gamma3.state() if state.gamma3 is not None else None
    if g3 is not None:
        _gamma3_arrays(comm, problem, g3, arrays)
    _time_error_arrays(comm, sim, arrays)
    if comm.rank == 0:
        st = sim.stepper.state()
        mem = g3["memory"] if g3 is not None else None
        groups = group_map(problem.disc.body)
        meta = {"n": sim.n, "t": sim.t, "fingerprint": case_fingerprint(sim.case, laws),
                "case_key": case_key(sim.case, groups, laws), "groups": groups,
                "steps": sim.steps,
                "stepper": {"adaptive": st["adaptive"], "n": st["n"], "k": st["k"],
                            "history": st["decisions"]},
                "memory": None if mem is None else {"t_prev": mem["t_prev"], "k": mem["k"]}}
        if laws:                          # the laws given through the Python API
            meta["laws"] = laws
        module = law_module(sim.case)
        if module is not None:            # the case's python laws: --law-module's file
            meta["law_module"] = module
        arrays["meta"] = np.array(json.dumps(meta))
    on_rank0(comm, _write, path, arrays, outdir)    # OutputError on every rank if it fails
    return path


def _gamma3_arrays(comm, problem, g3: dict, arrays: dict) -> None:
    """The Gamma3 history's nodal values (xi_n, the direct sum's u_nu^+ history, s_n, the
    Coulomb p_n, the slip path's u_{n-1,tau} and accumulated slip) at the owned Gamma3
    nodes, with their coordinates, gathered into ``arrays`` on rank 0."""
    disc = problem.disc
    own = disc.gamma3.nodes                       # owned Gamma3 nodes (local index)
    pos = np.searchsorted(disc.gamma3_local_nodes, own)
    xg = disc.V.tabulate_dof_coordinates()[own]
    cols = {}
    mem, slip = g3["memory"], g3["slip"]
    if mem is not None:
        cols["xi"] = mem["xi"][pos][:, None]
        if mem["r"]:                                 # the direct sum's stored steps
            cols["mem_r"] = np.asarray(mem["r"])[:, pos].T
    if slip is not None:
        cols["slip_s"] = slip["s"][pos][:, None]
    if g3.get("coulomb") is not None:
        cols["coulomb_p"] = g3["coulomb"]["p"][pos][:, None]
    path = g3.get("path")
    if path is not None and path["prev"] is not None:      # the slip path after step 1
        cols["path_prev"] = path["prev"][pos]
        cols["path_length"] = path["length"][pos][:, None]
    for name, v in cols.items():
        x, vv = _gather(comm, xg, v)
        if comm.rank == 0:
            arrays[f"g3_{name}_x"], arrays[f"g3_{name}_v"] = x, vv


def _time_error_arrays(comm, sim, arrays: dict) -> None:
    """The error estimate's time error (``est_dH``, ``est_dkappa``) at the owned cells and
    its Gamma3 sums (``est_g3_right``, ``est_g3_ds``: app/post/gamma3error.py) at the owned
    Gamma3 nodes, with their coordinates, gathered into ``arrays`` on rank 0 (what the
    estimate has, if finite: a restart starts the rest from zero)."""
    estimate, problem = getattr(sim, "estimate", None), sim.problem
    if estimate is None:
        return
    err = estimate.time.state() if estimate.time is not None else None
    disc = problem.disc
    n = disc.num_owned_cells
    cols = {} if err is None else {
        name: (points(problem, problem.state.H.function_space)[:n], v[:n])
        for name, v in err.items()}
    if estimate.gamma3 is not None:
        own = disc.gamma3.nodes
        pos = np.searchsorted(disc.gamma3_local_nodes, own)
        xg = disc.V.tabulate_dof_coordinates()[own]
        cols.update({f"g3_{name}": (xg, v[pos][:, None])
                     for name, v in estimate.gamma3.state().items() if v is not None})
    for name, (x, v) in cols.items():
        gx, gv = _gather(comm, x, v)
        if comm.rank == 0 and np.isfinite(gv).all():    # overflowed rates: not stored
            arrays[f"est_{name}_x"], arrays[f"est_{name}_v"] = gx, gv


def _write(path: Path, arrays: dict, outdir) -> None:
    """Write the checkpoint atomically (a failed write leaves no partial file) and remove
    checkpoints beyond the newest KEEP."""
    tmp = path.with_name(f".{path.name}.tmp.npz")
    try:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except OSError:
        tmp.unlink(missing_ok=True)
        raise
    for old in sorted(Path(outdir).glob(PATTERN))[:-KEEP]:
        old.unlink()


class CheckpointError(CaseError):
    """A checkpoint that a run cannot continue from (bad input: the CLI prints the message
    as one line and exits with code 2)."""

    def __init__(self, path, why: str):
        super().__init__(f"--restart: {path} is not a readable checkpoint: {why}")
        self.path, self.why = path, why


STEP_KEYS = ("n", "t", "norm_u_V", "norm_sigma_Q", "norm_kappa_Y", "max_vm", "max_kappa",
             "newton_iterations", "wall_s")


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _integer(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _group_map(groups) -> bool:
    """Whether ``groups`` is a ``casekey.group_map``: facet and cell names -> tags."""
    return isinstance(groups, dict) and all(
        isinstance(groups.get(kind), dict) and all(
            isinstance(k, str) and _integer(v) for k, v in groups[kind].items())
        for kind in ("facets", "cells"))


def _check_meta(meta) -> str | None:
    """Why the checkpoint's meta data is unusable (types and internal consistency), or None."""
    if not isinstance(meta, dict):
        return f"meta is a {type(meta).__name__}, not a mapping"
    for key in ("n", "t", "fingerprint", "steps", "stepper", "memory"):
        if key not in meta:
            return f"meta: '{key}' is missing"
    n, t, steps, st = meta["n"], meta["t"], meta["steps"], meta["stepper"]
    if not _integer(n) or n < 0:
        return f"meta: n = {n!r} is not a step number"
    if not _number(t) or t < 0:
        return f"meta: t = {t!r} is not a time"
    if not isinstance(meta["fingerprint"], str):
        return "meta: fingerprint is not a string"
    if "case_key" in meta and not (isinstance(meta["case_key"], str) and _group_map(
            meta.get("groups"))):
        return "meta: case_key is not a string with the mesh's groups"
    if not isinstance(steps, list) or len(steps) != n:
        return f"meta: steps is not a list of {n} step records"
    for i, rec in enumerate(steps):
        if not isinstance(rec, dict) or not all(_number(rec.get(k)) for k in STEP_KEYS) \
                or rec["n"] != i + 1 or not _integer(rec["newton_iterations"]):
            return f"meta: steps[{i}] is not the record of step {i + 1}"
    if not isinstance(st, dict) or not isinstance(st.get("adaptive"), bool) \
            or not isinstance(st.get("history"), list) \
            or not all(isinstance(h, dict) for h in st["history"]):
        return "meta: stepper is not a stepper state (adaptive, n, k, history)"
    if st["adaptive"] and not (_number(st.get("k")) and st["k"] > 0):
        return f"meta: stepper.k = {st.get('k')!r} is not a positive step"
    if not st["adaptive"] and st.get("n") != n:
        return f"meta: stepper.n = {st.get('n')!r} is not the step number {n}"
    if not isinstance(meta.get("laws", {}), dict):
        return "meta: laws is not a mapping of the laws given through the Python API"
    mem = meta["memory"]
    if mem is not None and not (isinstance(mem, dict) and all(
            isinstance(mem.get(k), list) and all(_number(x) for x in mem[k])
            for k in ("t_prev", "k")) and len(mem["t_prev"]) == len(mem["k"])):
        return "meta: memory is not a memory-term state (t_prev, k: lists of equal length)"
    return None


def _check_arrays(arrays: dict) -> str | None:
    """Why the stored fields are unusable: every ``<name>_x`` (coordinates) needs its
    ``<name>_v`` (values), both finite float tables with the same number of rows."""
    names = {k[:-2] for k in arrays if k.endswith(("_x", "_v"))}
    for name in sorted(names):
        x, v = arrays.get(f"{name}_x"), arrays.get(f"{name}_v")
        if x is None or v is None:
            return f"'{name}_{'x' if x is None else 'v'}' is missing"
        for key, a in ((f"{name}_x", x), (f"{name}_v", v)):
            if a.dtype.kind != "f" or a.ndim != 2:
                return f"'{key}' is not a table of floats (dtype {a.dtype}, shape {a.shape})"
            if not np.isfinite(a).all():
                return f"'{key}' holds values that are not finite"
        if len(x) != len(v):
            return f"'{name}': {len(x)} coordinates but {len(v)} values"
    return None


def _required(case) -> dict[str, int | None]:
    """The fields a checkpoint of ``case`` must hold, with their values per node/cell (None:
    the law's number m of internal variables, checked when the field is restored)."""
    d = case.dim
    need = {"u": d, "sigma": d * d}
    vp = next((m.viscoplastic for m in case.all_materials if m.viscoplastic), None)
    if vp is not None or case.initial.u0 is not None or case.initial.sigma0 is not None:
        need["H"] = d * d
    if vp is not None:          # the law's m columns, checked against the State's kappa
        need["kappa"] = None    # when it is restored (_restore_fields)
    for c in case.contact.sections:        # the contact section, or each pair's laws
        if c.memory is not None:
            need["g3_xi"] = 1
        coulomb = getattr(c.friction, "coulomb", None)
        if c.friction is not None and (c.friction.slip is not None
                                       or coulomb is not None and coulomb.has_slip):
            need["g3_slip_s"] = 1
        if coulomb is not None:
            need["g3_coulomb_p"] = 1
    return need


class Checkpoint:
    """A loaded and checked checkpoint; ``restore`` puts its state into a freshly set-up run.
    Every problem with the file's content raises CheckpointError.

    Args:
        path: the checkpoint file.

    Raises:
        CheckpointError: the file is unreadable or its content inconsistent.
    """

    def __init__(self, path: Path):
        self.path = path
        # set by restore(): the estimate's delta and Gamma3 sums, or None (none stored)
        self.time_error = self.gamma3_error = None
        try:
            with np.load(path, allow_pickle=False) as data:
                self.arrays = {k: data[k] for k in data.files}
            meta = self.arrays.pop("meta", None)
            if meta is None:
                raise CheckpointError(path, "'meta' is missing")
            self.meta = json.loads(str(meta))
        except CheckpointError:
            raise
        except Exception as exc:                  # noqa: BLE001 (any unreadable file)
            raise CheckpointError(path, f"{type(exc).__name__}: {exc}") from None
        why = _check_meta(self.meta) or _check_arrays(self.arrays)
        if why:
            raise CheckpointError(path, why)

    @property
    def n(self) -> int:
        """The step n the checkpoint was written after."""
        return self.meta["n"]

    @property
    def t(self) -> float:
        """The time t_n of that step."""
        return self.meta["t"]

    def check(self, case) -> str | None:
        """Whether the checkpoint belongs to ``case``.

        Args:
            case: the validated Case of the restart.

        Returns:
            None if it does, else the reason it does not.

        Raises:
            CheckpointError: it does, but lacks what a restart of the case needs.
        """
        if self.meta.get("laws"):
            return (f"{self.path} was written with laws given through the Python API "
                    f"({_laws_text(self.meta['laws'])}): continue it from the Python API "
                    "with the same laws")
        stored, given = self.meta.get("law_module"), law_module(case)
        if stored is not None and given is not None and stored["sha256"] != given["sha256"]:
            return (f"{self.path} was written with the law module {stored['path']} (SHA-256 "
                    f"{stored['sha256'][:12]}...); --law-module {given['path']} differs "
                    f"(SHA-256 {given['sha256'][:12]}...): an edited law module is another "
                    "law; restart with the module the run was written with, or start anew")
        key = self.meta.get("case_key")      # checkpoints written before it: as written
        if (case_key(case, self.meta["groups"]) if key is not None
                else case_fingerprint(case)) != (key or self.meta["fingerprint"]):
            return (f"{self.path} was written for a different case (mesh, material, contact, "
                    "loads, initial values or time grid differ)")
        for name, cols in _required(case).items():
            v = self.arrays.get(f"{name}_v")
            if v is None:
                raise CheckpointError(self.path, f"'{name}_v' is missing")
            if cols is not None and v.shape[1] != cols:
                raise CheckpointError(self.path, f"'{name}_v' has {v.shape[1]} values per row, "
                                                 f"not {cols}")
        self._check_time(case)
        mem = self.meta["memory"]
        if (mem is None) != all(c.memory is None for c in case.contact.sections):
            raise CheckpointError(self.path, "meta: memory does not match the case's memory term")
        stored = self.arrays["g3_mem_r_v"].shape[1] if "g3_mem_r_v" in self.arrays else 0
        if mem is not None and stored != len(mem["t_prev"]):
            raise CheckpointError(self.path, f"'g3_mem_r_v' holds {stored} steps of the memory "
                                             f"term, meta {len(mem['t_prev'])}")
        return None

    def _check_time(self, case) -> None:
        """Step n and time t on the case's time grid (adaptive: within [0, T])."""
        n, t, times = self.n, self.t, case.time.times
        if self.meta["stepper"]["adaptive"] != (case.time.adaptive is not None):
            raise CheckpointError(self.path, "meta: stepper.adaptive does not match the case")
        if case.time.adaptive is not None:
            if t > case.time.T * (1 + 1e-12):
                raise CheckpointError(self.path, f"meta: t = {t:g} is after T = {case.time.T:g}")
        elif n >= len(times) or abs(times[n] - t) > 1e-12 * max(1.0, abs(t)):
            raise CheckpointError(self.path, f"meta: step {n} at t = {t:g} is not on the case's "
                                             "time grid")
        if self.meta["steps"] and abs(self.meta["steps"][-1]["t"] - t) > 1e-12 * max(1.0, t):
            raise CheckpointError(self.path, "meta: the last step record is not at t")

    def _lookup(self, name: str, x_local: np.ndarray, rows: int) -> np.ndarray:
        """The values of ``name`` at the local coordinates ``x_local``; ``rows`` is the
        global number of nodes or cells the checkpoint must hold."""
        x, values = self.arrays.get(f"{name}_x"), self.arrays.get(f"{name}_v")
        if x is None:
            raise CheckpointError(self.path, f"'{name}_x' is missing")
        if len(x) != rows:
            raise CheckpointError(self.path, f"'{name}' holds {len(x)} rows, the mesh has "
                                             f"{rows} nodes or cells for it")
        if x.shape[1] != x_local.shape[1]:
            raise CheckpointError(self.path, f"'{name}_x' has {x.shape[1]} coordinates per "
                                             f"row, not {x_local.shape[1]}")
        try:
            index = match_points(x, x_local)
        except ValueError as exc:
            raise CheckpointError(self.path, f"the mesh does not match '{name}': {exc}") \
                from None
        return values[index].reshape(len(index), *values.shape[1:])

    def restore(self, sim) -> list:
        """Set the fields and the history terms of a freshly set-up run to the checkpoint's.
        Collective: if the checkpoint does not fit the problem on any rank, CheckpointError
        on all.

        Args:
            sim: the Simulation (its problem with its State, and stepper are set).

        Returns:
            The step records up to step n.

        Raises:
            CheckpointError: the checkpoint does not fit the problem.
        """
        problem = sim.problem
        disc = problem.disc
        comm = disc.comm
        self.check_laws(sim)
        n_g3 = comm.allreduce(len(disc.gamma3.nodes) if disc.gamma3 is not None else 0)
        try:
            self._restore_fields(problem, problem.state, n_g3)
            self._restore_time_error(problem, problem.state, n_g3)
            why = None
        except CheckpointError as exc:
            why = exc.why
        why = next((w for w in comm.allgather(why) if w), None)
        if why:
            raise CheckpointError(self.path, why)
        st = self.meta["stepper"]
        sim.stepper.load_state({"adaptive": st["adaptive"], "n": st.get("n"),
                                "k": st.get("k"), "decisions": st["history"]})
        problem.update_vm()
        return list(self.meta["steps"])

    def check_laws(self, sim) -> None:
        """The laws given through the Python API must be the checkpointed run's (the same
        classes, names, constants and attributes: ``law_identity``); collective (rank 0
        compares, so every rank refuses alike).

        Args:
            sim: the Simulation of the restart (set up).

        Raises:
            CaseError: on every rank, if they differ (the message names both).
        """
        why = None
        if sim.comm.rank == 0:
            stored, given = self.meta.get("laws"), api_laws(sim)
            if stable_json(stored or {}) != stable_json(given or {}):
                why = (f"restart from {self.path}: the laws given through the Python API "
                       f"differ from the checkpointed run's (checkpoint: "
                       f"{_laws_text(stored)}; this run: {_laws_text(given)})")
        why = sim.comm.bcast(why, root=0)
        if why:
            raise CaseError(why)

    def _restore_fields(self, problem, state, n_g3: int) -> None:
        """The State's fields u, sigma, H, kappa and its Gamma3 history (local, no
        collectives)."""
        g3 = state.gamma3
        for name, f in state.fields().items():
            V = f.function_space
            x = points(problem, V)                     # owned and ghost: no scatter needed
            values = self._lookup(name, x, V.dofmap.index_map.size_global)
            if values.size != f.x.array.size:
                raise CheckpointError(self.path, f"'{name}_v' has {values.shape[1]} values "
                                                 f"per row, not {V.dofmap.index_map_bs}")
            f.x.array[:] = values.reshape(-1)
        if g3 is None:
            return
        xg = problem.disc.V.tabulate_dof_coordinates()[problem.disc.gamma3_local_nodes]
        state = {"memory": None, "slip": None}
        if g3.memory is not None:
            mem = self.meta["memory"]
            xi = self._lookup("g3_xi", xg, n_g3)[:, 0].copy()
            r = self._lookup("g3_mem_r", xg, n_g3) if "g3_mem_r_x" in self.arrays else None
            state["memory"] = {"xi": xi, "t_prev": mem["t_prev"], "k": mem["k"],
                               "r": [] if r is None else [r[:, j].copy()
                                                          for j in range(r.shape[1])]}
        if g3.slip is not None:
            state["slip"] = {"s": self._lookup("g3_slip_s", xg, n_g3)[:, 0].copy()}
        if g3.coulomb is not None:
            state["coulomb"] = {"p": self._lookup("g3_coulomb_p", xg, n_g3)[:, 0].copy()}
        if g3.path is not None and "g3_path_length_x" in self.arrays:
            state["path"] = {"prev": self._lookup("g3_path_prev", xg, n_g3).copy(),
                             "length": self._lookup("g3_path_length", xg, n_g3)[:, 0].copy()}
        g3.load_state(state)

    def _restore_time_error(self, problem, state, n_g3: int) -> None:
        """``time_error``: the error estimate's delta H, delta kappa at the local cells (owned
        and ghost); ``gamma3_error``: its Gamma3 sums at the local Gamma3 nodes; each None
        if the checkpoint has none (local, no collectives)."""
        if state.H is not None and {"est_dH_x", "est_dkappa_x"} <= self.arrays.keys():
            V = state.H.function_space
            x, rows = points(problem, V), V.dofmap.index_map.size_global
            self.time_error = {name: self._lookup(f"est_{name}", x, rows).copy()
                               for name in ("dH", "dkappa")}
        names = [k for k in ("right", "ds") if f"est_g3_{k}_x" in self.arrays]
        disc = problem.disc
        if names and disc.gamma3 is not None:
            xg = disc.V.tabulate_dof_coordinates()[disc.gamma3_local_nodes]
            self.gamma3_error = {k: self._lookup(f"est_g3_{k}", xg, n_g3)[:, 0].copy()
                                 for k in names}
