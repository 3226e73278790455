"""Anisotropic and per-cell elasticity at the numpy level: the orthotropic matrix against the
engineering constants it is built from (uniaxial compliances in the material axes, plane
strain's reduced compliance), the Voigt matrix, the per-cell elasticity's rows, and the
energy-norm projection P_K for an anisotropic E against a bisection on its secular
equation (the KKT conditions A (p - s) + mu M p = 0, p^T M p = kappa^2, solved with
np.linalg.solve: no eigen-decomposition, CPU-independent); the case's refusals."""
import copy

import numpy as np
import pytest

from conftest import paper_raw, validate_raw
from vpcontact.case.anisotropy import elasticity_matrix, energy_minimum
from vpcontact.io.errors import CaseError
from vpcontact.model.material import (
    CellElasticity,
    Elasticity,
    MatrixElasticity,
    VonMisesProjection,
    make_projection,
)

ORTHO3 = {"E": [3000.0, 1000.0, 700.0], "nu": [0.25, 0.2, 0.35], "G": [500.0, 450.0, 300.0]}
PAIRS = {2: [(0, 0), (1, 1), (0, 1)], 3: [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]}


def _t(tau):
    """t-coordinates of a symmetric d x d tensor (written out here, not the code's)."""
    return np.array([tau[i, j] for i, j in PAIRS[tau.shape[0]]])


def _tensor(t, dim):
    tau = np.zeros((dim, dim))
    for v, (i, j) in zip(t, PAIRS[dim]):
        tau[i, j] = tau[j, i] = v
    return tau


def _axes3(a, b):
    """Orthonormal a1, a2, a3 from Euler-like angles (degrees)."""
    a, b = np.radians(a), np.radians(b)
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    Rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    return (Rz @ Rx).T                                    # rows: the axes


def _strain(C, sigma):
    dim = sigma.shape[0]
    return _tensor(np.linalg.solve(C, _t(sigma)), dim)


def test_orthotropic_uniaxial_compliances_3d():
    """With axes rotated by (30, 20) degrees: a uniaxial stress s along a_i gives the strain
    s/E_i along a_i, -nu_ij s/E_i along a_j; a shear tau on (a_i, a_j) the engineering
    strain tau/G_ij."""
    R = _axes3(30.0, 20.0)
    C = elasticity_matrix({"orthotropic": {**ORTHO3, "axes": R[:2].tolist()}}, 3)
    E, (n12, n13, n23), (G12, G13, G23) = ORTHO3["E"], ORTHO3["nu"], ORTHO3["G"]
    nu = {(0, 1): n12, (0, 2): n13, (1, 2): n23}
    s = 7.0
    for i in range(3):
        eps = _strain(C, s * np.outer(R[i], R[i]))
        assert R[i] @ eps @ R[i] == pytest.approx(s / E[i], rel=1e-12)
        for j in range(3):
            if j != i:       # nu_ji / E_j = nu_ij / E_i
                nij = nu[(i, j)] if i < j else nu[(j, i)] * E[i] / E[j]
                assert R[j] @ eps @ R[j] == pytest.approx(-nij * s / E[i], rel=1e-12)
    for (i, j), G in (((0, 1), G12), ((0, 2), G13), ((1, 2), G23)):
        eps = _strain(C, s * (np.outer(R[i], R[j]) + np.outer(R[j], R[i])))
        assert 2 * R[i] @ eps @ R[j] == pytest.approx(s / G, rel=1e-12)


