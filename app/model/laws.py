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

A viscoplastic law written by a user (the user protocol) is any class, no base class needed,
in tensors rather than t-coordinates::

    class MyLaw:
        m = 1                                   # the number of internal variables kappa

        def __init__(self, elasticity, **params):   # the case's E, then the law's constants
            self.elasticity = elasticity

        def G(self, sigma, eps, kappa):         # (n, d, d), (n, d, d), (n, m) -> (n, d, d)
            ...

        def Gk(self, sigma, eps, kappa):        # the same arguments -> (n, m)
            ...

sigma, eps and kappa are numpy arrays over the n cells: sigma_{n-1}, eps(u_{n-1}) and
kappa_{n-1} in the explicit update (3.2)-(3.3) (eps_{n-1} = E^-1 (sigma_{n-1} - H_{n-1})),
sigma, kappa at the current iterate and the trial strain eps(u_n) in the implicit one; G must
be symmetric, and kappa starts at the case's ``kappa0`` in every component.  The
law receives the case's ``Elasticity`` (app/model/material.py: ``Cmat`` the (mt, mt) matrix
of E in t-coordinates, ``apply``, ``von_mises``, ``to_voigt``/``from_voigt``, ``dim``) as
the first argument of its constructor; from the command line (``material.viscoplastic.law:
python``) the class is built as ``Class(elasticity, **params)`` with the case's
``material.viscoplastic.params``; from the Python API ``Simulation(case, comm, law=...)``
takes the class (or any callable ``elasticity -> law``) or a law object already built.
Optional methods:

- ``dG(sigma, eps, kappa)`` -> (dG/dsigma (n, d, d, d, d), dG/dkappa (n, d, d, m)) and
  ``dGk(sigma, eps, kappa)`` -> (dGk/dsigma (n, m, d, d), dGk/dkappa (n, m, m)), entry
  [..., a, b] the derivative by sigma_ab: the implicit scheme's local Newton uses them
  (both, or neither: a finite-difference Jacobian then);
- ``rate_bound()`` -> r_max [1/s], the largest relaxation rate of the explicit update, for
  the stability indicator k r_max <= 2 (absent or None: no indicator from the law);
