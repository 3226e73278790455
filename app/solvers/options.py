"""The step solvers' PETSc options: their defaults, the defaults' scaling to a case, and how
they reach PETSc.

Every option of the case file's ``petsc`` section and of the command line (``-snes_rtol
1e-9``) reaches PETSc under the prefix PREFIX (``vpcontact_``): SNES VI and its KSP/PC read
``vpcontact_<option>`` (app/solvers/snesvi.py), the inner multigrid PC
``vpcontact_amg_<option>`` (app/solvers/amg.py), the condensed solver's direct solver
``vpcontact_fast_<option>`` (given as ``fast_ksp_type`` etc.).  The defaults below are
overridden by the case's options, and the command line's override both.  A solver puts its
options into PETSc's database as dolfinx 0.5.2's LinearProblem does (``push_options``:
prefixPush, set, prefixPop, then the solver's setFromOptions) and takes them out when it is
destroyed (``remove_options``).  Options are checked before any solve in
app/solvers/optioncheck.py.
"""
from __future__ import annotations

PREFIX = "vpcontact_"
FAST_PREFIX = PREFIX + "fast_"      # the condensed solver's direct solver

# PETSc options used unless the case or the command line says otherwise; the absolute
# tolerances snes_atol and snes_vi_zero_tolerance are for the paper's scales and are
# scaled to each case's size and loads (scaled_defaults).
DEFAULT_PETSC = {
    "snes_type": "vinewtonrsls",
    "snes_linesearch_type": "basic",
    "snes_rtol": 1.0e-10,
    "snes_atol": 1.0e-11,
    "snes_stol": 1.0e-14,
    "snes_vi_zero_tolerance": 1.0e-8,
    "snes_max_it": 50,
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}
REFERENCE_FORCE = 8.0       # the paper's nodal force scale (N/m, 2D), where snes_atol holds


def scaled_defaults(stress: float, length: float, dim: int, g) -> dict:
    """DEFAULT_PETSC's absolute tolerances scaled to the case, so that a body of any size
    or stiffness converges alike (their values hold for the paper's scales: the unit square
    under a stress of 8 N/m^2):
    - snes_atol, on the residual, a vector of nodal forces ~ stress L^(d-1); without loads
      or initial data (u = 0 exactly) the default value serves;
    - snes_vi_zero_tolerance, how close to its bound (in m) SNES VI takes a dof as active:
      relative to the body's size L, and at most 1e-4 of the gap g (a tenth of the limit
      in ``tolerance_limits``, so that a small gap keeps a valid default); a gap given by
      an expression: relative to L only.

    Args:
        stress: the stress scale of the case's loads and initial data.
        length: the body's size L [m].
        dim: the space dimension d.
        g: the gap contact.g if it is a number, else None.

    Returns:
        PETSc option name -> default value.
    """
    force = stress * length ** (dim - 1)
    atol = DEFAULT_PETSC["snes_atol"]
    zero = DEFAULT_PETSC["snes_vi_zero_tolerance"] * length
    return {"snes_atol": atol * force / REFERENCE_FORCE if force > 0 else atol,
            "snes_vi_zero_tolerance": min(zero, 1e-4 * g) if g else zero}


def tolerance_limits(stress: float, length: float, dim: int, g) -> dict:
    """The largest absolute tolerances that still solve a step of this case, with the
    reason (for optioncheck.check_petsc_options): a residual tolerance of 1e-3 of the nodal
    force scale stress L^(d-1) (none without loads or initial data: u = 0 exactly), an
    active-set tolerance of 1e-3 of the gap g (a number) and of the body's size L.

    Args:
        stress: the stress scale of the case's loads and initial data.
        length: the body's size L [m].
        dim: the space dimension d.
        g: the gap contact.g if it is a number, else None.

    Returns:
        PETSc option name -> (largest value, reason).
    """
    force = stress * length ** (dim - 1)
    limits = {}
    if force > 0:
        limits["snes_atol"] = (1e-3 * force, f"Newton would stop before solving, the "
                               f"residual's nodal forces are of order {force:.3g} "
                               "(stress x L^(d-1))")
    scale, what = (g, "the gap g") if g is not None and 0 < g < length else (length, "L")
    limits["snes_vi_zero_tolerance"] = (1e-3 * scale, f"SNES VI would take dofs "
                                        f"{1e-3 * scale:.3g} m (1e-3 {what}) or farther "
                                        "from their bound as active")
    return limits


def snes_vi_options(case, linear: str) -> dict:
    """SNES VI's PETSc options: the case's, and for ``amg`` the iterative defaults
    (app/solvers/amg.AMG_PETSC) in place of the direct solver's defaults.

    Args:
        case: the validated Case (its petsc options).
        linear: "direct" or "amg".

    Returns:
        Option name (without '-') -> value.
    """
    if linear != "amg":
        return dict(case.petsc)
    from vpcontact.solvers.amg import AMG_PETSC, DIRECT_KEYS

    given = {k: v for k, v in case.petsc.items()
             if not (k in DIRECT_KEYS and DEFAULT_PETSC.get(k) == v)}
    return {**AMG_PETSC, **given}


def option_text(value) -> str:
    """The options database's text of a value.

    Args:
        value: None or True (a flag: empty text), False ("false"), anything else.

    Returns:
        The text; str(value) for anything else.
    """
    if value is None or value is True:
        return ""
    return "false" if value is False else str(value)


def push_options(options: dict, prefix: str = PREFIX) -> None:
    """Put options into PETSc's database under a prefix, as dolfinx 0.5.2's LinearProblem
    does: prefixPush(prefix), set, prefixPop(); the solver's setFromOptions reads them.

    Args:
        options: name without '-' -> value (see ``option_text``).
        prefix: the options prefix (e.g. "vpcontact_": -vpcontact_snes_rtol).
    """
    from petsc4py import PETSc

    db = PETSc.Options()
    db.prefixPush(prefix)
    try:
        for key, value in options.items():
            db.setValue(str(key), option_text(value))
    finally:
        db.prefixPop()


def remove_options(options, prefix: str = PREFIX) -> None:
    """Take options (put there by ``push_options``) out of PETSc's database again, so that
    they cannot reach a solver created later in the same process.

    Args:
        options: the names (without '-'); only the keys of a mapping are used.
        prefix: the prefix they were put under.
    """
    from petsc4py import PETSc

    db = PETSc.Options()
    for key in options:
        db.delValue(prefix + str(key))


def case_defaults(case, stress: float, length: float) -> tuple[dict, dict]:
    """A case's PETSc defaults and the limits of its absolute tolerances.

    Args:
        case: the Case (its dimension and gap contact.g: a number counts, an expression's
            scale is unknown and the length serves).
        stress: the stress scale of the case's loads and initial data.
        length: the body's size L [m].

    Returns:
        (DEFAULT_PETSC with the scaled tolerances, ``tolerance_limits``).
    """
    g = None if isinstance(case.contact.g, str) else case.contact.g
    return ({**DEFAULT_PETSC, **scaled_defaults(stress, length, case.dim, g)},
            tolerance_limits(stress, length, case.dim, g))
