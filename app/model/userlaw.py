"""A viscoplastic law written by a user, in the user protocol of app/model/laws.py (``m``,
``G(sigma, eps, kappa)``, ``Gk(sigma, eps, kappa)`` in tensors, optionally ``dG``, ``dGk``,
``rate_bound``), as a ViscoplasticLaw: ``UserLaw`` converts between the t-coordinates of the
updates and the user's tensors (Elasticity.to_voigt / from_voigt), passes the strain eps
(``uses_eps``) and checks what the law returns; ``as_viscoplastic_law`` takes a class, a
factory or an object.  A contact law written by a user for the case file (``law: python``
of contact.normal_compliance or contact.friction), duck-typed as a ScalarLaw (``energy``,
``derivative``, ``second_derivative`` of one scalar, written with the primitives of
``backend(x)``), is checked and described by ``UserContactLaw``.
"""
from __future__ import annotations

import numpy as np

from vpcontact.io.errors import CaseError
from vpcontact.model.laws import ScalarLaw, ViscoplasticLaw, elastic_strain
from vpcontact.model.material import FLAT, FROM, Elasticity
from vpcontact.model.primitives import positive_slip
from vpcontact.model.usercode import USER_ERRORS, raised


class LawEvaluationError(RuntimeError):
    """A user's law raised (``sys.exit`` too) or returned non-finite values during a step
    (the step fails)."""


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
            given, or G, Gk (dG, dGk) at the zero state raise, have the wrong shapes or are
            not finite (later, in a step, these fail the step: LawEvaluationError).
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
            J = self.implicit_jacobian(np.zeros((n, mt + self.m)), zeros,
                                       np.zeros((n, self.m)), 1.0, zeros)
        except LawEvaluationError as exc:
            raise CaseError(f"{exc} at sigma = 0, eps = 0, kappa = 0") from None
        if J is not None:
            if not np.isfinite(J).all():
                raise CaseError(f"{self.where}: dG or dGk returned non-finite values "
                                "(NaN/Inf) at sigma = 0, eps = 0, kappa = 0")

    def _call(self, method: str, *args):
        """The user's ``method(sigma, eps, kappa)``; what it raises (SystemExit too) as a
        LawEvaluationError naming the law and the method."""
        try:
            return getattr(self.user, method)(*args)
        except USER_ERRORS as exc:
            raise LawEvaluationError(f"{self.where}: {method}(sigma, eps, kappa) "
                                     f"{raised(exc)}") from exc

    def _check_shape(self, what: str, value, shape: tuple) -> np.ndarray:
        """The user's output as a float array of the expected shape, else LawEvaluationError
        (the probe's refusal before the first step, a failed step during the run)."""
        try:
            out = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise LawEvaluationError(f"{self.where}: {what} returned a "
                                     f"{type(value).__name__}, not an array of numbers of "
                                     f"shape {shape}") from None
        if out.shape != shape:
            raise LawEvaluationError(f"{self.where}: {what} returned an array of shape "
                                     f"{out.shape}, expected {shape}")
        return out

    def _pair(self, what: str, value) -> tuple:
        """dG's or dGk's pair (by sigma, by kappa), else LawEvaluationError."""
        if not (isinstance(value, (tuple, list)) and len(value) == 2):
            raise LawEvaluationError(f"{self.where}: {what} returned a {type(value).__name__}, "
                                     "expected a pair (by sigma, by kappa)")
        return tuple(value)

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
            LawEvaluationError: G or Gk raised, returned arrays of the wrong shapes, or
                returned non-finite values (NaN/Inf) with ``finite``.
        """
        sigma, e, kap = self._tensors(t, eps, kappa)
        n, d = sigma.shape[0], self.elasticity.dim
        G = self._check_shape("G", self._call("G", sigma, e, kap), (n, d, d))
        Gk = self._check_shape("Gk", self._call("Gk", sigma, e, kap), (n, self.m))
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

        Raises:
            LawEvaluationError: dG or dGk raised or returned the wrong shapes.
        """
        if not self.derivatives:
            return None
        mt, m, d = self.elasticity.m, self.m, self.elasticity.dim
        sigma, e, kap = self._tensors(z[:, :mt], eps, z[:, mt:])
        n = sigma.shape[0]
        dGs, dGk_ = self._pair("dG", self._call("dG", sigma, e, kap))
        dKs, dKk = self._pair("dGk", self._call("dGk", sigma, e, kap))
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
            CaseError: rate_bound() raised, or the bound is negative or not finite.
        """
        bound = getattr(self.user, "rate_bound", None)
        try:
            value = bound() if callable(bound) else None
        except USER_ERRORS as exc:
            raise CaseError(f"{self.where}: rate_bound() {raised(exc)}") from None
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


# where a contact law written by the user is probed before the first step: the normal
# displacement r (either sign) and the regularised slip rho > 0 [m]
CONTACT_PROBES = {"normal": (-1e-3, 0.0, 1e-3), "friction": (1e-4, 1e-3, 1e-2)}
SCALAR_METHODS = ("energy", "derivative", "second_derivative")


class UserContactLaw(ScalarLaw):
    """A contact law written by the user (contact.normal_compliance or contact.friction with
    ``law: python``) as the run's ScalarLaw: the user's object is duck-typed (a ScalarLaw of
    app/model/laws.py, or any object with ``energy``, ``derivative``, ``second_derivative``
    written with ``backend(x)``: numpy at the nodes, UFL in the forms), its three methods
    are called as they are (the same operations as the user's object), and it is checked
    before the first step: the methods exist, numpy values at a few points have the
    argument's shape and are finite, on a UFL symbol they give UFL expressions (the forms),
    a friction law's ``m_j`` (of (2.6)), if stated, is a number >= 0.

    Args:
        law: the user's object.
        where: what to name in messages (the module file and class).
        part: "normal" (P(r) of the normal displacement r) or "friction" (psi(rho) of the
            regularised slip rho).
        params: the constants the law was built with (``check``, summary.json).

    Raises:
        CaseError: the object is not a contact law (see above).
    """

    def __init__(self, law, where: str, part: str, params: dict | None = None):
        missing = [f for f in SCALAR_METHODS if not callable(getattr(law, f, None))]
        if missing:
            raise CaseError(f"{where}: not a contact law: no method {missing[0]}(x) (a "
                            "ScalarLaw of vpcontact.model.laws: energy, derivative, "
                            "second_derivative)")
        self.user, self.where, self.params = law, where, dict(params or {})
        self.part = part
        self.name = str(getattr(law, "name", type(law).__name__))
        self.m_j = None
        if part == "friction" and getattr(law, "m_j", None) is not None:
            m_j = law.m_j
            if isinstance(m_j, bool) or not isinstance(m_j, (int, float, np.number)) \
                    or not (np.isfinite(m_j) and m_j >= 0):
                raise CaseError(f"{where}: m_j = {m_j!r}: the largest decreasing slope of "
                                "psi' (2.6) must be a number >= 0")
            self.m_j = float(m_j)
        self._probe(np.array(CONTACT_PROBES[part]))
        self._probe_ufl()

    def _probe(self, x: np.ndarray) -> None:
        """The three methods at the points x (numpy): the shape of x, finite values."""
        for method in SCALAR_METHODS:
            try:
                out = np.asarray(getattr(self.user, method)(x.copy()), dtype=float)
            except USER_ERRORS as exc:      # the user's code: report what it raised
                raise CaseError(f"{self.where}: {method}(x) at x = {x.tolist()} (a numpy "
                                f"array) {raised(exc)}") from None
            if out.shape not in (x.shape, ()):
                raise CaseError(f"{self.where}: {method}(x) returned an array of shape "
                                f"{out.shape}, expected {x.shape} (the shape of x)")
            if not np.isfinite(out).all():
                raise CaseError(f"{self.where}: {method}(x) returned non-finite values "
                                f"(NaN/Inf) at x = {x.tolist()}")

    def _probe_ufl(self) -> None:
        """The three methods on a UFL symbol (SNES VI's forms): a UFL expression or a
        number, else (numpy's functions on a UFL expression) CaseError naming the rule."""
        import logging

        import ufl
        x = ufl.Constant(ufl.Mesh(ufl.VectorElement("Lagrange", ufl.triangle, 1)))
        log = logging.getLogger("UFL")              # UFL logs its error before raising it
        level = log.level
        log.setLevel(logging.CRITICAL)
        try:
            for method in SCALAR_METHODS:
                try:
                    out = getattr(self.user, method)(x)
                except USER_ERRORS as exc:  # the user's code
                    out = exc
                if not isinstance(out, (ufl.core.expr.Expr, int, float)):
                    what = raised(out).rstrip(".") if isinstance(out, BaseException) \
                        else f"returned a {type(out).__name__}"
                    raise CaseError(f"{self.where}: {method}(x) on a UFL expression (SNES VI's "
                                    f"forms) {what}; write the law with the primitives of "
                                    "vpcontact.model.primitives.backend(x), not numpy's "
                                    "functions")
        finally:
            log.setLevel(level)

    def constants(self) -> dict:
        """The law's constants for ``check`` and summary.json.

        Returns:
            The user's ``constants()`` where it gives some, else the numeric ``params`` the
            law was built with (no units).

        Raises:
            CaseError: the user's ``constants()`` raised.
        """
        try:
            own = self.user.constants() if callable(getattr(self.user, "constants", None)) \
                else {}
        except USER_ERRORS as exc:
            raise CaseError(f"{self.where}: constants() {raised(exc)}") from None
        return dict(own) or {key: (value, "") for key, value in self.params.items()}

    def _call(self, method: str, r):
        """The user's ``method(r)``, a friction law's at the slip ``positive_slip(r)`` (= r;
        its UFL form compiles whatever psi is); what it raises during the run (SystemExit
        too) as a LawEvaluationError naming the law and the method (the step fails)."""
        try:
            return getattr(self.user, method)(positive_slip(r) if self.part == "friction"
                                              else r)
        except USER_ERRORS as exc:
            raise LawEvaluationError(f"{self.where}: {method}(x) {raised(exc)}") from exc

    def energy(self, r):
        """The user's energy.

        Args:
            r: the variable at the nodes (numpy) or a UFL expression.

        Returns:
            The energy, elementwise.
        """
        return self._call("energy", r)

    def derivative(self, r):
        """The user's derivative.

        Args:
            r: as for ``energy``.

        Returns:
            The derivative, elementwise.
        """
        return self._call("derivative", r)

    def second_derivative(self, r):
        """The user's second derivative.

        Args:
            r: as for ``energy``.

        Returns:
            The second derivative, elementwise.
        """
        return self._call("second_derivative", r)