- ``name``, a string for the logs and summary.json (absent: the class's name).

``UserLaw`` (app/model/userlaw.py) turns such an object into a ViscoplasticLaw and checks
it (m, the shapes and finiteness of G and Gk); every ViscoplasticLaw gives ``G`` and ``Gk``
in tensors too, so a built-in law can stand wherever a user's law is expected.  A contact law
written by a user is a ``ScalarLaw`` subclass written with the primitives of ``backend(r)``:
it then serves both step solvers.
"""
from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from vpcontact.model.material import Elasticity


def elastic_strain(elasticity: Elasticity, t: np.ndarray) -> np.ndarray:
    """E^-1 tau: the strain of a stress, in t-coordinates.

    Args:
        elasticity: E, homogeneous (Cmat (mt, mt)) or per cell (Cmat (n, mt, mt)).
        t: rows (n, mt) of tau.

    Returns:
        The rows (n, mt) of E^-1 tau.
    """
    C = elasticity.Cmat
    if C.ndim == 2:
        return np.linalg.solve(C, np.asarray(t).T).T
    return np.linalg.solve(C, np.asarray(t)[:, :, None])[:, :, 0]


class ViscoplasticLaw(ABC):
    """A viscoplastic law: G and Gk of (1.2)-(1.3), vectorised over cells, no state.

    Args:
        elasticity: the elasticity E (its t-coordinates, E and the von Mises form).

    Attributes:
        m: the number of internal variables kappa (a class attribute).
    """

    m: int = 1
    name: str = "user law"
    uses_eps: bool = False     # rates and residual take the strain eps too (a user's law)
    # rate_at_stress is at the initial internal state and the rates fall as the law hardens
    # (Chaboche with Q >= 0): k r(S) above the limit is then a bound, not a prediction
    hardens: bool = False

    def __init__(self, elasticity: Elasticity):
        self.elasticity = elasticity

    def constants(self) -> dict[str, tuple[float, str]]:
        """The law's constants with their units (``check`` and summary.json list them).

        Returns:
            name -> (value, unit); {} where the law declares none.
        """
        return {}

    def describe(self) -> dict:
        """The law's name, m and constants (summary.json's "laws", ``check``).

        Returns:
            {"name", "m", "constants": {name: [value, unit]}, "lipschitz_constant"}.
        """
        return {"name": self.name, "m": self.m,
                "constants": {k: [v if isinstance(v, str) else float(v), u]
                              for k, (v, u) in self.constants().items()},
                "lipschitz_constant": self.lipschitz_constant()}

    def lipschitz_constant(self) -> float | None:
        """L_G of H(G): the Lipschitz constant of sigma -> G(sigma, kappa), uniform in kappa,
        in the energy norm |tau|_E = (E tau : tau)^1/2.

        Returns:
            L_G [1/s], or None where the law does not know it (no bound: the stability
            indicator is then estimated, app/post/diagnostics.py).
        """
        return None

    def rate_at_stress(self, S: float) -> float | None:
        """The relaxation rate of the explicit update linearised at stresses of von Mises
        norm up to S (the data's stress scale), for a law whose rate grows with the stress
        (Norton's, Chaboche's: the stability indicator k_max r(S) <= 2 of
        app/post/diagnostics.py); by default the stated ``relaxation_rate`` (else L_G),
        which holds at every stress.

        Args:
            S: the stress scale [Pa].

        Returns:
            r(S) [1/s], or None where the law does not know it.
        """
        rate = self.relaxation_rate()
        return self.lipschitz_constant() if rate is None else rate

    @abstractmethod
    def rates(self, t: np.ndarray, kappa: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """G and Gk of (1.2)-(1.3) per cell.

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, m) internal variables.

        Returns:
            (G, Gk): G rows (n, mt) in t-coordinates, Gk (n, m).
        """

    def G(self, sigma: np.ndarray, eps: np.ndarray, kappa: np.ndarray) -> np.ndarray:
        """G(sigma, kappa) of (1.2) in tensors, the user protocol's form of ``rates``.

        Args:
            sigma: (n, d, d) stresses.
            eps: (n, d, d) strains (not used by a law of sigma and kappa).
            kappa: (n, m) internal variables.

        Returns:
            (n, d, d) tensors G.
        """
        el = self.elasticity
        return el.from_voigt(self.rates(el.to_voigt(sigma), kappa)[0])

    def Gk(self, sigma: np.ndarray, eps: np.ndarray, kappa: np.ndarray) -> np.ndarray:
        """Gk(sigma, kappa) of (1.3), the user protocol's form of ``rates``.

        Args:
            sigma: (n, d, d) stresses.
            eps: (n, d, d) strains (not used by a law of sigma and kappa).
            kappa: (n, m) internal variables.

        Returns:
            (n, m) rates Gk.
        """
        return self.rates(self.elasticity.to_voigt(sigma), kappa)[1]

    def rate_bound(self) -> float | None:
        """The user protocol's name of ``relaxation_rate``.

        Returns:
            r_max [1/s], or None.
        """
        return self.relaxation_rate()

    def implicit_jacobian(self, z: np.ndarray, s_tr: np.ndarray, kappa_prev: np.ndarray,
                          k: float) -> np.ndarray | None:
        """The Jacobian of ``implicit_residual`` by z, where the law knows it.

        Args:
            z: (n, mt + m) unknowns: sigma in t-coordinates, then kappa.
            s_tr: (n, mt) trial stresses.
            kappa_prev: (n, m) kappa_{n-1}.
            k: the time step k_n.

        Returns:
            (n, mt + m, mt + m), or None: the local solve then takes finite differences.
        """
        return None

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
    A law that ``uses_eps`` gets eps_{n-1} too, E^-1 (sigma_{n-1} - H_{n-1}), exact before
    H is updated (sigma_{n-1} = E eps(u_{n-1}) + H_{n-1}); the other laws pay nothing for it.

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
        if self.law.uses_eps:          # eps_{n-1} = E^-1 (sigma_{n-1} - H_{n-1}) (3.2)
            t = el.to_voigt(sigma)
            eps = elastic_strain(el, t - el.to_voigt(H))
            g_sigma, g_kappa = self.law.rates(t, kappa, eps)
        else:
            g_sigma, g_kappa = self.law.rates(el.to_voigt(sigma), kappa)
        H[:] += k * el.from_voigt(g_sigma).reshape(-1)
        kappa[:] += k * g_kappa


class ScalarLaw:
    """The interface of a law of one scalar per node: no state, vectorised.

    Subclasses write ``energy``, ``derivative`` and ``second_derivative`` with the
    primitives of ``backend(r)``; ``name`` names the term in the forms' list of terms.
    """

    name = "contact law"

    def constants(self) -> dict[str, tuple[object, str]]:
        """The law's constants with their units (``check`` lists them).

        Returns:
            name -> (value, unit); {} where the law declares none.
        """
        return {}

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
