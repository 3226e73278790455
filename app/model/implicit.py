"""Right-end-point (implicit, backward-Euler) variant of the history terms, for any
viscoplastic law (app/model/viscoplastic.py).

Instead of the paper's left-end-point sums (3.2)-(3.3), step n uses sigma_n, kappa_n in G
and Gk:
    sigma_n = E eps(u_n) + H_{n-1} + k_n G(sigma_n, kappa_n),
    kappa_n = kappa_{n-1} + k_n Gk(sigma_n, kappa_n),
i.e. per cell, with the trial stress s_tr = E eps(u_n) + H_{n-1} (H_{n-1} = sigma_{n-1} -
E eps(u_{n-1})), the law's ``implicit_residual`` (R_s, R_k) = 0; for Perzyna's law
    R_s = sigma - s_tr + k/(2 lambda1) E (sigma - P_kappa sigma) = 0,
    R_k = kappa - kappa_{n-1} - k 2/(3 lambda2) ||sigma - P_kappa sigma||_VM = 0.
This local system is solved by a vectorised Newton iteration (the law's
``implicit_jacobian`` where it gives one, else a finite-difference Jacobian of size mt + m;
backtracking on the residual norm) inside every evaluation of the global residual; the global
Jacobian uses the algorithmic tangent d sigma / d eps = [J_loc^-1]_{sigma sigma} E.  A law of
the strain too (``uses_eps``, a user's law, app/model/laws.py) gets the trial strain eps(u_n),
fixed during the local iteration; the tangent leaves out its d G / d eps (Newton's rate,
not the solution).
The update is dissipative for any k (backward Euler of a monotone relaxation), which is why it
stays bounded where the explicit scheme's stability limit k r_max <= 2 is exceeded.
"""
from __future__ import annotations

import numpy as np


class LocalFailure(RuntimeError):
    """The local Newton iteration of the implicit update failed at some cells."""


def _solve(J, r):
    """J^-1 r (J^-1 for r None); a singular J (a law's overflow) is a LocalFailure, so
    that the step solver can shorten its step."""
    try:
        return np.linalg.inv(J) if r is None else np.linalg.solve(J, r)
    except np.linalg.LinAlgError:
        raise LocalFailure("implicit update: singular local Jacobian") from None


