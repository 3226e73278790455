"""A viscoplastic law written by a user, in the user protocol of app/model/laws.py (``m``,
``G(sigma, eps, kappa)``, ``Gk(sigma, eps, kappa)`` in tensors, optionally ``dG``, ``dGk``,
``rate_bound``), as a ViscoplasticLaw: ``UserLaw`` converts between the t-coordinates of the
updates and the user's tensors (Elasticity.to_voigt / from_voigt), passes the strain eps
(``uses_eps``) and checks what the law returns; ``as_viscoplastic_law`` takes a class, a
factory or an object.
"""
from __future__ import annotations

import numpy as np

from vpcontact.io.errors import CaseError
from vpcontact.model.laws import ViscoplasticLaw, elastic_strain
from vpcontact.model.material import FLAT, FROM, Elasticity


class LawEvaluationError(RuntimeError):
    """A user's law returned non-finite values during a step (the step fails)."""


def _symmetric_selector(dim: int) -> np.ndarray:
    """S (d*d, mt): the derivative by t_j sums the derivatives by the entries (a, b) of
    sigma that hold t_j (both (a, b) and (b, a) for a shear)."""
    S = np.zeros((dim * dim, len(FLAT[dim])))
    S[np.arange(dim * dim), FROM[dim]] = 1.0
    return S


