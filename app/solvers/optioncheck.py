"""Checks of PETSc options (case file ``petsc`` section or command line) before any solve.

The step solvers pass the options unchanged to PETSc under our prefixes (app/solvers/
options.py): ``vpcontact_`` for the SNES VI solver and its KSP/PC (app/solvers/snesvi.py),
``vpcontact_fast_`` for the condensed solver's direct solver (options named
``fast_ksp_type`` etc.).  PETSc
itself would only complain when the solver is set up, after the mesh and forms are built,
with an error code and a traceback.  Here:
- first, only options that load no code and name no file are let through (an allow-list:
  app/solvers/optionpolicy.py); PETSc reads none of the options before that;
- ``*_type`` options are checked against PETSc's type lists (KSP, PC, SNES, line search,
  factorisation packages of this PETSc build);
- tolerances (``*_rtol``, ...) must be numbers >= 0 (relative ones below 1), counts
  (``*_max_it``, ...) integers of a 32-bit PetscInt;
- what the step problems need: SNES VI types (the bound u_nu <= g), an exact factorisation
  for the condensed solver (its options are named fast_*) by a package its matrix type
  supports, absolute tolerances below the case's scales (``limits``), at most MAX_OPTIONS
  options;
- as a catch-all, a throwaway SNES and KSP with the same prefixes read the options and set
  up a small matrix; a PETSc error there is reported naming the option that causes it.
"""
from __future__ import annotations

import functools
import math
import re

from vpcontact.io.errors import CaseError
from vpcontact.solvers.optionpolicy import policy_fault
from vpcontact.solvers.options import (
    FAST_PREFIX,
    PREFIX,
    option_text,
    push_options,
    remove_options,
)

LINE_SEARCH_TYPES = ("basic", "bt", "l2", "cp", "nleqerr", "shell")
# factorisation package -> the external package PETSc must be built with
_SOLVER_PACKAGES = {"cholmod": "suitesparse", "umfpack": "suitesparse", "klu": "suitesparse",
                    "spqr": "suitesparse", "sparseelemental": "elemental",
                    "cusparse": "cuda", "cuda": "cuda"}
_REAL = re.compile(r"(^|_)(rtol|atol|stol|divtol|dtol)$")
_INTEGER = re.compile(r"(^|_)(max_it|max_funcs|max_fail|max_linear_solve_fail|restart|"
                      r"lag_jacobian|lag_preconditioner)$")
_RELATIVE = re.compile(r"(^|_)(rtol|stol)$")
_SIGNED = re.compile(r"(^|_)(lag_jacobian|lag_preconditioner)$")   # -1, -2 have a meaning
MAX_PETSC_INT = 2**31 - 1         # PetscInt of the Debian PETSc build (32 bit)
MAX_OPTIONS = 100                 # PETSc's database holds 512 in all (its own ones included)
# the step problem is a variational inequality: only SNES VI types honour the bound
VI_SNES_TYPES = ("vinewtonrsls", "vinewtonssls")
# the condensed solver's matrix (app/solvers/condensed/): BAIJ in serial, AIJ under mpirun;
# the packages that factorise it exactly, by PC type (as tried with this PETSc build)
FAST_PACKAGES = {(True, "lu"): ("mumps", "petsc"), (True, "cholesky"): ("petsc",),
                 (False, "lu"): ("mumps", "superlu_dist"),
                 (False, "cholesky"): ("mumps", "superlu_dist")}


class PetscOptionError(ValueError):
    """An option PETSc would refuse; the message starts with the option's name."""


def _type_lists() -> dict[str, tuple[str, tuple]]:
    """Option suffix -> (what it names, the allowed values in this PETSc build)."""
    from petsc4py import PETSc

    def values(cls):
        return tuple(sorted(v for k, v in vars(cls).items()
                            if not k.startswith("_") and isinstance(v, str)))

    packages = tuple(s for s in values(PETSc.Mat.SolverType) if s == "petsc"
                     or PETSc.Sys.hasExternalPackage(_SOLVER_PACKAGES.get(s, s)))
    return {"pc_factor_mat_solver_type": ("factorisation package", packages),
            "snes_linesearch_type": ("SNES line search type", LINE_SEARCH_TYPES),
            "snes_type": ("SNES type", values(PETSc.SNES.Type)),
            "ksp_type": ("KSP type", values(PETSc.KSP.Type)),
            "pc_type": ("PC type", values(PETSc.PC.Type))}


