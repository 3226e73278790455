"""Which PETSc options a user may give: an allow-list, checked before PETSc sees an option.

A case file is data from anyone, and PETSc options can do more than tune a solver: a
``python`` type (``pc_type: python`` with ``pc_python_type: module.Class``, likewise for KSP,
SNES and Mat) makes petsc4py import and call Python code; a viewer or monitor with an
argument (``ksp_monitor: ascii:/path``, ``snes_view: binary:``, ``draw``) creates or
truncates a file anywhere or opens a window; ``options_file`` reads further options from a
file.  So every option given by the case file's ``petsc`` section, ``--set petsc.*`` or the
command line (app/solvers/optioncheck.py check_petsc_options, before any computation) must:
- be named by a family of ALLOWED (solver and preconditioner types, tolerances, iteration
  counts, line search, Eisenstat-Walker, factorisation, GAMG/MG/hypre/Jacobi/SOR/ASM and
  block Jacobi settings, MUMPS and SuperLU_DIST controls), or by VIEWERS (monitors, views
  and converged reasons written to standard output), after the sub-solver prefixes
  SUBSOLVER_PREFIXES (``fast_`` for the condensed solver, ``amg_`` for the inner multigrid,
  ``mg_levels_``, ``mg_coarse_``, ``sub_`` for PETSc's own sub-solvers);
- have a value that loads no code and names no file: not ``python``; for VIEWERS only a flag
  (no value, true, false) or standard output (``ascii``, ``ascii::<format>``); any other text
  of letters, digits and ``. _ + -`` only.
"""
from __future__ import annotations

import re

# the project's own options of the inner multigrid (app/solvers/amg.py AMGSolver._option)
PROJECT_OPTIONS = ("keep_levels", "incremental", "fine_sbaij", "reuse")
SUBSOLVER_PREFIXES = re.compile(r"^(fast_|amg_|mg_levels_(\d+_)?|mg_coarse_|sub_)")
ALLOWED = re.compile("|".join((
    r"(snes|ksp|pc|snes_linesearch)_type",
    r"snes_(rtol|atol|stol|max_it|max_funcs|max_fail|max_linear_solve_fail|"
    r"divergence_tolerance|lag_jacobian|lag_preconditioner|force_iteration|"
    r"error_if_not_converged|vi_zero_tolerance)",
    r"snes_linesearch_(damping|max_it|order|minlambda|maxstep|rtol|atol|ltol|norms|"
    r"keeplambda|alpha)",
    r"snes_ksp_ew(_[a-z0-9]+)?",
    r"ksp_(rtol|atol|divtol|max_it|norm_type|pc_side|initial_guess_nonzero|"
    r"error_if_not_converged|reuse_preconditioner|richardson_scale|converged_maxits|"
    r"gmres_[a-z_]+|chebyshev_[a-z0-9_]+)",
    r"pc_(factor|gamg|mg|hypre|jacobi|sor|asm|gasm|bjacobi)_[a-z0-9_]+",
    r"mat_mumps_(icntl|cntl)_\d+",
    r"mat_superlu_dist_[a-z0-9_]+",
    "|".join(PROJECT_OPTIONS),
)))
VIEWERS = re.compile(r"(snes|ksp)_monitor(_true_residual|_short|_singular_value)?|"
                     r"snes_(linesearch|vi)_monitor|(snes|ksp|pc)_view|"
                     r"(snes|ksp)_converged_reason")
# words of options that write files, draw, debug or load code, even inside an allowed family
_UNSAFE_WORDS = re.compile(r"python|view|monitor|log|dump|file|draw|debug|save|load|write")
_STDOUT_VIEWER = re.compile(r"(ascii)?(::ascii_[a-z_]+)?")
_PLAIN_TEXT = re.compile(r"[A-Za-z0-9_.+-]*")
ALLOWED_TEXT = ("solver and preconditioner types, tolerances, iteration counts, line search, "
                "Eisenstat-Walker, factorisation, GAMG/MG/hypre/Jacobi/SOR/ASM/block Jacobi, "
                "MUMPS and SuperLU_DIST settings, and monitors/views/converged reasons to "
                "standard output; see docs/user-guide.md")


def policy_fault(key: str, value) -> str | None:
    """Why an option must not reach PETSc, or None if it may.

    Args:
        key: the option's name without '-' and without our prefix (e.g. "ksp_monitor",
            "fast_pc_type").
        value: its value (None or a bool for a flag, a number, or text).

    Returns:
        The reason in a few words with what is allowed, or None.
    """
    name = str(key)
    while SUBSOLVER_PREFIXES.match(name):
        name = SUBSOLVER_PREFIXES.sub("", name, count=1)
    text = None if value is None or isinstance(value, (bool, int, float)) else str(value)
    viewer = VIEWERS.fullmatch(name) is not None
    if not viewer and (ALLOWED.fullmatch(name) is None or _UNSAFE_WORDS.search(name)):
        return f"not an option a case may give (allowed: {ALLOWED_TEXT})"
    if text is None:
        return None
    if text.strip().lower() == "python":
        return ("a python type makes petsc4py import and run Python code (allowed: PETSc's "
                "compiled types)")
    if viewer and not _STDOUT_VIEWER.fullmatch(text):
        return (f"{text!r} would write to a file or a window (allowed: no value, or ascii / "
                "ascii::<format> for standard output)")
    if not viewer and not _PLAIN_TEXT.fullmatch(text):
        return (f"{text!r} is not a plain value (allowed: letters, digits and . _ + - only, "
                "no file names)")
    return None