class UserLaw(ViscoplasticLaw):
    """A user's law object as a ViscoplasticLaw (see app/model/laws.py for the protocol).

    Args:
        law: the user's object (``m``, ``G``, ``Gk``; optional ``dG`` and ``dGk``,
            ``rate_bound``, ``name``).
        elasticity: the case's elasticity E (its t-coordinates).
        where: what to name in messages (the module file and class).
        params: the constants the law was built with (summary.json, ``check``).

    Raises:
        CaseError: m is not an integer >= 1, G or Gk is missing, only one of dG, dGk is
            given, or G, Gk (dG, dGk) at the zero state have the wrong shapes or are not
            finite.
    """

    uses_eps = True

    def __init__(self, law, elasticity: Elasticity, where: str, params: dict | None = None):
        super().__init__(elasticity)
        self.user, self.where, self.params = law, where, dict(params or {})
        m = getattr(law, "m", None)
        if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 1:
            raise CaseError(f"{where}: m = {m!r}: the number of internal variables kappa "
                            "must be an integer >= 1")
        self.m = int(m)
        for method in ("G", "Gk"):
            if not callable(getattr(law, method, None)):
                raise CaseError(f"{where}: no method {method}(sigma, eps, kappa)")
        given = [callable(getattr(law, method, None)) for method in ("dG", "dGk")]
        if any(given) and not all(given):
            raise CaseError(f"{where}: give both dG and dGk (the implicit scheme's tangent) "
                            "or neither (finite differences)")
        self.derivatives = all(given)
        self.name = str(getattr(law, "name", type(law).__name__))
        self._S = _symmetric_selector(elasticity.dim)
        self._probe()

    def _probe(self) -> None:
        """G, Gk (and dG, dGk) at the zero state of m + 5 cells: shapes and finiteness,
        before the first step."""
        n, mt = self.m + 5, self.elasticity.m
        zeros = np.zeros((n, mt))
        if len(getattr(self.elasticity, "selected", (0,))) == 0:
            return                   # an E per cell on a rank without cells: the others probe
        with self.elasticity.rows(np.zeros(n, dtype=np.intp)):   # an E per cell: row 0's
            self._probe_at(zeros, n)

    def _probe_at(self, zeros, n) -> None:
        """The probe at the zero state of n cells (see _probe)."""
        mt = self.elasticity.m
        try:
            self.rates(zeros, np.zeros((n, self.m)), zeros)
        except LawEvaluationError as exc:
            raise CaseError(f"{exc} at sigma = 0, eps = 0, kappa = 0") from None
        if self.derivatives:
            J = self.implicit_jacobian(np.zeros((n, mt + self.m)), zeros,
                                       np.zeros((n, self.m)), 1.0, zeros)
            if not np.isfinite(J).all():
                raise CaseError(f"{self.where}: dG or dGk returned non-finite values "
                                "(NaN/Inf) at sigma = 0, eps = 0, kappa = 0")

    def _check_shape(self, what: str, value, shape: tuple) -> np.ndarray:
        """The user's output as a float array of the expected shape, else CaseError."""
        out = np.asarray(value, dtype=float)
        if out.shape != shape:
            raise CaseError(f"{self.where}: {what} returned an array of shape {out.shape}, "
                            f"expected {shape}")
        return out

    def _tensors(self, t, eps, kappa):
        """The user's arguments: sigma, eps (n, d, d) and a copy of kappa (n, m); without a
        strain (a caller of ``rates(t, kappa)`` alone) eps = E^-1 sigma, no history."""
        el = self.elasticity
        if eps is None:
            eps = elastic_strain(el, t)
        return el.from_voigt(t), el.from_voigt(eps), np.array(kappa, dtype=float)

    def rates(self, t, kappa, eps=None, finite: bool = True):
        """G and Gk of the user's law in t-coordinates.

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, m) internal variables.
            eps: rows (n, mt) of the strain eps in t-coordinates (None: E^-1 sigma).
            finite: refuse non-finite values (the explicit update; the implicit update's
                line search may probe states where a law overflows).

        Returns:
            (G rows (n, mt), Gk (n, m)).

        Raises:
            CaseError: the law returned arrays of the wrong shapes.
            LawEvaluationError: non-finite values (NaN/Inf), with ``finite``.
        """
        sigma, e, kap = self._tensors(t, eps, kappa)
        n, d = sigma.shape[0], self.elasticity.dim
        G = self._check_shape("G", self.user.G(sigma, e, kap), (n, d, d))
        Gk = self._check_shape("Gk", self.user.Gk(sigma, e, kap), (n, self.m))
        if finite:
            bad = ~(np.isfinite(G).all(axis=(1, 2)) & np.isfinite(Gk).all(axis=1))
            if bad.any():
                raise LawEvaluationError(f"{self.where}: G or Gk returned non-finite values "
                                         f"(NaN/Inf) at {int(bad.sum())} cell(s)")
        return self.elasticity.to_voigt(G), Gk

    def elastic(self, t, kappa, eps=None):
        """The cells where G = 0 and Gk = 0 (the implicit update keeps the trial state).

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, m) internal variables.
            eps: rows (n, mt) of the strain.

        Returns:
            (n,) booleans.
        """
        G, Gk = self.rates(t, kappa, eps, finite=False)
        return ~(np.any(G != 0.0, axis=1) | np.any(Gk != 0.0, axis=1))

    def implicit_residual(self, z, s_tr, kappa_prev, k, eps=None):
        """R_s = sigma - s_tr - k G(sigma, eps, kappa), R_k = kappa - kappa_{n-1} -
        k Gk(sigma, eps, kappa), eps the trial strain (app/model/implicit.py).

        Args:
            z: (n, mt + m) unknowns: sigma in t-coordinates, then kappa.
            s_tr: (n, mt) trial stresses.
            kappa_prev: (n, m) kappa_{n-1}.
            k: the time step k_n.
            eps: (n, mt) the trial strain eps(u_n) in t-coordinates.

        Returns:
            The (n, mt + m) residuals.
        """
        mt = self.elasticity.m
        G, Gk = self.rates(z[:, :mt], z[:, mt:], eps, finite=False)
        r = np.empty_like(z)
        r[:, :mt] = z[:, :mt] - s_tr - k * G
        r[:, mt:] = z[:, mt:] - kappa_prev - k * Gk
        return r

    def implicit_jacobian(self, z, s_tr, kappa_prev, k, eps=None):
        """J = I - k [[dG/dt, dG/dkappa], [dGk/dt, dGk/dkappa]] from the user's dG and dGk
        (their tensor derivatives by sigma summed over the entries (a, b), (b, a) that hold
        one t-coordinate); None without them.

        Args:
            z: (n, mt + m) unknowns: sigma in t-coordinates, then kappa.
            s_tr: (n, mt) trial stresses (not used).
            kappa_prev: (n, m) kappa_{n-1} (not used).
            k: the time step k_n.
            eps: (n, mt) the trial strain in t-coordinates.

        Returns:
            (n, mt + m, mt + m), or None.
        """
        if not self.derivatives:
            return None
        mt, m, d = self.elasticity.m, self.m, self.elasticity.dim
        sigma, e, kap = self._tensors(z[:, :mt], eps, z[:, mt:])
        n = sigma.shape[0]
        dGs, dGk_ = self.user.dG(sigma, e, kap)
        dKs, dKk = self.user.dGk(sigma, e, kap)
        dGs = self._check_shape("dG[0]", dGs, (n, d, d, d, d)).reshape(n, d * d, d * d)
        dGk_ = self._check_shape("dG[1]", dGk_, (n, d, d, m)).reshape(n, d * d, m)
        dKs = self._check_shape("dGk[0]", dKs, (n, m, d, d)).reshape(n, m, d * d)
        dKk = self._check_shape("dGk[1]", dKk, (n, m, m))
        rows = FLAT[d]
        J = np.empty((n, mt + m, mt + m))
        J[:, :mt, :mt] = dGs[:, rows, :] @ self._S
        J[:, :mt, mt:] = dGk_[:, rows, :]
        J[:, mt:, :mt] = dKs @ self._S
        J[:, mt:, mt:] = dKk
        return np.eye(mt + m) - k * J

    def relaxation_rate(self) -> float | None:
        """The user's ``rate_bound()`` (app/post/diagnostics.py: k r_max <= 2).

        Returns:
            r_max [1/s], or None where the law gives none.

        Raises:
            CaseError: the bound is negative or not finite.
        """
        bound = getattr(self.user, "rate_bound", None)
        value = bound() if callable(bound) else None
        if value is None:
            return None
        if not (np.isfinite(value) and value >= 0):
            raise CaseError(f"{self.where}: rate_bound() = {value!r}: a rate [1/s] >= 0 "
                            "(or None: not known)")
        return float(value)

    def constants(self) -> dict:
        """Returns: the numeric constants the law was built with (``params``), no units."""
        return {key: (value, "") for key, value in self.params.items()
                if isinstance(value, (int, float)) and not isinstance(value, bool)}


def as_viscoplastic_law(law, elasticity: Elasticity, where: str | None = None,
                        params: dict | None = None) -> ViscoplasticLaw:
    """A law for the run from what a user gives: a ViscoplasticLaw is used as it is; a
    class (or any callable that is not a law object) is called with the elasticity; an
    object in the user protocol is wrapped in a UserLaw.

    Args:
        law: a ViscoplasticLaw, a user's law object, or a class / callable
            ``elasticity -> law``.
        elasticity: the case's elasticity E.
        where: what to name in messages (default: the object's module and class).
        params: the constants the law was built with.

    Returns:
        The ViscoplasticLaw.

    Raises:
        CaseError: the object does not follow the protocol (see UserLaw).
    """
    if isinstance(law, type) or (callable(law) and not hasattr(law, "G")):
        law = law(elasticity)
    if isinstance(law, ViscoplasticLaw):
        return law
    kind = type(law)
    return UserLaw(law, elasticity, where or f"law {kind.__module__}.{kind.__qualname__}",
                   params)
