"""Checks of PETSc options (case file ``petsc`` section or command line) before any solve.

The step solvers pass the options unchanged to PETSc under our prefixes: ``vpcontact_`` for
the SNES VI solver and its KSP/PC (app/solver.py), ``vpcontact_fast_`` for the fast
solver's direct solver (app/fastsolver.py, options named ``fast_ksp_type`` etc.).  PETSc
itself would only complain when the solver is set up, after the mesh and forms are built,
with an error code and a traceback.  Here:
- ``*_type`` options are checked against PETSc's type lists (KSP, PC, SNES, line search,
  factorisation packages of this PETSc build);
- tolerances (``*_rtol``, ...) must be numbers >= 0, counts (``*_max_it``, ...) integers;
- as a catch-all, a throwaway SNES and KSP with the same prefixes read the options and set
  up a small matrix; a PETSc error there is reported naming the option that causes it.
"""
from __future__ import annotations

import functools
import math
import re

PREFIX = "vpcontact_"               # app/solver.py's PREFIX (tests/unit/test_case_hostile.py)
FAST_PREFIX = PREFIX + "fast_"      # app/fastsolver.py's direct solver
LINE_SEARCH_TYPES = ("basic", "bt", "l2", "cp", "nleqerr", "shell")
# factorisation package -> the external package PETSc must be built with
_SOLVER_PACKAGES = {"cholmod": "suitesparse", "umfpack": "suitesparse", "klu": "suitesparse",
                    "spqr": "suitesparse", "sparseelemental": "elemental",
                    "cusparse": "cuda", "cuda": "cuda"}
_REAL = re.compile(r"(^|_)(rtol|atol|stol|divtol|dtol)$")
_INTEGER = re.compile(r"(^|_)(max_it|max_funcs|max_fail|max_linear_solve_fail|restart|"
                      r"lag_jacobian|lag_preconditioner)$")


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
    elif _INTEGER.search(key):
        if isinstance(value, bool) or not re.fullmatch(r"[-+]?\d+", str(value)):
            raise PetscOptionError(f"{value!r} is not an integer (allowed: whole numbers "
                                   "such as 50)")


def check_petsc_options(options: dict, source: str, where: str = "petsc.",
                        base: dict | None = None) -> None:
    """Raise CaseError if PETSc would refuse one of ``options`` (name without '-' ->
    value, as given to app/solver.py's set_petsc_options) on top of the ``base`` options
    (accepted already, e.g. the defaults).  ``where`` prefixes the option name in the
    message: "petsc." for a case file's section, "-" for the command line."""
    from .case import CaseError

    types = _type_lists()
    for key, value in options.items():
        try:
            _check_value(str(key), value, types)
        except PetscOptionError as exc:
            raise CaseError(f"{source}: {where}{key}: {exc}") from None
    def failure_without(skip):
        merged = {**(base or {}), **{k: v for k, v in options.items() if k != skip}}
        return _petsc_failure(tuple((str(k), _text(v)) for k, v in merged.items()))

    failure = failure_without(None)
    if failure is None:
        return
    # the given option whose removal makes PETSc accept the rest (the last given first)
    culprit = next((k for k in reversed(options) if failure_without(k) is None), None)
    if culprit is not None:
        raise CaseError(f"{source}: {where}{culprit}: PETSc refuses it: {failure}")
    raise CaseError(f"{source}: {where[:-1] if where.endswith('.') else 'PETSc options'}: "
                    f"PETSc refuses this combination: {failure}")


def _text(value) -> str:
    """The option database's text of a value (as app/solver.py's set_petsc_options)."""
    if value is None or value is True:
        return ""
    return "false" if value is False else str(value)


@functools.lru_cache(maxsize=64)
def _petsc_failure(items: tuple) -> str | None:
    """PETSc's message if a SNES (prefix PREFIX) and a KSP (prefix FAST_PREFIX) cannot read
    the options and set up their linear solvers on a small matrix, else None."""
    from petsc4py import PETSc

    db = PETSc.Options()
    objects = []
    for key, value in items:
        db.setValue(PREFIX + key, value)
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
        ksp.setType("preonly")          # as app/solver.py's direct_solver
        ksp.getPC().setType("lu")
        ksp.setFromOptions()
        for solver in (snes.getKSP(), ksp):
            solver.setOperators(A)
            solver.setUp()
    except PETSc.Error as exc:
        lines = [ln.removeprefix("[0] ").strip() for ln in str(exc).splitlines()]
        return lines[-1] if lines else f"error code {exc.ierr}"
    finally:
        for key, _ in items:
            db.delValue(PREFIX + key)
        for obj in reversed(objects):
            obj.destroy()
    return None
