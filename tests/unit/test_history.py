"""The explicit history update (3.2)-(3.3): H_n = H_{n-1} + k_n Gfun(sigma_{n-1}, kappa_{n-1}),
kappa_n = kappa_{n-1} + k_n Gk(sigma_{n-1}, kappa_{n-1}), cell by cell."""
import numpy as np
from mpi4py import MPI

from conftest import make_case
from vpcontact.meshes import build_rectangle
from vpcontact.model.history import ViscoplasticHistory
from vpcontact.model.material import PlaneStress, to_voigt
from vpcontact.model.problem import ContactProblem
from vpcontact.model.viscoplastic import Perzyna


def test_advance_matches_the_scheme():
    case = make_case(mesh={"n": 2})
    problem = ContactProblem(case, build_rectangle(MPI.COMM_SELF, 1.0, 1.0, n=2))
    hist = ViscoplasticHistory(problem, Perzyna(problem.elasticity, 100.0, 50.0))
    hist.kappa.x.array[:] = 0.5
    assert np.all(problem.H.x.array == 0.0)
    rng = np.random.default_rng(0)
    ncell = problem.sigma.x.array.size // 4
    s = rng.normal(size=(ncell, 2, 2)) * 5.0
    s = 0.5 * (s + s.transpose(0, 2, 1))
    problem.sigma.x.array[:] = s.reshape(-1)
    law = Perzyna(PlaneStress(case.material.E, case.material.nu), 100.0, 50.0)
    k = 0.125
    for _ in range(2):   # two steps with the same sigma: kappa changes in between
        H_old, kappa_old = problem.H.x.array.copy(), hist.kappa.x.array.copy()
        g_sigma, g_kappa = law.rates(to_voigt(s), kappa_old[:, None])
        hist.advance(problem.sigma, k)
        dH = (problem.H.x.array - H_old).reshape(-1, 2, 2)
        np.testing.assert_allclose(to_voigt(dH), k * g_sigma, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(dH, dH.transpose(0, 2, 1))      # H stays symmetric
        np.testing.assert_allclose(hist.kappa.x.array - kappa_old, k * g_kappa[:, 0], rtol=1e-13)
    assert np.all(g_kappa > 0)  # the random stresses lie outside the ball: flow happened
