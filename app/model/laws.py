"""The law protocols of the model: every built-in law implements them, and so does a law
written by a user.

- ``ViscoplasticLaw``: the pair (G, Gk) of (1.2)-(1.3), sigma' = E eps(u') + G(sigma, kappa),
  kappa' = Gk(sigma, kappa), kappa in R^m.  A law holds no state: it declares ``m``, the
  number of internal variables kappa, and gives G and Gk vectorised over cells (``rates``:
  sigma in t-coordinates (n, mt) and kappa (n, m) in, G (n, mt) and Gk (n, m) out;
  app/model/material.py describes the t-coordinates).  From them it builds the two updates a
  run calls, each an object that keeps its own work arrays:
  ``explicit()``, H_n = H_{n-1} + k_n G(sigma_{n-1}, kappa_{n-1}), kappa_n = kappa_{n-1} +
  k_n Gk(sigma_{n-1}, kappa_{n-1}) (3.2)-(3.3), in numpy from ``rates`` by default
  (``ExplicitUpdate``); ``implicit()``, the backward-Euler variant's local solve
  (app/model/implicit.py), whose residual is ``implicit_residual`` (by default from
  ``rates``).
- ``ScalarLaw``: a contact law of one scalar per node on Gamma3 (normal compliance P, the
  friction potential psi, ...): energy, derivative and second derivative, vectorised over
  nodes, written with the primitives of app/model/primitives.py so that one definition
  serves numpy (the condensed solver's nodal problem) and UFL (the step energy J_n).

The built-in laws: app/model/viscoplastic.py (Perzyna, PowerLaw), app/model/contact_laws.py.
"""
from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from vpcontact.model.material import Elasticity


class ViscoplasticLaw(ABC):
    """A viscoplastic law: G and Gk of (1.2)-(1.3), vectorised over cells, no state.

    Args:
        elasticity: the elasticity E (its t-coordinates, E and the von Mises form).

    Attributes:
        m: the number of internal variables kappa (a class attribute).
    """

    m: int = 1

    def __init__(self, elasticity: Elasticity):
        self.elasticity = elasticity

    @abstractmethod
    def rates(self, t: np.ndarray, kappa: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """G and Gk of (1.2)-(1.3) per cell.

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, m) internal variables.

        Returns:
            (G, Gk): G rows (n, mt) in t-coordinates, Gk (n, m).
        """

    def elastic(self, t: np.ndarray, kappa: np.ndarray) -> np.ndarray:
        """The cells where the law does not flow (G = 0, Gk = 0): the implicit update keeps
        the trial state there.

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, m) internal variables.

        Returns:
            (n,) booleans.
        """
        G, Gk = self.rates(t, kappa)
        return ~(np.any(G != 0.0, axis=1) | np.any(Gk != 0.0, axis=1))

    def implicit_residual(self, z: np.ndarray, s_tr: np.ndarray, kappa_prev: np.ndarray,
                          k: float) -> np.ndarray:
        """The backward-Euler local residual: R_s = sigma - s_tr - k G(sigma, kappa),
        R_k = kappa - kappa_{n-1} - k Gk(sigma, kappa).

        Args:
            z: (n, mt + m) unknowns: sigma in t-coordinates, then kappa.
            s_tr: (n, mt) trial stresses E eps(u_n) + H_{n-1}.
            kappa_prev: (n, m) kappa_{n-1}.
            k: the time step k_n.

        Returns:
            The (n, mt + m) residuals.
        """
        mt = self.elasticity.m
        G, Gk = self.rates(z[:, :mt], z[:, mt:])
        r = np.empty_like(z)
        r[:, :mt] = z[:, :mt] - s_tr - k * G
        r[:, mt:] = z[:, mt:] - kappa_prev - k * Gk
        return r

    def relaxation_rate(self) -> float | None:
        """The largest relaxation rate r_max of the explicit update (3.2): the explicit
        scheme is stable for k r_max <= 2 (app/post/diagnostics.py).

        Returns:
            r_max, or None where the law does not know it (no stability indicator then).
        """
        return None

    def explicit(self) -> ExplicitUpdate:
        """Returns: the explicit update (3.2)-(3.3) of this law, in numpy."""
        return ExplicitUpdate(self)

    def implicit(self, rtol: float = 1e-12, max_iter: int = 60):
        """The backward-Euler local solve of this law (app/model/implicit.py).

        Args:
            rtol: tolerance of the scaled local residual.
            max_iter: local Newton iterations allowed.

        Returns:
            A BackwardEuler.
        """
        from vpcontact.model.implicit import BackwardEuler
        return BackwardEuler(self, rtol, max_iter)


class ExplicitUpdate:
    """H += k G(sigma, kappa), kappa += k Gk(sigma, kappa) in place (3.2)-(3.3), in numpy.

    Args:
        law: the ViscoplasticLaw.
    """

    def __init__(self, law: ViscoplasticLaw):
        self.law = law

    def __call__(self, sigma: np.ndarray, H: np.ndarray, kappa: np.ndarray, k: float) -> None:
        """One explicit step of the history terms; nothing is written if it fails.

        Args:
            sigma: sigma_{n-1} per cell, flat (ncells * d * d).
            H: H_{n-1} per cell, same layout; becomes H_n.
            kappa: kappa_{n-1}, (ncells, m); becomes kappa_n.
            k: the step k_n.

        Raises:
            RuntimeError: the law's evaluation failed (e.g. a projection did not converge).
        """
        el = self.law.elasticity
        g_sigma, g_kappa = self.law.rates(el.to_voigt(sigma), kappa)
        H[:] += k * el.from_voigt(g_sigma).reshape(-1)
        kappa[:] += k * g_kappa


class ScalarLaw:
    """The interface of a law of one scalar per node: no state, vectorised.

    Subclasses write ``energy``, ``derivative`` and ``second_derivative`` with the
    primitives of ``backend(r)``; ``name`` names the term in the forms' list of terms.
    """

    name = "contact law"

    def energy(self, r):
        """The energy.

        Args:
            r: the variable at the nodes (numpy array or number) or a UFL expression.

        Returns:
            The energy, elementwise.
        """
        raise NotImplementedError

    def derivative(self, r):
        """The first derivative of ``energy``.

        Args:
            r: as for ``energy``.

        Returns:
            The derivative, elementwise.
        """
        raise NotImplementedError

    def second_derivative(self, r):
        """The second derivative of ``energy``.

        Args:
            r: as for ``energy``.

        Returns:
            The second derivative, elementwise.
        """
        raise NotImplementedError
