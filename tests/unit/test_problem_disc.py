"""The step problem holds its Discretisation as ``problem.disc`` and does not repeat its
attributes: the mesh, spaces, groups and Gamma3 nodes are read there, and so is
the box of U^h, u_nu <= g at the Gamma3 nodes (Discretisation.bounds)."""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from conftest import make_case
from vpcontact.meshes import build_rectangle
from vpcontact.model.problem import ContactProblem


def _problem():
    case = make_case(mesh={"n": 4})
    return ContactProblem(case, build_rectangle(MPI.COMM_SELF, 1.0, 1.0, n=4))


def test_the_discretisation_is_read_on_disc_only():
    problem = _problem()
    for name in ("mesh", "comm", "dim", "body", "V", "Q", "Y", "tags", "dirichlet", "bcs",
                 "gamma3", "gamma3_local_nodes", "frames", "pairs", "caps", "length_scale",
                 "num_owned_cells", "cell_volumes", "reduce", "bounds", "pair_operators"):
        assert name not in dir(problem), name       # dir: no cached property is built
        assert name in dir(problem.disc), name
    assert problem.u.function_space is problem.disc.V
    assert problem.sigma.function_space is problem.disc.Q


def test_bounds_hold_the_gap_at_the_free_bottom_nodes():
    """The paper's body on the unit square, clamped on the left side (x = 0), Gamma3 the
    bottom (y = 0) with the outward normal -e_y: -u_y <= g at the bottom nodes off the
    clamped side, PETSc's infinities elsewhere."""
    problem = _problem()
    g = problem.case.contact.g
    lb, ub = problem.disc.bounds(problem.u.vector)
    x = problem.disc.V.tabulate_dof_coordinates()
    bottom = np.isclose(x[:, 1], 0.0) & ~np.isclose(x[:, 0], 0.0)
    lo, up = lb.array.reshape(-1, 2), ub.array.reshape(-1, 2)
    assert np.all(lo[bottom, 1] == -g) and bottom.sum() == 4
    assert np.all(lo[~bottom, 1] == PETSc.NINFINITY) and np.all(lo[:, 0] == PETSc.NINFINITY)
    assert np.all(up == PETSc.INFINITY)
    lb.destroy()
    ub.destroy()
