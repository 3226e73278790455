"""Norton's creep law (no yield surface), m = 1, kappa = p the accumulated creep strain:
with sigma_eq = ||sigma||_VM and the flow direction N = d sigma_eq / d sigma
(= (3/2) dev(sigma) / sigma_eq in 3D),
    eps_vp' = A sigma_eq^n N,   G(sigma, p) = -E eps_vp',   Gk(sigma, p) = p' = A sigma_eq^n,
the pair (G, Gk) of (1.2)-(1.3).

The flow direction is the gradient of the body's von Mises form ||tau||_VM^2 = t^T M t
(app/model/material.py) with respect to the tensor: in t-coordinates the shears count twice
in tau : sigma (Elasticity.weights w), so N_t = M t / (w sigma_eq).  In 3D this is
(3/2) dev(sigma) / sigma_eq.  In 2D the norm is the paper's t11^2 + t22^2 - t11 t22 + 3 t12^2,
the 3D von Mises norm of the in-plane stress with sigma_33 = 0: in plane stress that is the
stress state, and in plane strain the 2D model keeps the same norm (the out-of-plane stress
is not a variable of the 2D model), so N is the gradient of the paper's norm in both; its
in-plane part drives the stress (the out-of-plane creep strain -(N11 + N22) of plane stress
only thins the plate).
"""
from __future__ import annotations

import numpy as np

from vpcontact.model.laws import ViscoplasticLaw
from vpcontact.model.material import Elasticity


def flow_direction(t: np.ndarray, M: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The von Mises norm and sigma_eq N = M t / w, its gradient times the norm, per row.

    Args:
        t: rows (n, mt) of sigma in t-coordinates (tensor components).
        M: the (mt, mt) von Mises form, ||tau||_VM^2 = t^T M t.
        w: the (mt,) Frobenius weights of the coordinates (2 for the shears).

    Returns:
        (sigma_eq (n,), sigma_eq N (n, mt)): N = d sigma_eq / d sigma in t-coordinates
        (tensor components); sigma_eq N = (3/2) dev(sigma) in 3D, 0 where sigma = 0.
    """
    Mt = t @ M
    return np.sqrt(np.maximum(np.einsum("ni,ni->n", Mt, t), 0.0)), Mt / w


class Norton(ViscoplasticLaw):
    """Norton's creep law (see the module docstring), m = 1, kappa = p:
    G = -A sigma_eq^n E N, Gk = A sigma_eq^n.  The explicit update is the protocol's numpy
    ExplicitUpdate; the law flows wherever sigma != 0, so ``elastic`` (the implicit update's
    cells kept at the trial state) is exactly sigma_eq = 0.  The relaxation rate
    n A sigma_eq^(n-1) E grows with the stress: a rate (and the stability indicator) only
    for n = 1.

    Args:
        elasticity: the elasticity E.
        A: the Norton coefficient A > 0 [Pa^-n s^-1].
        n: the Norton exponent n >= 1.
    """

    m = 1
    name = "norton"
    fields = (("p", 1),)         # kappa written to solution.xdmf as the field p

    def __init__(self, elasticity: Elasticity, A: float, n: float):
        super().__init__(elasticity)
        self.A, self.n = A, n
        self._M, self._w = elasticity.M, elasticity.weights

    def constants(self):
        """Returns: A [Pa^-n s^-1], n [-] (as the case file's keys)."""
        return {"A": (self.A, "Pa^-n s^-1"), "n": (self.n, "-")}

    def _linear_part(self) -> np.ndarray:
        """The matrix of sigma -> E N' sigma in t-coordinates, N' sigma = sigma_eq N
        (= (3/2) dev(sigma) in 3D): G = -A E N' sigma for n = 1."""
        return self.elasticity.Cmat @ (self._M / self._w[:, None])

    def relaxation_rate(self) -> float | None:
        """For n = 1 the law is linear, sigma' = -A E N' sigma: E N' = W^-1 A_E W^-1 M (A_E
        the energy form, W the weights) has real eigenvalues >= 0, and the largest, times A,
        is the rate (3 mu A in 3D, on the deviators); for n > 1 the rate n A sigma_eq^(n-1)
        grows with the stress: None.

        Returns:
            r_max [1/s] for n = 1, else None.
        """
        if self.n != 1:
            return None
        return self.A * float(np.max(np.linalg.eigvals(self._linear_part()).real))

    def lipschitz_constant(self) -> float | None:
        """L_G of H(G) in the energy norm |tau|_E = (E tau : tau)^1/2: for n = 1, A times
        the operator norm of E N' in that norm (r_max where E and N' commute, as for
        isotropic E); for n > 1 none (not Lipschitz).

        Returns:
            L_G [1/s] for n = 1, else None.
        """
        if self.n != 1:
            return None
        T, A_E = self._linear_part(), self.elasticity.A
        adjoint_T = np.linalg.solve(A_E, T.T @ A_E)
        return self.A * float(np.sqrt(np.max(np.linalg.eigvals(adjoint_T @ T).real)))

    def creep_rate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The creep strain rate eps_vp' = A sigma_eq^n N and p' = A sigma_eq^n.

        Args:
            t: rows (n, mt) of sigma in t-coordinates.

        Returns:
            (eps_vp' rows (n, mt) in t-coordinates (tensor components), p' (n,)).
        """
        seq, seq_N = flow_direction(t, self._M, self._w)
        with np.errstate(over="ignore"):
            f = self.A * seq ** (self.n - 1.0)           # 0^0 = 1: n = 1 at sigma = 0
        return f[:, None] * seq_N, f * seq

    def rates(self, t, kappa):
        """G = -E eps_vp' = -A sigma_eq^n E N, Gk = A sigma_eq^n (kappa = p does not enter).

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, 1) accumulated creep strains p (unused).

        Returns:
            (G rows (n, mt), Gk (n, 1)).
        """
        eps_vp, p_rate = self.creep_rate(t)
        return -self.elasticity.apply(eps_vp), p_rate[:, None]

    def elastic(self, t, kappa):
        """No creep exactly where sigma_eq = 0 (the rates are exactly 0 there).

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, 1) accumulated creep strains (unused).

        Returns:
            (n,) booleans.
        """
        return flow_direction(t, self._M, self._w)[0] == 0.0
