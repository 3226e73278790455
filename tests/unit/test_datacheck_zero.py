"""Zero-valued and constant data: UFL folds "0*t", "0*x" or a number to a value without a
mesh, which dolfinx can neither interpolate nor integrate; every such datum must run like its
nonzero neighbour (TimeData.on_mesh).  Run on the built-in mesh: a mesh file's data take the
same path (ContactProblem)."""
import numpy as np
import pytest
from mpi4py import MPI

from conftest import make_case, run_case
from vpcontact.meshes import build_rectangle
from vpcontact.model.problem import ContactProblem

VP = {"lambda1": 100.0, "lambda2": 100.0}

# (name, sections of the paper case to merge): each datum zero or a constant without x, y, t
ZERO_DATA = [
    ("u0 numbers", {"initial": {"u0": [0, 0]}}),
    ("u0 0*x", {"initial": {"u0": ["0*x", 0.0]}}),
    ("u0 constant expression", {"initial": {"u0": ["0*y", "2 - 2"]}}),
    ("sigma0 numbers", {"initial": {"sigma0": [[0, 0], [0, 0]]}}),
    ("sigma0 0*x", {"initial": {"sigma0": [["0*x", 0], [0, "0*y"]]}}),
    ("sigma0 constant expression", {"initial": {"sigma0": [["1 + 1", 0], [0, "pi"]]}}),
    ("kappa0 0*x", {"material": {"viscoplastic": {**VP, "kappa0": "0*x"}}}),
    ("kappa0 constant expression", {"material": {"viscoplastic": {**VP, "kappa0": "0.5"}}}),
    ("f0 0*t", {"loads": {"f0": ["0*t", "0*t"], "traction": {"top": [0.0, -8.0]}}}),
    ("traction zero", {"loads": {"traction": {"top": [0.0, 0.0], "right": ["0*t", "0*x"]}}}),
    ("traction constant expression", {"loads": {"traction": {"top": ["1 - 1", "-8"]}}}),
    ("pressure 0*t", {"loads": {"pressure": {"top": "0*t"}}}),
    ("pressure 0", {"loads": {"pressure": {"top": 0}}}),
    ("displacement 0*t", {"loads": {"displacement": {"right": ["0*t", None]}}}),
    ("displacement constant expression", {"loads": {"displacement": {"right": [None, "0"]}}}),
    ("gap 0*x", {"contact": {"g": "0*x"}}),
]


@pytest.mark.parametrize("sections", [s for _, s in ZERO_DATA], ids=[n for n, _ in ZERO_DATA])
def test_zero_data_run_on_the_built_in_mesh(sections):
    case = make_case(mesh={"n": 2}, time={"N": 2}, **sections)
    result = run_case(case)
    assert result.status == "completed", result.summary
    assert np.isfinite(result.problem.u.x.array).all()


def test_zero_initial_values_are_zero_on_the_mesh():
    """u0 = [0*x, 0] gives u = 0, sigma0 = [[0*x, 0], [0, 0]] gives H = 0, kappa0 = 0*x gives
    kappa = 0 (the values, not only the absence of an error)."""
    case = make_case(mesh={"n": 2}, initial={"u0": ["0*x", 0],
                                             "sigma0": [["0*x", 0], [0, "0*y"]]},
                     material={"viscoplastic": {**VP, "kappa0": "0*x"}})
    problem = ContactProblem(case, build_rectangle(MPI.COMM_SELF, 1.0, 1.0, n=2))
    kappa = problem.state.kappa
    kappa.x.array[:] = 7.0
    problem.u.x.array[:] = 5.0
    problem.set_initial_values()
    assert np.all(problem.u.x.array == 0.0)
    assert np.all(problem.H.x.array == 0.0)
    assert np.all(kappa.x.array == 0.0)
