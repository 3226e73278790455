"""The bench's yardstick: one elasticity solve on a row's mesh, timed in the same bench run.

Machines differ by 1.5-2x (docs/performance.md, section 8), so every bench row also gives
its times as ratios to a reference measured in the same bench run on the same mesh: the
elasticity matrix K = (eps(u), eps(v)) on V^h (P1, every boundary facet clamped)
assembled, factorised and solved once for a load of ones, with the linear solver SNES VI
would take on that mesh (``choose_linear``: its serial LU, or above AUTO_AMG_MIN_DOFS
in 3D, where LU's fill would not fit, CG + GAMG with the rigid body modes).  The form is
compiled and the mesh built before the clock starts; the fastest of ``REPEAT`` timings
counts.  It runs as a process of its own (``python -m vpcontact.studies.benchref CASE --set
...``, one JSON line on stdout), serial, with the runs' environment (benchrun.ENV), so the
bench's own process stays free of MPI.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

from vpcontact.studies.benchrun import ENV, stop_child

REPEAT = 3                   # timed solves per reference: the fastest counts
PREFIX = "benchref_"         # the reference KSP's PETSc options (its own process)
TIMES = ("wall_s", "setup_s", "loop_s", "steps_s", "step_median_s")   # a row's seconds


def measure(case, mesh_overrides: list[str]) -> dict:
    """The reference of a case's mesh, in a process of its own.

    Args:
        case: the case file.
        mesh_overrides: the --set items that make the row's mesh (e.g. ``mesh.n=64``).

    Returns:
        {"reference_s": fastest seconds, "reference_runs_s": all of them, "reference_dofs",
        "reference_solver": "lu" or "cg+gamg"}.

    Raises:
        RuntimeError: the reference process failed (the end of its error output).
    """
    cmd = [sys.executable, "-m", "vpcontact.studies.benchref", str(case)]
    for item in mesh_overrides:
        cmd += ["--set", item]
    proc = subprocess.Popen(cmd, env={**os.environ, **ENV}, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        stdout, stderr = proc.communicate()
    except BaseException:          # SIGINT/SIGTERM to the bench: the reference ends with it
        stop_child(proc)
        raise
    if proc.returncode != 0:
        raise RuntimeError(f"bench reference failed ({' '.join(cmd)}): "
                           f"{stderr.strip()[-300:]}")
    return json.loads(stdout.strip().splitlines()[-1])


class References:
    """The references of one bench run, each mesh measured once (``measure``, or a stand-in
    with its signature)."""

    def __init__(self, measure=measure, log=print):
        self.measure, self.log, self.known = measure, log, {}

    def attach(self, row: dict, case, mesh_overrides: list[str]) -> dict:
        """Add the reference of the row's mesh and the row's times as ratios to it.

        Args:
            row: a bench row (its seconds under TIMES' keys).
            case: the row's case file.
            mesh_overrides: the --set items of the row's mesh.

        Returns:
            The row, with "reference_s", "reference_dofs", "reference_solver" and
            "<time>_ratio" = "<time>_s" / reference_s for each of its TIMES; or with the
            reason under "reference_failed".
        """
        key = (str(Path(case).resolve()), tuple(mesh_overrides))
        if key not in self.known:
            try:
                self.known[key] = self.measure(case, list(mesh_overrides))
            except RuntimeError as exc:
                self.known[key] = {"reference_failed": str(exc).strip().splitlines()[-1]}
            ref = self.known[key]
            self.log(f"  reference {' '.join([Path(case).name, *mesh_overrides])}: " + (
                f"{ref['reference_s']:.3g} s ({ref['reference_solver']}, "
                f"{ref['reference_dofs']} dofs)" if "reference_s" in ref
                else f"FAILED: {ref['reference_failed']}"))
        return with_ratios(row, self.known[key])


def with_ratios(row: dict, ref: dict) -> dict:
    """The row with the reference's entries and its times as ratios to reference_s.

    Args:
        row: a bench row.
        ref: a reference (``measure``'s dict, or one with "reference_failed").

    Returns:
        The row (changed in place).
    """
    row.update(ref)
    if "reference_s" in ref:
        for key in TIMES:
            if row.get(key) is not None:
                row[f"{key[:-2]}_ratio"] = row[key] / ref["reference_s"]
    return row


# bench.md's note on the reference columns
REFERENCE_TEXT = ("Reference = one elasticity matrix assembly, factorisation (LU; CG + GAMG "
                  "set-up in 3D above 20,000 dofs) and solve on the row's mesh, serial, "
                  "timed in the same bench run (fastest of 3); x / ref = the row's seconds "
                  "over it, comparable between machines.")


def reference_cells(row: dict, keys) -> list[str]:
    """bench.md's cells of a row's reference.

    Args:
        row: a bench row.
        keys: its ratio keys to show (e.g. ``wall_ratio``).

    Returns:
        The reference's seconds ("failed" or "-" without one), then the ratios.
    """
    if "reference_s" not in row:
        return ["failed" if "reference_failed" in row else "-"] + ["-"] * len(keys)
    return [f"{row['reference_s']:.3g}", *(ratio_text(row, k) for k in keys)]


def ratio_text(row: dict, key: str) -> str:
    """A ratio for bench.md.

    Args:
        row: a bench row.
        key: its ratio key (e.g. ``wall_ratio``).

    Returns:
        "12.3x" (three digits, whole numbers from 100x), "-" where there is none.
    """
    value = row.get(key)
    if value is None:
        return "-"
    return f"{value:.0f}x" if value >= 100 else f"{value:.3g}x"


def _solve_once(msh, linear: str) -> float:
    """Seconds of one assembly of K, its factorisation (or AMG set-up) and one solve."""
    import ufl
    from dolfinx import fem
    from dolfinx.mesh import exterior_facet_indices
    from petsc4py import PETSc

    from vpcontact.forms.elasticity import eps
    from vpcontact.solvers.snesvi import direct_solver

    V = fem.VectorFunctionSpace(msh, ("CG", 1))
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    dofs = fem.locate_dofs_topological(V, tdim - 1, exterior_facet_indices(msh.topology))
    bc = fem.dirichletbc(PETSc.ScalarType((0.0,) * tdim), dofs, V)
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    a = fem.form(ufl.inner(eps(u), eps(v)) * ufl.dx)         # compiled before the clock
    t0 = time.perf_counter()
    K = fem.petsc.create_matrix(a)
    fem.petsc.assemble_matrix(K, a, bcs=[bc])
    K.assemble()
    ksp = direct_solver(K, msh.comm) if linear == "direct" else _amg(K, V)
    b, x = K.createVecRight(), K.createVecRight()
    b.set(1.0)
    fem.petsc.set_bc(b, [bc])
    ksp.setUp()
    ksp.solve(b, x)
    seconds = time.perf_counter() - t0
    if ksp.getConvergedReason() < 0:
        raise RuntimeError(f"the reference solve did not converge ({ksp.getConvergedReason()})")
    for obj in (ksp, K, b, x):
        obj.destroy()
    return seconds


def _amg(K, V):
    """CG + GAMG on K as SNES VI's iterative path sets them up (amg.AMG_PETSC, its PC
    options without their prefix), the rigid body modes as near-nullspace; rtol 1e-8."""
    from petsc4py import PETSc

    from vpcontact.solvers.amg import AMG_PETSC, AMG_PREFIX, near_nullspace, rigid_body_modes
    from vpcontact.solvers.options import push_options

    K.setNearNullSpace(near_nullspace(rigid_body_modes(V), K))
    ksp = PETSc.KSP().create(K.getComm())
    ksp.setOptionsPrefix(PREFIX)
    ksp.setOperators(K)
    push_options({**{k: AMG_PETSC[k] for k in ("ksp_type", "ksp_rtol", "ksp_max_it")},
                  **{k[len(AMG_PREFIX):]: v for k, v in AMG_PETSC.items()
                     if k.startswith(AMG_PREFIX)}}, PREFIX)
    ksp.setFromOptions()
    return ksp


def main(argv: list[str]) -> None:
    """The reference process: prints the measurement as JSON (its threads from
    benchrun.ENV, as the runs').

    Args:
        argv: ``CASE [--set k=v ...]``.
    """
    from mpi4py import MPI

    from vpcontact.case import load_raw, validate
    from vpcontact.simulation import build_mesh
    from vpcontact.solvers.choice import choose_linear

    case_file, overrides = argv[0], [s for s in argv[1:] if s != "--set"]
    case = validate(load_raw(case_file, overrides), case_file)
    msh = build_mesh(case, MPI.COMM_SELF).mesh
    dofs = msh.geometry.dim * msh.topology.index_map(0).size_global
    linear = "amg" if choose_linear(case, dofs) == "amg" else "direct"
    runs = [_solve_once(msh, linear) for _ in range(REPEAT + 1)][1:]   # the first: warm-up
    print(json.dumps({"reference_s": min(runs), "reference_runs_s": runs,
                      "reference_dofs": dofs,
                      "reference_solver": "cg+gamg" if linear == "amg" else "lu"}))
    sys.stdout.flush()


if __name__ == "__main__":
    main(sys.argv[1:])