@pytest.mark.parametrize("plane", ["stress", "strain"])
def test_orthotropic_2d_plane_stress_and_strain(plane):
    """2D, a1 at 25 degrees: plane stress gives 1/E1, -nu12/E1, 1/G12 (the 2D data and
    the 3D data agree); plane strain gives the reduced compliance S_ij - S_i3 S_j3 / S_33
    of the 3D one (eps_33 = 0), written out here."""
    c, s_ = np.cos(np.radians(25.0)), np.sin(np.radians(25.0))
    a1, a2 = np.array([c, s_]), np.array([-s_, c])
    data = {**ORTHO3, "axes": [a1.tolist()]}
    C = elasticity_matrix({"orthotropic": data}, 2, plane)
    E1, E2, E3 = ORTHO3["E"]
    n12, n13, n23 = ORTHO3["nu"]
    S11, S22, S12 = 1 / E1, 1 / E2, -n12 / E1
    S13, S23, S33 = -n13 / E1, -n23 / E2, 1 / E3
    if plane == "strain":
        S11, S22, S12 = S11 - S13 ** 2 / S33, S22 - S23 ** 2 / S33, S12 - S13 * S23 / S33
    s = 3.0
    eps = _strain(C, s * np.outer(a1, a1))
    assert a1 @ eps @ a1 == pytest.approx(S11 * s, rel=1e-12)
    assert a2 @ eps @ a2 == pytest.approx(S12 * s, rel=1e-12)
    eps = _strain(C, s * np.outer(a2, a2))
    assert a2 @ eps @ a2 == pytest.approx(S22 * s, rel=1e-12)
    eps = _strain(C, s * (np.outer(a1, a2) + np.outer(a2, a1)))
    assert 2 * a1 @ eps @ a2 == pytest.approx(s / ORTHO3["G"][0], rel=1e-12)
    if plane == "stress":
        two = {"E": ORTHO3["E"][:2], "nu": ORTHO3["nu"][:1], "G": ORTHO3["G"][:1],
               "axes": [a1.tolist()]}
        np.testing.assert_allclose(elasticity_matrix({"orthotropic": two}, 2), C,
                                   rtol=1e-13, atol=1e-13 * np.abs(C).max())


@pytest.mark.parametrize("dim", [2, 3])
def test_voigt_matrix_of_the_isotropic_law(dim):
    """The isotropic law's Voigt matrix (engineering shears) is Elasticity's Cmat; m_E is
    2 mu (the smallest eigenvalue of the isotropic E)."""
    E, nu = 1000.0, 0.3
    if dim == 2:
        D = E / (1 - nu ** 2) * np.array([[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]])
    else:
        lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
        D = np.diag([2 * mu] * 3 + [mu] * 3) + np.pad(np.full((3, 3), lam), (0, 3))
    C = elasticity_matrix({"voigt": D.tolist()}, dim)
    np.testing.assert_allclose(C, Elasticity(E, nu, dim).Cmat, rtol=1e-14, atol=1e-12)
    assert energy_minimum(C, dim) == pytest.approx(E / (1 + nu), rel=1e-13)


def _bisection_projection(A, M, s, kappa):
    """argmin (p - s)^T A (p - s) s.t. p^T M p <= kappa^2: p(mu) = (A + mu M)^-1 A s with
    p^T M p decreasing in mu; mu by bisection to the last bit.  kappa = 0: the A-projection
    onto the null space of M (3D: the hydrostatic line I; 2D: {0})."""
    def p(mu):
        return np.linalg.solve(A + mu * M, A @ s)
    if s @ M @ s <= kappa ** 2:
        return s
    if kappa == 0.0:
        N = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0]) if len(s) == 6 else np.zeros(3)
        return N * (N @ A @ s) / (N @ A @ N) if N.any() else N
    lo, hi = 0.0, 1.0
    while p(hi) @ M @ p(hi) > kappa ** 2:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        lo, hi = (mid, hi) if p(mid) @ M @ p(mid) > kappa ** 2 else (lo, mid)
    return p(hi)


