"""Perzyna viscoplasticity of the paper (Section 4; MODEL.md section 2), in 2D and 3D.

Stresses are stored per cell (DG0) as d x d arrays; the per-cell algebra uses coordinates
t = (t11, t22, t12) in 2D and t = (t11, t22, t33, t23, t13, t12) in 3D, vectorised over cells:
- E acts as  (E tau) = Cmat t;  E tau = lmbda tr(tau) I + two_mu tau (plane stress in 2D,
  isotropic Hooke in 3D, see forms/elasticity.py);
- the energy form (E tau):tau = t^T A t,  A = diag(1.., 2..) Cmat  (shears counted twice);
- the von Mises form ||tau||_VM^2 = t^T M t: in 2D t11^2 + t22^2 - t11 t22 + 3 t12^2 (the
  paper), in 3D 3/2 dev(tau):dev(tau).

Perzyna law: Gfun(sigma, kappa) = -1/(2 lambda1) E (sigma - P sigma),
             Gk(sigma, kappa)   = 2/(3 lambda2) ||sigma - P sigma||_VM,
P = P_K(kappa) the projection onto K(kappa) = {||tau||_VM <= kappa} in the energy inner
product, exact in both dimensions (VonMisesProjection in 2D, RadialReturn in 3D).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from forms.elasticity import lame_constants

# (row, col) of the coordinates t_i in the d x d tensor
_PAIRS = {2: [(0, 0), (1, 1), (0, 1)],
          3: [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]}


def to_voigt(tau: np.ndarray, dim: int = 2) -> np.ndarray:
    """(n, d, d) symmetric tensors -> (n, m) coordinates (m = 3 in 2D, 6 in 3D)."""
    tau = np.asarray(tau).reshape(-1, dim, dim)
    return np.stack([0.5 * (tau[:, i, j] + tau[:, j, i]) for i, j in _PAIRS[dim]], axis=1)


def from_voigt(t: np.ndarray, dim: int = 2) -> np.ndarray:
    """(n, m) coordinates -> (n, d, d) symmetric tensors."""
    pairs = _PAIRS[dim]
    t = np.asarray(t).reshape(-1, len(pairs))
    out = np.empty((t.shape[0], dim, dim))
    for k, (i, j) in enumerate(pairs):
        out[:, i, j] = out[:, j, i] = t[:, k]
    return out


def _von_mises_matrix(dim: int) -> np.ndarray:
    if dim == 2:
        return np.array([[1.0, -0.5, 0.0], [-0.5, 1.0, 0.0], [0.0, 0.0, 3.0]])
    M = np.zeros((6, 6))
    M[:3, :3] = -0.5
    np.fill_diagonal(M[:3, :3], 1.0)
    M[3:, 3:] = 3.0 * np.eye(3)
    return M


@dataclass(frozen=True)
class Elasticity:
    """The elasticity operator and the quadratic forms in t-coordinates (d = 2 or 3)."""

    E: float
    nu: float
    dim: int = 2

    @property
    def m(self) -> int:
        return len(_PAIRS[self.dim])

    @property
    def Cmat(self) -> np.ndarray:
        lmbda, two_mu = lame_constants(self.E, self.nu, self.dim)
        d, m = self.dim, self.m
        C = two_mu * np.eye(m)
        C[:d, :d] += lmbda
        return C

    @property
    def weights(self) -> np.ndarray:
        """Frobenius weights of the coordinates: tau:sigma = sum w_i t_i s_i."""
        return np.array([1.0] * self.dim + [2.0] * (self.m - self.dim))

    @property
    def A(self) -> np.ndarray:
        return np.diag(self.weights) @ self.Cmat

    @property
    def M(self) -> np.ndarray:
        return _von_mises_matrix(self.dim)

    def apply(self, t: np.ndarray) -> np.ndarray:
        """E tau for rows t (n, m)."""
        return t @ self.Cmat.T

    def von_mises(self, t: np.ndarray) -> np.ndarray:
        """||tau||_VM for rows t (n, m)."""
        return np.sqrt(np.maximum(np.einsum("ni,ij,nj->n", t, self.M, t), 0.0))

    def to_voigt(self, tau):
        return to_voigt(tau, self.dim)

    def from_voigt(self, t):
        return from_voigt(t, self.dim)


def PlaneStress(E: float, nu: float) -> Elasticity:
    """The paper's plane-stress law (d = 2)."""
    return Elasticity(E, nu, 2)


class RadialReturn:
    """Closed-form projection onto K(kappa) in 3D for isotropic E.

    With tau = dev(tau) + tr(tau)/3 I, both forms split: (E tau):tau = two_mu dev:dev +
    (lmbda + two_mu/3) tr^2 and ||tau||_VM^2 = 3/2 dev:dev.  On deviators the energy form is
    a multiple of the Frobenius one, so the closest point in the energy norm keeps the
    hydrostatic part and scales the deviator radially:
        P tau = tr(tau)/3 I + min(1, kappa / ||tau||_VM) dev(tau).
    """

    def __init__(self, law: Elasticity):
        if law.dim != 3:
            raise ValueError("RadialReturn is the 3D projection")
        self.law = law

    def __call__(self, s: np.ndarray, kappa: np.ndarray) -> np.ndarray:
        s = np.asarray(s, dtype=float).reshape(-1, 6)
        kappa = np.broadcast_to(np.asarray(kappa, dtype=float), (s.shape[0],))
        vm = self.law.von_mises(s)
        scale = np.where(vm > kappa, kappa / np.where(vm > 0, vm, 1.0), 1.0)
        mean = s[:, :3].mean(axis=1, keepdims=True)
        out = s * scale[:, None]
        out[:, :3] = mean + (s[:, :3] - mean) * scale[:, None]
        return out


