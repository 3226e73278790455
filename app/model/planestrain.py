"""The out-of-plane stress of a 2D creep law in plane strain (laws norton and chaboche).

In plane strain the body is long in x3: eps_33 = 0, eps_13 = eps_23 = 0, but sigma_33 != 0.
A law whose creep strain eps_vp is isochoric (tr eps_vp = 0) has eps_vp33 = -(eps_vp11 +
eps_vp22) != 0, so the elastic strain eps_33 - eps_vp33 = -eps_vp33 carries a stress:
with the 3D constants E, nu of an isotropic E,
    sigma_33 = nu (sigma_11 + sigma_22) - E eps_vp33,
and the 3D stress (sigma_11, sigma_22, sigma_33, sigma_12) is the one of the law's von Mises
norm and flow direction.  The in-plane stress is sigma = E_ps (eps - eps_vp) - lambda
eps_vp33 I (E_ps the plane-strain E of the 2D model, lambda the 3D Lame constant), so
    G = -(C3 eps_vp')_in-plane = -(E_ps eps_vp'_in-plane + lambda eps_vp33' I)
(C3 the 3D E): the rate H' of (3.2) of the 3D law with eps_33 = 0.  The law carries eps_vp33
as one more internal variable (kappa' gets eps_vp33').

The 2D model's E in plane strain is the isotropic plane-stress form with the moduli of
forms.elasticity.plane_strain_moduli, E tau = lambda tr(tau) I + 2 mu tau with the 3D Lame
constants: lambda and 2 mu are read off its matrix (Cmat[0, 1] and Cmat[2, 2]), one E for
the body or one per cell (CellElasticity), and nu = lambda / (2 (lambda + mu)), E = mu (3
lambda + 2 mu) / (lambda + mu).  An anisotropic E in plane strain does not give the
out-of-plane coupling (its 2D matrix is the in-plane block only): refused.
"""
from __future__ import annotations

import numpy as np

from vpcontact.model.material import ElasticityForms

# the 3D t-coordinates (11, 22, 33, 23, 13, 12) of the 2D ones (11, 22, 12)
IN_3D = [0, 1, 5]


def matrices(elasticity: ElasticityForms) -> np.ndarray:
    """Every distinct matrix of E in t-coordinates.

    Args:
        elasticity: a 2D elasticity (homogeneous: one matrix; per cell: its ``mats``).

    Returns:
        (g, 3, 3) matrices (g = 1 for a homogeneous E).
    """
    if elasticity.homogeneous:
        return np.asarray(elasticity.Cmat, dtype=float).reshape(1, 3, 3)
    return np.asarray(elasticity.mats, dtype=float)


def isotropic_rows(C: np.ndarray) -> np.ndarray:
    """Which 2D matrices are isotropic: lambda tr(tau) I + 2 mu tau.

    Args:
        C: (g, 3, 3) matrices in t-coordinates.

    Returns:
        (g,) booleans: the matrix is [[l + 2m, l, 0], [l, l + 2m, 0], [0, 0, 2m]].
    """
    scale = np.abs(C).max(axis=(1, 2))[:, None]
    want = np.zeros_like(C)
    want[:, :2, :2] = C[:, 0, 1][:, None, None]
    want[:, [0, 1, 2], [0, 1, 2]] += C[:, 2, 2][:, None]
    return np.all(np.abs(C - want).reshape(len(C), -1) <= 1e-12 * scale, axis=1)


def isotropic(elasticity: ElasticityForms) -> bool:
    """Whether a 2D E is isotropic in every cell: lambda tr(tau) I + 2 mu tau.

    Args:
        elasticity: a 2D elasticity (homogeneous or per cell).

    Returns:
        True if every matrix is [[l + 2m, l, 0], [l, l + 2m, 0], [0, 0, 2m]].
    """
    return bool(np.all(isotropic_rows(matrices(elasticity))))


class PlaneStrain:
    """The out-of-plane stress sigma_33 and the rate G of a creep strain in plane strain
    (module docstring), vectorised over cells (the elasticity's selected rows).

    Args:
        elasticity: the 2D model's E in plane strain (isotropic, homogeneous or per cell).

    Raises:
        ValueError: if E is not 2D or not isotropic in some cell.
    """

    def __init__(self, elasticity: ElasticityForms):
        if elasticity.dim != 2 or not isotropic(elasticity):
            raise ValueError("plane strain with sigma_33: the law needs an isotropic E "
                             "(material.E, material.nu), not an anisotropic one")
        self.elasticity = elasticity

    def lame(self) -> tuple:
        """The 3D Lame constants of the selected rows.

        Returns:
            (lambda, 2 mu): numbers (one E) or (n,) arrays (one per selected cell).
        """
        C = self.elasticity.Cmat
        return C[..., 0, 1], C[..., 2, 2]

    def young_poisson(self) -> tuple:
        """The 3D constants E and nu of the selected rows (from lambda and mu).

        Returns:
            (E, nu): numbers or (n,) arrays.
        """
        lmbda, two_mu = self.lame()
        mu = 0.5 * two_mu
        return mu * (3.0 * lmbda + two_mu) / (lmbda + mu), lmbda / (2.0 * (lmbda + mu))

    def stress(self, t: np.ndarray, eps_vp33: np.ndarray) -> np.ndarray:
        """The 3D stress (sigma_33 = nu (sigma_11 + sigma_22) - E eps_vp33).

        Args:
            t: rows (n, 3) of the in-plane sigma in t-coordinates.
            eps_vp33: (n,) the out-of-plane creep strains.

        Returns:
            The rows (n, 6) of sigma in 3D t-coordinates (sigma_13 = sigma_23 = 0).
        """
        E, nu = self.young_poisson()
        s = np.zeros((t.shape[0], 6))
        s[:, IN_3D] = t
        s[:, 2] = nu * (t[:, 0] + t[:, 1]) - E * eps_vp33
        return s

    def G(self, eps_vp: np.ndarray) -> np.ndarray:
        """G = -(C3 eps_vp)_in-plane = -(E_ps eps_vp_in-plane + lambda eps_vp33 I).

        Args:
            eps_vp: rows (n, 6) of a creep strain rate in 3D t-coordinates.

        Returns:
            The rows (n, 3) of G in t-coordinates.
        """
        lmbda = self.lame()[0]
        G = -self.elasticity.apply(eps_vp[:, IN_3D])
        G[:, :2] -= (lmbda * eps_vp[:, 2])[:, None]
        return G