@pytest.mark.parametrize("dim", [2, 3])
def test_anisotropic_projection_against_bisection(dim):
    """VonMisesProjection (one orthotropic E) and CellProjection (E per cell: orthotropic
    with different axes, isotropic with different nu) equal the bisection's projection."""
    rng = np.random.default_rng(3)
    mats = []
    for angle in (0.0, 30.0, 75.0):
        axes = _axes3(angle, 2 * angle)[:2].tolist() if dim == 3 else \
            [[np.cos(np.radians(angle)), np.sin(np.radians(angle))]]
        mats.append(elasticity_matrix({"orthotropic": {**ORTHO3, "axes": axes}}, dim,
                                      "strain"))
    mats += [Elasticity(1000.0, nu, dim).Cmat for nu in (0.0, 0.3, 0.45)]
    n = 12
    index = np.arange(n) % len(mats)
    s = rng.normal(size=(n, 3 * dim - 3)) * 50.0
    kappa = rng.uniform(0.0, 40.0, n)
    kappa[0] = 0.0
    cells = CellElasticity(np.array(mats), index, dim)
    per_cell = make_projection(cells)(s, kappa)
    W = np.diag([1.0] * dim + [2.0] * (2 * dim - 3))
    M = cells.M
    for i in range(n):
        ref = _bisection_projection(W @ mats[index[i]], M, s[i], kappa[i])
        one = VonMisesProjection(MatrixElasticity(mats[index[i]], dim))(s[i:i + 1],
                                                                        kappa[i:i + 1])[0]
        scale = np.abs(s[i]).max()
        assert np.abs(one - ref).max() <= 1e-10 * scale
        assert np.abs(per_cell[i] - ref).max() <= 1e-10 * scale


def test_cell_elasticity_rows():
    """Rows selected (nested) act on their cells' matrices; apply refuses other rows."""
    mats = np.array([Elasticity(1000.0, 0.3, 2).Cmat, Elasticity(2000.0, 0.1, 2).Cmat])
    el = CellElasticity(mats, [0, 1, 1, 0, 1], 2)
    t = np.arange(15.0).reshape(5, 3)
    full = el.apply(t)
    for i in range(5):
        np.testing.assert_allclose(full[i], mats[el.index[i]] @ t[i], rtol=1e-15)
    with el.rows([1, 3, 4]):
        with el.rows([2, 0]):
            np.testing.assert_allclose(el.apply(t[[4, 1]]), full[[4, 1]], rtol=1e-15)
            assert el.Cmat.shape == (2, 3, 3)
        with pytest.raises(ValueError):
            el.apply(t)
    assert el.bounds() == pytest.approx((1000.0 / 1.3, 2000.0 / 0.9))


def _material(**section):
    raw = paper_raw()
    raw["material"] = {"viscoplastic": copy.deepcopy(raw["material"]["viscoplastic"]),
                       **section}
    return raw


@pytest.mark.parametrize("section, key, why", [
    ({"elasticity": {"orthotropic": {"E": [3, 1], "nu": [0.2], "G": [1],
                                     "axes": [[0, 0]]}}},
     "material.elasticity.orthotropic.axes", "zero"),
    ({"elasticity": {"orthotropic": {"E": [3, 1], "nu": [2.0], "G": [1], "axes": [[1, 0]]}}},
     "material.elasticity.orthotropic.nu", "not positive definite"),
    ({"plane": "strain", "elasticity": {"orthotropic": {"E": [3, 1], "nu": [0.2], "G": [1],
                                                        "axes": [[1, 0]]}}},
     "material.elasticity.orthotropic.E", "plane strain needs"),
    ({"elasticity": {"voigt": [[1, 2, 0], [2, 1, 0], [0, 0, 1]]}},
     "material.elasticity.voigt", "not positive definite"),
    ({"elasticity": {"voigt": [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]}},
     "material.elasticity.voigt", "not symmetric"),
    ({"E": 1000.0, "elasticity": {"voigt": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}},
     "material.elasticity", "instead of E and nu"),
    ({"E": "1000 - 2000*x", "nu": 0.3}, "material.E", "> 0"),
    ({"E": 1000.0, "nu": "0.3 + 0.3*y"}, "material.nu", "[0, 0.5)"),
])
def test_refusals(section, key, why):
    with pytest.raises(CaseError) as exc:
        validate_raw(_material(**section))
    assert f"{key}:" in str(exc.value) or f"{key} (" in str(exc.value)
    assert why in str(exc.value)


def test_axes_not_orthogonal_3d():
    raw = paper_raw()
    raw["mesh"] = {"dim": 3, "L1": 1.0, "L2": 1.0, "L3": 1.0, "n": 2}
    raw["boundaries"] = {"clamped": ["left"], "contact": []}
    del raw["contact"]
    raw["loads"] = {"traction": {"right": [1.0, 0.0, 0.0]}}
    raw["material"] = {"elasticity": {"orthotropic": {**ORTHO3,
                                                      "axes": [[1, 0, 0], [0.1, 1, 0]]}}}
    with pytest.raises(CaseError, match=r"material\.elasticity\.orthotropic\.axes.*not "
                                        r"orthogonal"):
        validate_raw(raw)