def make_projection(law: Elasticity):
    """The exact energy-norm projection onto the von Mises ball for this law."""
    return VonMisesProjection(law) if law.dim == 2 else RadialReturn(law)


class VonMisesProjection:
    """Exact projection onto K(kappa) = {||tau||_VM <= kappa} in the norm (E tau : tau)^1/2.

    With V such that V^T A V = I and V^T M V = diag(lam) (computed once per material),
    P s = V diag(1 / (1 + mu lam)) V^T A s, and the root mu of ||P s||_VM = kappa solves the
    secular equation  1/sqrt(q(mu)) = 1/kappa,  q(mu) = sum_i lam_i z_i^2 / (1 + mu lam_i)^2,
    z = V^T A s.  1/sqrt(q) is concave and increasing in mu, so Newton from mu = 0 converges
    monotonically (as for the trust-region subproblem); iterations are vectorised over cells.
    """

    def __init__(self, law: Elasticity, rtol: float = 1e-14, max_iter: int = 100):
        A, M = law.A, law.M
        self.m = A.shape[0]
        L = np.linalg.cholesky(A)
        Linv = np.linalg.inv(L)
        lam, W = np.linalg.eigh(Linv @ M @ Linv.T)
        self.lam = np.where(lam > 1e-12 * lam.max(), lam, 0.0)   # M may be singular (3D)
        self.V = Linv.T @ W
        self.A, self.M = A, M
        self.rtol, self.max_iter = rtol, max_iter

    def __call__(self, s: np.ndarray, kappa: np.ndarray) -> np.ndarray:
        """Project rows s (n, 3) onto K(kappa) (kappa: (n,) >= 0); returns (n, 3)."""
        s = np.asarray(s, dtype=float).reshape(-1, self.m)
        kappa = np.broadcast_to(np.asarray(kappa, dtype=float), (s.shape[0],))
        out = s.copy()
        bad = ~(np.isfinite(s).all(axis=1) & np.isfinite(kappa))
        out[bad] = np.nan                       # non-finite input propagates as NaN
        # P is positively homogeneous: P_{K(c kappa)}(c s) = c P_{K(kappa)}(s); scale each row
        # by max |s_i| so that the secular equation cannot overflow for huge stresses.
        scale = np.where(bad, 1.0, np.maximum(np.abs(np.where(bad[:, None], 0.0, s)).max(axis=1),
                                              1e-300))
        s = np.where(bad[:, None], 0.0, s) / scale[:, None]
        kappa = np.where(bad, 0.0, kappa) / scale
        vm = np.sqrt(np.maximum(np.einsum("ni,ij,nj->n", s, self.M, s), 0.0))
        outside = (vm > kappa) & ~bad
        if not np.any(outside):
            return out
        z = (s[outside] @ self.A) @ self.V  # z = V^T A s per row
        k = kappa[outside]
        lam = self.lam
        mu = np.zeros(z.shape[0])
        zero = k <= 0.0
        kk = np.where(zero, 1.0, k)
        lz2, l2z2 = lam * z**2, lam**2 * z**2
        for _ in range(self.max_iter):   # whole-array Newton steps (no compaction: cheaper)
            d = 1.0 + mu[:, None] * lam[None, :]
            q = np.sum(lz2 / d**2, axis=1)            # ||P s||_VM^2 at mu
            dq = -2.0 * np.sum(l2z2 / d**3, axis=1)
            phi = 1.0 / np.sqrt(q) - 1.0 / kk
            phi[zero] = 0.0
            if np.abs(phi * kk).max(initial=0.0) <= self.rtol:
                break
            mu = mu - phi / (-0.5 * q ** (-1.5) * dq)
        else:
            raise RuntimeError("von Mises projection: secular equation did not converge")
        factor = 1.0 / (1.0 + mu[:, None] * lam[None, :])
        # kappa = 0: mu -> infinity keeps only the directions with lam = 0 (none in plane stress).
        factor[zero] = (lam[None, :] == 0.0).astype(float)
        out[outside] = ((z * factor) @ self.V.T) * scale[outside, None]
        return out


@dataclass(frozen=True)
class Perzyna:
    """Perzyna rates of the paper: (Gfun, Gk) at (sigma, kappa), rows in t-coordinates."""

    law: Elasticity
    lambda1: float
    lambda2: float

    def __post_init__(self):
        object.__setattr__(self, "_project", make_projection(self.law))

    def project(self, t: np.ndarray, kappa: np.ndarray) -> np.ndarray:
        return self._project(t, kappa)

    def rates(self, t: np.ndarray, kappa: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gfun = -1/(2 lambda1) E (sigma - P sigma), Gk = 2/(3 lambda2) ||sigma - P sigma||_VM."""
        excess = t - self._project(t, kappa)
        return (-0.5 / self.lambda1) * self.law.apply(excess), \
            (2.0 / (3.0 * self.lambda2)) * self.law.von_mises(excess)