class BackwardEuler:
    """Vectorised per-cell solver of a law's implicit update; sigma in t-coordinates (n, mt),
    kappa (n, m).

    Args:
        law: the viscoplastic law (its elasticity E and ``implicit_residual``).
        rtol: tolerance of the scaled local residual.
        max_iter: local Newton iterations allowed.
    """

    def __init__(self, law, rtol: float = 1e-12, max_iter: int = 60):
        self.law = law
        self.elasticity = law.elasticity
        self.m = self.elasticity.m
        self.rtol, self.max_iter = rtol, max_iter

    def _residual(self, z, s_tr, kappa_prev, k, eps, rows=None):
        """The law's residual; eps (the trial strain) only for a law that uses it; ``rows``:
        the cells of z's rows for an E per cell (CellElasticity.rows)."""
        with self.elasticity.rows(rows):
            if eps is None:
                return self.law.implicit_residual(z, s_tr, kappa_prev, k)
            return self.law.implicit_residual(z, s_tr, kappa_prev, k, eps)

    def _jacobian(self, z, r0, s_tr, kappa_prev, k, scale, eps=None, rows=None):
        """The law's Jacobian of the residual where it gives one, else finite differences
        (``rows`` as for _residual)."""
        with self.elasticity.rows(rows):
            J = self.law.implicit_jacobian(z, s_tr, kappa_prev, k) if eps is None else \
                self.law.implicit_jacobian(z, s_tr, kappa_prev, k, eps)
        if J is not None:
            return J
        n, m1 = z.shape
        J = np.empty((n, m1, m1))
        for j in range(m1):
            h = 1e-7 * (np.abs(z[:, j]) + scale)
            zp = z.copy()
            zp[:, j] += h
            J[:, :, j] = (self._residual(zp, s_tr, kappa_prev, k, eps, rows) - r0) / \
                h[:, None]
        return J

    def solve(self, s_tr, kappa_prev, k, eps=None):
        """Solve the local system per cell.

        Cells where the law does not flow at the trial state are elastic: sigma = s_tr.

        Args:
            s_tr: (n, mt) trial stresses E eps(u_n) + H_{n-1} in t-coordinates.
            kappa_prev: (n, m) kappa_{n-1}.
            k: the time step k_n.
            eps: (n, mt) the trial strain eps(u_n) in t-coordinates, for a law that
                ``uses_eps`` (else None); fixed during the local iteration.

        Returns:
            (sigma_n (n, mt), kappa_n (n, m), C_alg (n, mt, mt)): C_alg maps d eps
            (t-coordinates) to d sigma, the algorithmic tangent.

        Raises:
            LocalFailure: if the local Newton iteration stalls or does not converge.
        """
        m = self.m
        n = s_tr.shape[0]
        sigma, kappa = s_tr.copy(), kappa_prev.copy()
        C = np.broadcast_to(self.elasticity.Cmat, (n, m, m)).copy()
        flow = ~(self.law.elastic(s_tr, kappa_prev) if eps is None else
                 self.law.elastic(s_tr, kappa_prev, eps))
        if not np.any(flow):
            return sigma, kappa, C
        st, kp = s_tr[flow], kappa_prev[flow]
        cells = np.flatnonzero(flow)            # the rows of an E per cell
        ep = None if eps is None else eps[flow]
        scale = np.maximum(np.abs(st).max(axis=1), 1e-300)[:, None] * \
            np.ones((1, m + kp.shape[1]))
        scale[:, m:] = np.maximum(scale[:, :1], kp)
        z = np.column_stack([st, kp])
        r = self._residual(z, st, kp, k, ep, cells)
        norm = np.linalg.norm(r / scale, axis=1)
        for _ in range(self.max_iter):
            active = norm > self.rtol
            if not np.any(active):
                break
            epa = None if ep is None else ep[active]
            J = self._jacobian(z[active], r[active], st[active], kp[active], k,
                               scale[active, 0], epa, cells[active])
            dz = -_solve(J, r[active][:, :, None])[:, :, 0]
            step = np.ones(dz.shape[0])
            za, sa, ka, sca = z[active], st[active], kp[active], scale[active]
            new_norm = np.full(dz.shape[0], np.inf)
            for _ls in range(20):   # backtracking on the scaled residual norm
                trial = za + step[:, None] * dz
                rt = self._residual(trial, sa, ka, k, epa, cells[active])
                nt = np.linalg.norm(rt / sca, axis=1)
                better = (nt < norm[active] * (1 - 1e-4 * step)) | (nt <= self.rtol)
                accept = better & np.isinf(new_norm)
                new_norm[accept] = nt[accept]
                idx = np.flatnonzero(active)[accept]
                z[idx], r[idx] = trial[accept], rt[accept]
                if np.all(np.isfinite(new_norm)):
                    break
                step[~np.isfinite(new_norm)] *= 0.5
            stalled = ~np.isfinite(new_norm)
            idx = np.flatnonzero(active)
            norm[idx[~stalled]] = new_norm[~stalled]
            if np.any(stalled):
                raise LocalFailure("implicit Perzyna update: no descent in the local Newton "
                                   f"iteration at {int(stalled.sum())} cell(s)")
        if np.any(norm > self.rtol):
            raise LocalFailure(f"implicit Perzyna update did not converge at "
                               f"{int((norm > self.rtol).sum())} cell(s)")
        J = self._jacobian(z, r, st, kp, k, scale[:, 0], ep, cells)
        Jinv = _solve(J, None)
        sigma[flow], kappa[flow] = z[:, :m], z[:, m:]
        with self.elasticity.rows(cells):
            C[flow] = Jinv[:, :m, :m] @ self.elasticity.Cmat
        return sigma, kappa, C
