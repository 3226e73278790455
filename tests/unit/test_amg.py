"""SNES VI's iterative path (app/solvers/amg.py): the choice of the linear solver, its PETSc
options, and the rigid body modes it gives GAMG."""
import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from conftest import ROOT, make_case
from vpcontact.case import load_raw, validate
from vpcontact.forms.elasticity import eps
from vpcontact.simulation import build_mesh
from vpcontact.solvers import AUTO_AMG_MIN_DOFS, choose_linear
from vpcontact.solvers.amg import AMG_PETSC, orthonormal_columns, rigid_body_modes
from vpcontact.solvers.options import snes_vi_options


def _box(**solver):
    raw = load_raw(ROOT / "cases" / "box3d.yaml")
    raw["mesh"]["n"] = 3
    raw.setdefault("solver", {}).update(solver)
    return validate(raw, "box")


@pytest.mark.parametrize("dofs, expected", [(AUTO_AMG_MIN_DOFS, "schur"),
                                            (AUTO_AMG_MIN_DOFS + 1, "amg")])
def test_auto_picks_amg_for_large_3d_meshes(dofs, expected):
    """Below: the Gamma3 Schur complement on one factorisation of K (SNES VI takes LU
    where it does not apply)."""
    assert choose_linear(_box(method="snes_vi"), dofs) == expected


def test_auto_keeps_a_direct_solver_in_2d():
    assert choose_linear(make_case(solver={"method": "snes_vi"}), 10**7) == "schur"


@pytest.mark.parametrize("linear", ["direct", "schur", "amg"])
def test_an_explicit_linear_solver_is_kept(linear):
    assert choose_linear(_box(linear=linear), 10 * AUTO_AMG_MIN_DOFS if linear == "direct"
                         else 10) == linear


def test_amg_options_replace_the_lu_defaults_but_not_given_options():
    case = _box(linear="amg")
    options = snes_vi_options(case, "amg")
    assert options["ksp_type"] == "cg" and "pc_type" not in options
    assert "pc_factor_mat_solver_type" not in options
    assert options["snes_type"] == "vinewtonrsls"
    assert options["amg_pc_type"] == AMG_PETSC["amg_pc_type"]
    raw = load_raw(ROOT / "cases" / "box3d.yaml")
    raw["mesh"]["n"] = 3
    raw["petsc"] = {"ksp_type": "minres", "ksp_rtol": 1e-9}
    given = snes_vi_options(validate(raw, "box"), "amg")
    assert given["ksp_type"] == "minres" and given["ksp_rtol"] == 1e-9
    assert snes_vi_options(case, "direct") == dict(case.petsc)


@pytest.mark.parametrize("dim", [2, 3])
def test_rigid_body_modes_have_no_strain(dim):
    case = _box() if dim == 3 else make_case(mesh={"n": 4})
    body = build_mesh(case, MPI.COMM_WORLD)
    V = fem.VectorFunctionSpace(body.mesh, ("CG", 1))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    K = fem.petsc.assemble_matrix(fem.form(ufl.inner(eps(u), eps(v)) * ufl.dx))
    K.assemble()
    Z = orthonormal_columns(rigid_body_modes(V), MPI.COMM_WORLD)
    assert Z.shape[1] == (3 if dim == 2 else 6)
    assert np.allclose(MPI.COMM_WORLD.allreduce(Z.T @ Z), np.eye(Z.shape[1]), atol=1e-12)
    x, y = K.createVecs()
    for j in range(Z.shape[1]):
        x.array[:] = Z[:, j]
        K.mult(x, y)
        assert y.norm() < 1e-10 * K.norm()


def test_trace_constant_by_lobpcg_and_gamg_equals_power_iteration_with_lu():
    """(2.6)'s ||gamma||^2 on the 3D box: LOBPCG with GAMG (the iterative path's
    tolerances) against the power iteration with LU (Rayleigh quotients to 1e-10)."""
    from vpcontact.model.problem import ContactProblem
    from vpcontact.post.diagnostics import trace_constant
    raw = load_raw(ROOT / "cases" / "box3d.yaml")
    raw["mesh"]["n"] = 6
    case = validate(raw, "box")
    problem = ContactProblem(case, build_mesh(case, MPI.COMM_WORLD))
    lu, _ = trace_constant(problem.disc, rtol=1e-10, max_iter=2000)
    lobpcg, its = trace_constant(problem.disc, linear="amg")
    assert lobpcg == pytest.approx(lu, rel=1e-6)
    assert its < 30