@pytest.mark.parametrize("dim", [2, 3])
def test_projection_invariant_under_a_factor_on_E(dim):
    """E(x) = c(x) E0 per cell: P_K is E0's in every cell (the energy norm's factor does not
    move the closest point).  nu(x) moves it in plane stress (the energy form does not
    split into deviator and trace there) and not for isotropic 3D E (radial return keeps
    the trace and scales the deviator whatever nu)."""
    rng = np.random.default_rng(5)
    m = 3 * dim - 3
    s, kappa = rng.normal(size=(6, m)) * 30.0, rng.uniform(1.0, 20.0, 6)
    base = Elasticity(1000.0, 0.3, dim)
    scaled = CellElasticity(np.array([c * base.Cmat for c in (0.1, 1.0, 7.0)]),
                            [0, 1, 2, 0, 1, 2], dim)
    ref = make_projection(base)(s, kappa)         # 3D: the closed form (RadialReturn)
    np.testing.assert_allclose(make_projection(scaled)(s, kappa), ref, rtol=0,
                               atol=1e-11 * np.abs(s).max())
    other = CellElasticity(Elasticity(1000.0, 0.45, dim).Cmat[None], np.zeros(6, int), dim)
    dev = np.abs(make_projection(other)(s, kappa) - ref).max()
    if dim == 2:
        assert dev > 1e-3 * np.abs(s).max()
    else:
        assert dev <= 1e-11 * np.abs(s).max()


@pytest.mark.parametrize("angle", [0.0, 0.4])
def test_out_of_plane_row_plane_strain(angle):
    """Plane strain with orthotropic 3D data: sigma_33 = r . t(sigma) equals the 3D law's
    sigma_33 at eps_33 = 0, computed here by rotating a strain into the material axes,
    applying C3 = S^-1 of the engineering constants written out, and rotating back; the
    isotropic constants give r = (nu, nu, 0)."""
    from vpcontact.case.anisotropy import out_of_plane_row
    E, nu, G = [1000.0, 400.0, 250.0], [0.25, 0.3, 0.35], [150.0, 120.0, 90.0]
    c, s = np.cos(angle), np.sin(angle)
    data = {"E": E, "nu": nu, "G": G, "axes": [[c, s]]}
    S = np.zeros((6, 6))
    S[:3, :3] = [[1 / E[0], -nu[0] / E[0], -nu[1] / E[0]],
                 [-nu[0] / E[0], 1 / E[1], -nu[2] / E[1]],
                 [-nu[1] / E[0], -nu[2] / E[1], 1 / E[2]]]
    S[3:, 3:] = np.diag([1 / G[2], 1 / G[1], 1 / G[0]])       # 23, 13, 12
    C3 = np.linalg.inv(S)
    R = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])   # rows: the material axes
    eps = np.array([[0.002, 0.0007, 0.0], [0.0007, -0.001, 0.0], [0.0, 0.0, 0.0]])
    el = R @ eps @ R.T
    e = np.array([el[0, 0], el[1, 1], el[2, 2], 2 * el[1, 2], 2 * el[0, 2], 2 * el[0, 1]])
    sl = C3 @ e
    sig_local = np.array([[sl[0], sl[5], sl[4]], [sl[5], sl[1], sl[3]], [sl[4], sl[3], sl[2]]])
    sig = R.T @ sig_local @ R
    r = out_of_plane_row(data)
    assert r @ [sig[0, 0], sig[1, 1], sig[0, 1]] == pytest.approx(sig[2, 2], rel=1e-12)
    iso = {"E": [1000.0] * 3, "nu": [0.3] * 3, "G": [1000.0 / 2.6] * 3, "axes": [[c, s]]}
    np.testing.assert_allclose(out_of_plane_row(iso), [0.3, 0.3, 0.0], atol=1e-14)