def _check_value(key: str, value, types: dict) -> None:
    """Type names and numbers of one option; raises PetscOptionError."""
    for suffix, (what, allowed) in types.items():
        if key == suffix or key.endswith("_" + suffix):
            if not isinstance(value, str) or value not in allowed:
                raise PetscOptionError(f"{value!r} is not a {what} (allowed: "
                                       f"{', '.join(allowed)})")
            return
    if _REAL.search(key):
        try:
            number = float(value) if not isinstance(value, bool) and value is not None \
                else math.nan
        except ValueError:
            number = math.nan
        if not (math.isfinite(number) and number >= 0):
            raise PetscOptionError(f"{value!r} is not a tolerance (allowed: a number >= 0)")
        if _RELATIVE.search(key) and number >= 1:
            raise PetscOptionError(f"{value!r} is not a relative tolerance: the solver would "
                                   "stop at once (allowed: 0 <= value < 1)")
    elif _INTEGER.search(key):
        if isinstance(value, bool) or not re.fullmatch(r"[-+]?\d+", str(value)):
            raise PetscOptionError(f"{value!r} is not an integer (allowed: whole numbers "
                                   "such as 50)")
        low = -MAX_PETSC_INT if _SIGNED.search(key) else 0
        if not low <= int(value) <= MAX_PETSC_INT:
            raise PetscOptionError(f"{value!r} is out of range (allowed: integers from {low} "
                                   f"to {MAX_PETSC_INT})")


def check_petsc_options(options: dict, source: str, where: str = "petsc.",
                        base: dict | None = None, limits: dict | None = None) -> None:
    """Check PETSc options before PETSc sees them.

    Args:
        options: name without '-' -> value, as given to the step solvers
            (options.push_options).
        source: the case file, for messages.
        where: prefix of the option name in messages: "petsc." for a case file's section,
            "-" for the command line.
        base: the options accepted already (e.g. the defaults) under ``options``.
        limits: an absolute tolerance -> (its largest value, the reason); default
            ``base.limits`` (see PetscOptions).

    Returns:
        None; every check that fails raises.

    Raises:
        CaseError: if PETSc would refuse one of ``options`` on top of ``base``, or if they
            would make a step solver give a wrong answer.
    """
    if limits is None:
        limits = getattr(base, "limits", {})
    merged = {**(base or {}), **options}
    if len(merged) > MAX_OPTIONS:
        raise CaseError(f"{source}: {where[:-1] if where.endswith('.') else 'PETSc options'}: "
                        f"{len(merged)} options (with the case's) are too many (allowed: at most "
                        f"{MAX_OPTIONS})")
    for key, value in options.items():      # before PETSc reads any of them
        why = policy_fault(key, value)
        if why:
            raise CaseError(f"{source}: {where}{key}: {why}")
    types = _type_lists()
    for key, value in options.items():
        try:
            _check_value(str(key), value, types)
        except PetscOptionError as exc:
            raise CaseError(f"{source}: {where}{key}: {exc}") from None
    for key, why in _step_problem_faults(merged, limits):
        shown = f"{where}{key}" if key in options else f"petsc.{key}"
        raise CaseError(f"{source}: {shown}: {why}")
    def failure_without(skip):
        merged = {**(base or {}), **{k: v for k, v in options.items() if k != skip}}
        return _petsc_failure(tuple((str(k), option_text(v)) for k, v in merged.items()))

    failure = failure_without(None)
    if failure is None:
        return
    # the given option whose removal makes PETSc accept the rest (the last given first)
    culprit = next((k for k in reversed(options) if failure_without(k) is None), None)
    if culprit is not None:
        raise CaseError(f"{source}: {where}{culprit}: PETSc refuses it: {failure}")
    raise CaseError(f"{source}: {where[:-1] if where.endswith('.') else 'PETSc options'}: "
                    f"PETSc refuses this combination: {failure}")


