"""strain.StrainOperator: the compiled cell passes equal the PETSc products of the assembled
operators (D_sigma u + H, D^T H, u^T A u) and the numpy von Mises norm and Q-norm, in 2D and
3D."""
import numpy as np
import pytest
from mpi4py import MPI

from conftest import ROOT, make_case
from vpcontact import kernels
from vpcontact.model.problem import ContactProblem
from vpcontact.simulation import build_mesh

pytestmark = pytest.mark.skipif(kernels.load() is None, reason="no C compiler")


def _problem(dim):
    if dim == 2:
        case = make_case(mesh={"n": 6, "diagonal": "left", "L1": 1.5})
    else:
        from vpcontact.case import load_raw, validate
        raw = load_raw(ROOT / "cases" / "box3d.yaml")
        raw["mesh"]["n"] = 3
        case = validate(raw, "box")
    return ContactProblem(case, build_mesh(case, MPI.COMM_WORLD))


@pytest.mark.parametrize("dim", [2, 3])
def test_cell_passes_equal_the_assembled_operators(dim):
    p = _problem(dim)
    op = p.strain_operator
    assert op._cells is not None
    rng = np.random.default_rng(dim)
    p.u.x.array[:] = rng.normal(size=p.u.x.array.size)
    H = rng.normal(size=(p.H.x.array.size // dim**2, dim, dim))
    p.H.x.array[:] = (H + H.transpose(0, 2, 1)).ravel()
    n = op.n_owned * dim**2

    # the PETSc reference: D_sigma u + H, the numpy von Mises norm, u^T A u, D^T H
    op.D_sigma.multAdd(p.u.vector, p.H.vector, p.sigma.vector)
    sigma_ref = p.sigma.x.array[:n].copy()
    vm_ref = p.elasticity.von_mises(p.elasticity.to_voigt(sigma_ref))
    op.A.mult(p.u.vector, op._b)
    e2_ref = op._b.dot(p.u.vector)
    b_ref = op._b.duplicate()
    b_ref.set(0.0)
    op.D.multTranspose(p.H.vector, op._b)
    b_ref.axpy(-1.0, op._b)

    p.sigma.x.array[:] = np.nan
    e2, s2 = op.update_sigma(p.u, p.H, p.sigma, p.sigma_vm)
    assert e2 == pytest.approx(e2_ref, rel=1e-13)                 # ||u||_V^2
    s2_ref = float(op.vol @ np.sum(sigma_ref.reshape(len(op.vol), -1) ** 2, axis=1))
    assert s2 == pytest.approx(s2_ref, rel=1e-13)                 # ||sigma||_Q^2
    scale = np.abs(sigma_ref).max()
    assert np.abs(p.sigma.x.array[:n] - sigma_ref).max() <= 1e-13 * scale
    assert np.abs(p.sigma_vm.x.array[:op.n_owned] - vm_ref).max() <= 1e-13 * scale
    assert op.strain_norm2(p.u) == pytest.approx(e2_ref, rel=1e-13)
    b = b_ref.duplicate()
    b.set(0.0)
    op.pre_stress_load(p.H, b)
    assert np.abs(b.array_r - b_ref.array_r).max() <= 1e-13 * np.abs(b_ref.array_r).max()

    # D^T H by the compiled pass over every cell, and over some cells exactly at the nodes
    # whose cells are all among them (the boundary layer's use)
    full = op.stress_load(p.H).array_r.copy()
    assert np.abs(full + b_ref.array_r).max() <= 1e-13 * np.abs(b_ref.array_r).max()
    rows = np.arange(0, op.n_owned, 2)
    part = op.stress_load(p.H, op.subset(rows)).array_r
    cells = p.disc.V.dofmap.list.array.reshape(op.n_owned, -1)[np.argsort(
        p.disc.Q.dofmap.list.array[:op.n_owned])]                      # Q's order: D's rows
    inside = np.setdiff1d(np.arange(len(full) // dim), cells[np.setdiff1d(
        np.arange(op.n_owned), rows)].ravel())
    assert len(inside) > 0
    dofs = (dim * inside[:, None] + np.arange(dim)).ravel()
    assert np.abs(part[dofs] - full[dofs]).max() <= 1e-13 * np.abs(full).max()
    assert np.abs(part - full).max() > 1e-6 * np.abs(full).max()  # not the whole sum


@pytest.mark.parametrize("d", [2, 3])
def test_batched_inverse(d):
    """strain._inverse (adjugates) against numpy's LAPACK inverse, for sheared, stretched
    and reflected (det < 0) cells."""
    from vpcontact.model.strain import _inverse
    rng = np.random.default_rng(d)
    J = rng.normal(size=(200, d, d)) + 3 * np.eye(d)
    J[::3] *= 1e-3                                   # small cells
    J[1::3, :, 0] *= -1                              # reflected
    ref = np.linalg.inv(J)
    assert np.abs(_inverse(J) - ref).max() <= 1e-12 * np.abs(ref).max()
