"""SNES VI's absolute tolerance scales with the problem (app/solvers/snesvi.py,
RoundoffFloor): on a nearly incompressible plane-strain body (nu = 0.4999, lambda / mu =
5000) the residual stalls at its round-off floor, ~100 eps || |J| |u| ||, above the default
snes_atol (scaled by the nodal force scale only); SNES VI failed there while the fast
solver completed.  Both must complete and agree to 1e-8."""
import numpy as np
import pytest

from conftest import paper_raw, run_case, validate_raw


def _incompressible(viscoplastic: bool, N: int) -> dict:
    raw = paper_raw()
    raw["material"].update(nu=0.4999, plane="strain")
    if viscoplastic:                 # lambda1 large enough for the explicit scheme's limit
        raw["material"]["viscoplastic"]["lambda1"] = 1e6
    else:
        del raw["material"]["viscoplastic"]
    raw["time"]["N"] = N
    return raw


def _both(raw: dict):
    runs = {}
    for method in ("snes_vi", "condensed"):
        raw.setdefault("solver", {})["method"] = method
        runs[method] = run_case(validate_raw(raw))
        assert runs[method].status == "completed", runs[method].summary.get("failure")
        assert runs[method].summary["solver"]["used"] == method
    return runs["snes_vi"], runs["condensed"]


def _agreement(a, b) -> tuple[float, float]:
    ua, ub = a.problem.u.x.array, b.problem.u.x.array
    du = np.abs(ua - ub).max() / np.abs(ua).max()
    dn = max(abs(x[k] - y[k]) / abs(x[k]) for x, y in zip(a.summary["steps"], b.summary["steps"])
             for k in ("norm_u_V", "norm_sigma_Q") if x[k])
    return du, dn


def _paper_run_and_jacobian(N: int):
    """The paper case run with N steps (its RunResult, which owns u: keep it while u is
    used) and the bulk Jacobian (assembled)."""
    from dolfinx import fem
    raw = paper_raw()
    raw["time"]["N"] = N
    result = run_case(validate_raw(raw))
    A = fem.petsc.assemble_matrix(fem.form(result.problem.forms.bulk_jacobian))
    A.assemble()
    return result, A


@pytest.mark.parametrize("viscoplastic", [False, True])   # True: completed before too
def test_nearly_incompressible_plane_strain_both_solvers_complete_and_agree(viscoplastic):
    a, b = _both(_incompressible(viscoplastic, N=4 if not viscoplastic else 8))
    du, dn = _agreement(a, b)
    assert du < 1e-8 and dn < 1e-8, (du, dn)


def test_the_floor_is_below_the_default_tolerance_on_the_paper_case():
    """Where the residual can reach the force-scaled snes_atol, the floor does not raise it:
    on the paper case ROUNDOFF_FACTOR eps || |J| |u| || at T (5.4e-13) stays well below 1e-11; the
    floor bounds ROUNDOFF_FACTOR eps || J u || from above (|J| |u| >= |J u| entrywise)."""
    from vpcontact.solvers.snesvi import ROUNDOFF_FACTOR, RoundoffFloor
    result, A = _paper_run_and_jacobian(N=4)
    u = result.problem.u.vector
    floor = RoundoffFloor()
    value = floor(A, u)
    y = u.duplicate()
    A.mult(u, y)
    assert ROUNDOFF_FACTOR * np.finfo(float).eps * y.norm() < value < 0.5e-11
    floor.destroy()
    A.destroy()


def test_a_given_snes_atol_is_kept():
    """A snes_atol the user gives is used as given (no floor): the stall is reported."""
    raw = _incompressible(False, N=2)
    raw["solver"] = {"method": "snes_vi"}
    raw["petsc"] = {"snes_atol": 2e-11}
    result = run_case(validate_raw(raw))
    assert result.status == "failed"


def _abs_reference(A, x) -> float:
    """eps || |A| |x| ||_2 from A's CSR arrays (numpy), the floor's definition."""
    ai, aj, av = A.getValuesCSR()
    rows = np.repeat(np.arange(len(ai) - 1), np.diff(ai))
    y = np.bincount(rows, weights=np.abs(av) * np.abs(x.array_r[aj]), minlength=len(ai) - 1)
    return np.finfo(float).eps * np.linalg.norm(y)


def test_the_floor_keeps_abs_J_in_the_symmetric_block_format_where_J_is_symmetric():
    """|J| is kept in SBAIJ (half the values) where J is symmetric with whole blocks, in AIJ
    otherwise; both give eps || |J| |x| || as the CSR arrays do (the SBAIJ product sums in
    another order: to 1e-13)."""
    from petsc4py import PETSc

    from vpcontact.solvers.snesvi import ROUNDOFF_FACTOR, RoundoffFloor
    result, A = _paper_run_and_jacobian(N=2)
    u = result.problem.u.vector
    assert A.getBlockSize() == 2
    for symmetric in (True, False):
        if not symmetric:                      # one entry of the upper triangle changed
            ai, aj, _ = A.getValuesCSR()
            row = 4
            col = int(aj[ai[row + 1] - 1])
            assert col > row
            A.setValue(row, col, 2.0, addv=PETSc.InsertMode.ADD_VALUES)
            A.assemble()
        floor = RoundoffFloor()
        value = floor(A, u) / ROUNDOFF_FACTOR
        assert floor.abs_J.getType() == ("seqsbaij" if symmetric else "seqaij")
        reference = _abs_reference(A, u)
        assert abs(value - reference) <= 1e-13 * reference, (symmetric, value, reference)
        floor.destroy()
    A.destroy()
