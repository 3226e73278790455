"""The Newton direction and the contact energy of the condensed solver's Gamma3 problem for
two bodies (app/solvers/condensed/pairs.py), against numpy's dense algebra:

- PairNewtonDirection: p = -(S + C^T W C)_ff^-1 g_f, 0 on the binding dofs, by a
  factorisation, and from PCG_MIN dofs by CG with the kept factor once W and the binding
  set change a little (to the relative residual asked for);
- PairContact: the energy, gradient C^T grad and nodal Hessian blocks of sum w_i phi_i on
  w = C y, each node with its own set of laws, against the nodal energy of every node
  evaluated alone (nodal_contact_numpy) and a finite difference of the energy.
"""
import numpy as np
from scipy.sparse import random as sparse_random

from vpcontact.model.contact_laws import (
    ContactLaw,
    NormalCompliance,
    PiecewiseLinearFriction,
    RegularisedNorm,
)
from vpcontact.solvers.condensed.pairs import PairContact, PairNewtonDirection, PairSection
from vpcontact.solvers.dense import PCG_MIN
from vpcontact.solvers.nodal import nodal_contact_numpy

D = 3


def _problem(m, n_s, seed=0):
    """S symmetric positive definite (m x m), C sparse (n_s d x m), SPD blocks W."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((m, m))
    S = A @ A.T / m + np.eye(m)
    C = sparse_random(n_s * D, m, density=4.0 / m, random_state=seed, format="csr")
    B = rng.standard_normal((n_s, D, D))
    W = np.einsum("nij,nkj->nik", B, B) + 0.1 * np.eye(D)
    return S, C, W, rng


def _reference(S, C, W, g, binding):
    H = S + C.T.toarray() @ _block_diag(W) @ C.toarray()
    free = np.flatnonzero(~binding)
    p = np.zeros(len(g))
    p[free] = -np.linalg.solve(H[np.ix_(free, free)], g[free])
    return p


def _block_diag(W):
    n = len(W)
    out = np.zeros((n * D, n * D))
    for i in range(n):
        out[i * D:(i + 1) * D, i * D:(i + 1) * D] = W[i]
    return out


def test_factorised_and_cg_directions():
    m = PCG_MIN + 2
    S, C, W, rng = _problem(m, 200)
    g = rng.standard_normal(m)
    binding = np.zeros(m, bool)
    binding[::50] = True
    direction = PairNewtonDirection(S, C, D)
    p = direction(W, g, binding)
    ref = _reference(S, C, W, g, binding)
    assert np.abs(p - ref).max() <= 1e-10 * np.abs(ref).max()
    assert direction.factorisations == 1 and direction.cg_iterations == 0
    # the next iteration: W changed by 1 %, two more dofs binding: CG with the kept factor
    W2 = W * (1 + 0.01 * rng.random((len(W), 1, 1)))
    binding[[3, 7]] = True
    p2 = direction(W2, g, binding, rtol=1e-10)
    ref2 = _reference(S, C, W2, g, binding)
    assert direction.factorisations == 1 and direction.cg_iterations > 0
    assert np.abs(p2 - ref2).max() <= 1e-7 * np.abs(ref2).max()
    assert (p2[binding] == 0).all()


def test_contact_of_w_with_laws_per_node():
    m, n_s = 30, 6
    _, C, _, rng = _problem(m, n_s, seed=1)
    laws = [ContactLaw(NormalCompliance(500.0), None, None, None),
            ContactLaw(NormalCompliance(80.0), None, PiecewiseLinearFriction(0.2, 1.0, 1.0, 0.1),
                       RegularisedNorm(1e-3))]
    nodes = [np.array([0, 2, 5]), np.array([1, 3, 4])]
    w = rng.random(n_s) + 0.5
    e0 = np.eye(D)[0]
    contact = PairContact([PairSection(k, law) for k, law in zip(nodes, laws)], w, e0, C, D,
                          None)
    y = 0.05 * rng.standard_normal((m // D, D))
    e, grad, H = contact.evaluate(y)
    wv = (C @ y.ravel()).reshape(-1, D)
    e_ref, g_ref = 0.0, np.zeros((n_s, D))
    for k, law in zip(nodes, laws):
        e_k, g_k, H_k = nodal_contact_numpy(wv[k], e0, law, None, None, w[k])
        e_ref += e_k
        g_ref[k] = g_k
        np.testing.assert_allclose(H[k], H_k, rtol=1e-12, atol=0)
    assert abs(e - e_ref) <= 1e-12 * abs(e_ref)
    np.testing.assert_allclose(grad.ravel(), C.T @ g_ref.ravel(), rtol=1e-12, atol=1e-14)
    # the gradient is the energy's: a central difference along a random direction
    v, h = rng.standard_normal(y.shape), 1e-6
    fd = (contact.evaluate(y + h * v, False)[0] - contact.evaluate(y - h * v, False)[0]) / (2 * h)
    assert abs(fd - grad.ravel() @ v.ravel()) <= 1e-6 * abs(fd)