class PetscOptions(dict):
    """A case's PETSc options with the largest absolute tolerances its scales allow, for
    checking options given later.

    Args:
        options: option name (without '-') -> value.
        limits: option -> (largest value, why).
    """

    def __init__(self, options: dict, limits: dict):
        super().__init__(options)
        self.limits = limits


def _step_problem_faults(merged: dict, limits: dict):
    """(option, why) for each option of ``merged`` (all options in force) that PETSc
    accepts but that would make a step solver ignore the model or solve it inexactly."""
    from mpi4py import MPI

    snes_type = merged.get("snes_type", VI_SNES_TYPES[0])
    if snes_type not in VI_SNES_TYPES:
        yield "snes_type", (f"{snes_type!r} ignores the bound u_nu <= g of the step's "
                            f"variational inequality (allowed: {', '.join(VI_SNES_TYPES)})")
    ksp_type = merged.get("fast_ksp_type", "preonly")
    if ksp_type != "preonly":
        yield "fast_ksp_type", (f"{ksp_type!r}: the fast solver needs an exact factorisation "
                                "(allowed: preonly)")
    pc_type = merged.get("fast_pc_type", "lu")
    if pc_type not in ("lu", "cholesky"):
        yield "fast_pc_type", (f"{pc_type!r}: the fast solver needs an exact factorisation "
                               "(allowed: lu, cholesky)")
        return
    serial = MPI.COMM_WORLD.size == 1
    packages = FAST_PACKAGES[(serial, pc_type)]
    package = merged.get("fast_pc_factor_mat_solver_type")
    if package is not None and package not in packages:
        yield "fast_pc_factor_mat_solver_type", (
            f"{package!r} cannot factorise the fast solver's {'BAIJ' if serial else 'AIJ'} "
            f"matrix by {pc_type} {'in serial' if serial else 'under mpirun'} "
            f"(allowed: {', '.join(packages)})")
    for key, (largest, why) in limits.items():
        if key in merged and _number(merged[key]) > largest:
            yield key, (f"{merged[key]!r} is too large: {why} (allowed: a number >= 0 up to "
                        f"{largest:.3g})")


def _number(value) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


@functools.lru_cache(maxsize=64)
def _petsc_failure(items: tuple) -> str | None:
    """PETSc's message if a SNES (prefix PREFIX) and a KSP (prefix FAST_PREFIX) cannot read
    the options and set up their linear solvers on a small matrix, else None."""
    from petsc4py import PETSc

    objects = []
    db = PETSc.Options()          # the options of a solver alive now are put back after
    kept = {key: db.getString(PREFIX + key) for key, _ in items if db.hasName(PREFIX + key)}
    push_options(dict(items), PREFIX)
    try:
        A = PETSc.Mat().createAIJ([6, 6], bsize=2, nnz=3, comm=PETSc.COMM_SELF)
        objects.append(A)
        for i in range(6):        # a small SPD matrix (tridiagonal 4, -1)
            A.setValues([i], [j for j in (i - 1, i, i + 1) if 0 <= j < 6],
                        [4.0 if j == i else -1.0 for j in (i - 1, i, i + 1) if 0 <= j < 6])
        A.assemble()
        snes = PETSc.SNES().create(PETSc.COMM_SELF)
        objects.append(snes)
        snes.setOptionsPrefix(PREFIX)
        snes.setFromOptions()
        ksp = PETSc.KSP().create(PETSc.COMM_SELF)
        objects.append(ksp)
        ksp.setOptionsPrefix(FAST_PREFIX)
        ksp.setType("preonly")          # as app/solvers/snesvi.py's direct_solver
        ksp.getPC().setType("lu")
        ksp.setFromOptions()
        for solver in (snes.getKSP(), ksp):
            solver.setOperators(A)
            solver.setUp()
    except PETSc.Error as exc:
        lines = [ln.removeprefix("[0] ").strip() for ln in str(exc).splitlines()]
        return lines[-1] if lines else f"error code {exc.ierr}"
    finally:
        remove_options(dict(items), PREFIX)
        push_options(kept, PREFIX)
        for obj in reversed(objects):
            obj.destroy()
    return None
