"""Plane-stress Perzyna viscoplasticity of the paper (Section 4; MODEL.md section 2).

Stresses are stored per cell (DG0) as 2x2 arrays; the per-cell algebra uses the coordinates
t = (t11, t22, t12) and is vectorised over cells with numpy.  In these coordinates
- E acts as  (E tau) = Cmat t,      Cmat = [[l+m2, l, 0], [l, l+m2, 0], [0, 0, m2]],
- the energy form (E tau):tau = t^T A t,  A = diag(1, 1, 2) Cmat  (shear counted twice),
- the von Mises form ||tau||_VM^2 = t^T M t,  M = [[1, -1/2, 0], [-1/2, 1, 0], [0, 0, 3]],
with l = E s/(1-s^2), m2 = E/(1+s).

Perzyna law: Gfun(sigma, kappa) = -1/(2 lambda1) E (sigma - P sigma),
             Gk(sigma, kappa)   = 2/(3 lambda2) ||sigma - P sigma||_VM,
P = P_K(kappa) the projection onto K(kappa) = {||tau||_VM <= kappa} in the energy inner
product.  The projection is exact: P sigma = (A + mu M)^-1 A sigma with mu >= 0 the root of
||P sigma||_VM = kappa, found through the simultaneous diagonalisation of (A, M).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from forms.elasticity import plane_stress_constants


def to_voigt(tau: np.ndarray) -> np.ndarray:
    """(n, 2, 2) symmetric tensors -> (n, 3) coordinates (t11, t22, t12)."""
    tau = np.asarray(tau).reshape(-1, 2, 2)
    return np.stack([tau[:, 0, 0], tau[:, 1, 1], 0.5 * (tau[:, 0, 1] + tau[:, 1, 0])], axis=1)


def from_voigt(t: np.ndarray) -> np.ndarray:
    """(n, 3) coordinates -> (n, 2, 2) symmetric tensors."""
    t = np.asarray(t).reshape(-1, 3)
    out = np.empty((t.shape[0], 2, 2))
    out[:, 0, 0], out[:, 1, 1] = t[:, 0], t[:, 1]
    out[:, 0, 1] = out[:, 1, 0] = t[:, 2]
    return out


@dataclass(frozen=True)
class PlaneStress:
    """The plane-stress elasticity operator and the quadratic forms in t-coordinates."""

    E: float
    nu: float

    @property
    def Cmat(self) -> np.ndarray:
        lmbda, two_mu = plane_stress_constants(self.E, self.nu)
        return np.array([[lmbda + two_mu, lmbda, 0.0], [lmbda, lmbda + two_mu, 0.0],
                         [0.0, 0.0, two_mu]])

    @property
    def A(self) -> np.ndarray:
        return np.diag([1.0, 1.0, 2.0]) @ self.Cmat

    M = np.array([[1.0, -0.5, 0.0], [-0.5, 1.0, 0.0], [0.0, 0.0, 3.0]])

    def apply(self, t: np.ndarray) -> np.ndarray:
        """E tau for rows t (n, 3)."""
        return t @ self.Cmat.T

    def von_mises(self, t: np.ndarray) -> np.ndarray:
        """||tau||_VM for rows t (n, 3)."""
        return np.sqrt(np.maximum(np.einsum("ni,ij,nj->n", t, self.M, t), 0.0))


class VonMisesProjection:
    """Exact projection onto K(kappa) = {||tau||_VM <= kappa} in the norm (E tau : tau)^1/2.

    With V such that V^T A V = I and V^T M V = diag(lam) (computed once per material),
    P s = V diag(1 / (1 + mu lam)) V^T A s, and the root mu of ||P s||_VM = kappa solves the
    secular equation  1/sqrt(q(mu)) = 1/kappa,  q(mu) = sum_i lam_i z_i^2 / (1 + mu lam_i)^2,
    z = V^T A s.  1/sqrt(q) is concave and increasing in mu, so Newton from mu = 0 converges
    monotonically (as for the trust-region subproblem); iterations are vectorised over cells.
    """

    def __init__(self, law: PlaneStress, rtol: float = 1e-14, max_iter: int = 100):
        A, M = law.A, law.M
        L = np.linalg.cholesky(A)
        Linv = np.linalg.inv(L)
        lam, W = np.linalg.eigh(Linv @ M @ Linv.T)
        self.lam = np.clip(lam, 0.0, None)
        self.V = Linv.T @ W
        self.A, self.M = A, M
        self.rtol, self.max_iter = rtol, max_iter

    def __call__(self, s: np.ndarray, kappa: np.ndarray) -> np.ndarray:
        """Project rows s (n, 3) onto K(kappa) (kappa: (n,) >= 0); returns (n, 3)."""
        s = np.asarray(s, dtype=float).reshape(-1, 3)
        kappa = np.broadcast_to(np.asarray(kappa, dtype=float), (s.shape[0],))
        out = s.copy()
        vm = np.sqrt(np.maximum(np.einsum("ni,ij,nj->n", s, self.M, s), 0.0))
        outside = vm > kappa
        if not np.any(outside):
            return out
        z = (s[outside] @ self.A) @ self.V  # z = V^T A s per row
        k = kappa[outside]
        lam = self.lam
        mu = np.zeros(z.shape[0])
        zero = k <= 0.0
        active = ~zero
        for _ in range(self.max_iter):
            if not np.any(active):
                break
            za, ma, ka = z[active], mu[active], k[active]
            d = 1.0 + ma[:, None] * lam[None, :]
            q = np.sum(lam * za**2 / d**2, axis=1)
            dq = -2.0 * np.sum(lam**2 * za**2 / d**3, axis=1)
            phi = 1.0 / np.sqrt(q) - 1.0 / ka
            dphi = -0.5 * q ** (-1.5) * dq
            step = -phi / dphi
            mu[active] = ma + step
            done = np.abs(phi) * ka <= self.rtol
            idx = np.flatnonzero(active)
            active[idx[done]] = False
        if np.any(active):
            raise RuntimeError("von Mises projection: secular equation did not converge")
        factor = 1.0 / (1.0 + mu[:, None] * lam[None, :])
        # kappa = 0: mu -> infinity keeps only the directions with lam = 0 (none in plane stress).
        factor[zero] = (lam[None, :] == 0.0).astype(float)
        out[outside] = (z * factor) @ self.V.T
        return out


@dataclass(frozen=True)
class Perzyna:
    """Perzyna rates of the paper: (Gfun, Gk) at (sigma, kappa), rows in t-coordinates."""

    law: PlaneStress
    lambda1: float
    lambda2: float

    def __post_init__(self):
        object.__setattr__(self, "_project", VonMisesProjection(self.law))

    def project(self, t: np.ndarray, kappa: np.ndarray) -> np.ndarray:
        return self._project(t, kappa)

    def rates(self, t: np.ndarray, kappa: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gfun = -1/(2 lambda1) E (sigma - P sigma), Gk = 2/(3 lambda2) ||sigma - P sigma||_VM."""
        excess = t - self._project(t, kappa)
        return (-0.5 / self.lambda1) * self.law.apply(excess), \
            (2.0 / (3.0 * self.lambda2)) * self.law.von_mises(excess)
