"""`check` (dry run) and `info`: what a run would do, and what it runs on."""
from __future__ import annotations

import os


def report(case, comm) -> list[str]:
    """Validate-and-set-up report of a case: mesh, dofs, steps, terms, solver, the laws and
    materials (app/post/lawreport.py), diagnostics.  Builds the mesh, spaces and forms (JIT)
    but solves nothing and writes nothing.

    Args:
        case: the validated Case.
        comm: the MPI communicator.

    Returns:
        The report's lines.
    """
    import numpy as np

    from vpcontact.case import rescale_for_length
    from vpcontact.model.datapoints import check_data_on_mesh
    from vpcontact.model.gamma3 import build_gamma3_history
    from vpcontact.model.problem import ContactProblem
    from vpcontact.post.diagnostics import diagnose
    from vpcontact.post.lawreport import law_lines, law_report
    from vpcontact.post.pairreport import pair_lines
    from vpcontact.simulation import build_mesh
    from vpcontact.solvers import choose_method, condensed_eligible, gamma3_dofs

    body = build_mesh(case, comm)
    if case.mesh.file is not None:      # as Simulation.setup: the data on the mesh's points
        lo, hi = body.bbox
        case = rescale_for_length(case, float(np.max(hi - lo)), check_data_on_mesh(case, body))
    problem = ContactProblem(case, body)
    disc = problem.disc
    ks = np.diff(case.time.times)
    n_dofs = gamma3_dofs(disc)
    n_g = n_dofs // disc.dim
    ok, why = condensed_eligible(case, disc)
    method = choose_method(case, n_dofs, disc)
    m = case.mesh
    if m.file is not None:
        mesh = f"{m.file}, h = {body.h_min:.3g}..{body.h:.3g}"
    else:
        mesh = (f"structured {m.n} x {m.n}" + (f" x {m.n}" if m.dim == 3 else "")
                if m.kind == "structured" else f"unstructured, h = {m.h:g}")
    groups = ", ".join(f"{name} ({tag})" for name, tag in sorted(body.groups.items(),
                                                                 key=lambda kv: kv[1]))
    b = case.boundaries
    pairs = ", ".join(f"{p.surface} -> {p.target}" for p in case.contact.pairs)
    lines = [
        f"case {case.name} ({case.source}): valid",
        f"mesh: {m.dim}D, {mesh}, {disc.num_cells} cells, {disc.num_vertices} vertices",
        f"boundary groups: {groups or 'none'}; clamped: {', '.join(map(str, b.clamped)) or '-'}"
        + (f"; contact pairs: {pairs}" if pairs
           else f"; contact: {', '.join(map(str, b.contact)) or '-'}")
        + (f"; displacement: {', '.join(map(str, case.loads.displacement))}"
           if case.loads.displacement else "")
        + (f"; rigid caps: {', '.join(map(str, case.loads.rigid))}"
           if case.loads.rigid else ""),
        f"dofs: {disc.num_dofs} (P1 displacement), Gamma3 nodes: {n_g}",
        f"time: T = {case.time.T:g}, {case.time.N} steps, k = "
        + (f"{ks[0]:g}" if case.time.uniform else f"{ks.min():g}..{ks.max():g}")
        + f", {case.time.scheme} history scheme"
        + (", adaptive" if case.time.adaptive is not None else ""),
        "active terms: " + ", ".join(case.active_terms()),
        "left out: " + (", ".join(case.omitted_terms()) or "nothing"),
        f"step solver: {method}" + (" (solver.method: auto)" if case.numerics.method == "auto"
                                    else "") + ("" if ok else f"; condensed not possible: {why}"),
    ]
    if problem.materials:        # one material per group of cells (app/model/materials.py)
        counts = problem.materials.cell_counts(disc.num_owned_cells, disc.comm)
        lines.insert(4, "cell groups (materials): " + ", ".join(
            f"{ref} (tag {tag}, {n} cells)" for ref, tag, n in counts))
    lines += pair_lines(disc)            # two bodies: each pair (app/post/pairreport.py)
    diag = diagnose(problem)
    lines += law_lines(law_report(problem, build_gamma3_history(case, problem)), diag)
    lines += [text for _, text in diag.messages()]
    lines.append(f"outputs every {case.output.every} step(s)"
                 + (f", checkpoints every {case.output.checkpoint_every}"
                    if case.output.checkpoint_every else "") + "; nothing solved or written")
    return lines


def info() -> list[str]:
    """Versions of the numerical stack and where the JIT caches are.

    Returns:
        The lines of ``vpcontact info``.
    """
    import basix
    import dolfinx
    import ffcx
    import numpy
    import ufl
    from mpi4py import MPI
    from petsc4py import PETSc

    from vpcontact import __version__
    from vpcontact.cachepaths import caches

    v = PETSc.Sys.getVersion()
    pkgs = ["mumps", "superlu_dist", "suitesparse", "hypre", "metis", "parmetis", "scalapack",
            "ptscotch", "hdf5"]
    have = [p for p in pkgs if PETSc.Sys.hasExternalPackage(p)]
    try:
        from vpcontact.meshes.gmshfile import import_gmsh
        gmsh_v = import_gmsh().__version__
    except Exception as exc:  # noqa: BLE001
        gmsh_v = f"not importable ({exc})"
    dirs = caches()
    lib = MPI.Get_library_version().strip().splitlines()[0]
    return [
        f"vpcontact {__version__}",
        f"dolfinx {dolfinx.__version__} (git {dolfinx.git_commit_hash[:10]}), "
        f"ufl {ufl.__version__}, ffcx {ffcx.__version__}, basix {basix.__version__}",
        f"PETSc {v[0]}.{v[1]}.{v[2]} (petsc4py, scalar {PETSc.ScalarType.__name__}), "
        f"external packages: {', '.join(have) or 'none found'}",
        f"MPI: {lib} (MPI {'.'.join(map(str, MPI.Get_version()))})",
        f"gmsh {gmsh_v}, numpy {numpy.__version__}",
        f"JIT cache (FFCx): {dirs.ffcx}",
        f"compiled kernels (cffi): {dirs.kernels}",
        f"run cache (convergence study): {dirs.root}",
        *[f"(not writable: {what} {wanted} ({why}); using {used})"
          for what, wanted, used, why in dirs.replaced],
        f"python: {os.sys.executable}",
    ]
