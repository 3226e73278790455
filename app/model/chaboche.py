"""Chaboche's unified viscoplastic law with nonlinear kinematic and isotropic hardening,
kappa = (X, R, p) in R^8 (m = 8; in 2D plane strain (X, R, p, eps_vp33), m = 9):
    f = ||sigma - X||_VM - R - k,        p' = <f/K>^n,
    eps_vp' = p' N(sigma - X),           N(tau) = d ||tau||_VM / d tau = (3/2) dev(tau)/||tau||_VM,
    X' = (2/3) C eps_vp' - gamma X p',   R' = b (Q - R) p',
    G(sigma, kappa) = -E eps_vp',        Gk(sigma, kappa) = (X', R', p'),
the pair (G, Gk) of (1.2)-(1.3), with <.> the positive part; k the initial yield stress, K
the drag stress, C and gamma the kinematic modulus and dynamic recovery, Q and b the
saturated isotropic hardening and its rate.

The back stress X is a symmetric deviatoric 3 x 3 tensor in 2D too: its six components are
stored in the 3D t-order (X11, X22, X33, X23, X13, X12) (tensor components), then R, then p.
X, R, p start at 0.  ||sigma - X||_VM is the 3D von Mises norm of the 3D stress minus X;
in 2D (sigma_13 = sigma_23 = 0):
- plane stress: sigma_33 = 0 (for X = 0 the norm is the paper's 2D norm); X_33 = -(X_11 +
  X_22) follows from the flow; the in-plane part of eps_vp' drives the stress.
- plane strain: sigma_33 = nu (sigma_11 + sigma_22) - E eps_vp33, with eps_vp33 the ninth
  internal variable (eps_vp33' = the 33 component of eps_vp'), and G = -(C3 eps_vp')_in-plane
  (app/model/planestrain.py: an isotropic E).

SPEC, at the end of the module, declares the law (app/model/lawspec.py): its keys k, K, n,
C, gamma, Q, b, its rules, kappa's growth bound and its factory.
"""
from __future__ import annotations

import numpy as np

from vpcontact.io.errors import CaseError
from vpcontact.model.laws import ViscoplasticLaw
from vpcontact.model.lawspec import (
    EXPONENT,
    NONNEGATIVE,
    NUMBER,
    POSITIVE,
    LawKey,
    LawSpec,
)
from vpcontact.model.material import Elasticity
from vpcontact.model.norton import M3 as _M3
from vpcontact.model.norton import W3 as _W3
from vpcontact.model.norton import flow_direction, flow_modulus, overflowed_rate
from vpcontact.model.planestrain import PlaneStrain

# the 3D t-coordinates of the body's stress coordinates (2D: s11, s22, s12)
_IN_3D = {2: [0, 1, 5], 3: [0, 1, 2, 3, 4, 5]}


class Chaboche(ViscoplasticLaw):
    """Chaboche's law (see the module docstring), m = 8, kappa = (X (6), R, p) (2D plane
    strain: m = 9, then eps_vp33).  The explicit update is the protocol's numpy
    ExplicitUpdate, the implicit one its default residual with the finite-difference
    tangent; ``elastic`` is exactly f <= 0 (p' = 0 there).  No relaxation rate (it grows
    with the overstress): the stability indicator is the linearisation's at the data's
    stress scale (``rate_at_stress``).

    Args:
        elasticity: the elasticity E.
        k: the initial yield stress k >= 0 [Pa].
        K: the drag stress K > 0 [Pa].
        n: the exponent n >= 1.
        C: the kinematic hardening modulus C >= 0 [Pa].
        gamma: the dynamic recovery gamma >= 0.
        Q: the saturated isotropic hardening Q [Pa].
        b: the rate b >= 0 of the isotropic hardening.
        plane: in 2D, "stress" (sigma_33 = 0) or "strain" (eps_33 = 0: sigma_33 carried,
            an isotropic E only); not used in 3D.

    Attributes:
        fields: the internal variables as output fields, (name, components) in kappa's
            order: X a 3 x 3 tensor (6 components), R, p (plane strain: then eps_vp33).
        plane_strain: the PlaneStrain of sigma_33, or None (3D, plane stress).
    """

    m = 8
    name = "chaboche"
    fields = (("X", 6), ("R", 1), ("p", 1))

    def __init__(self, elasticity: Elasticity, k: float, K: float, n: float, C: float,
                 gamma: float, Q: float, b: float, plane: str = "stress"):
        super().__init__(elasticity)
        self.k, self.K, self.n, self.C, self.gamma, self.Q, self.b = k, K, n, C, gamma, Q, b
        self._in3d = _IN_3D[elasticity.dim]
        self.plane_strain = PlaneStrain(elasticity) \
            if elasticity.dim == 2 and plane == "strain" else None
        if self.plane_strain is not None:
            self.m, self.fields = 9, self.fields + (("eps_vp33", 1),)

    def constants(self):
        """Returns: k, K [Pa], n [-], C [Pa], gamma [-], Q [Pa], b [-] (the case's keys)."""
        return SPEC.constants_of(self)

    @property
    def hardens(self) -> bool:
        """Returns: whether the rates fall as the law hardens (X grows towards sigma, R
        towards Q: with Q >= 0 both shrink the overstress f), so that ``rate_at_stress``,
        taken at X = R = 0, bounds the rates of the hardened states."""
        return self.Q >= 0.0

    def rate_at_stress(self, S: float) -> float | None:
        """The relaxation rate of the explicit update (3.2)-(3.3) linearised at the initial
        internal state (X = 0, R = 0) and a stress of von Mises norm S.  With the
        overstress f = ||sigma - X||_VM - R - k, phi(f) = <f/K>^n and phi' its slope, the
        radial part of (sigma, X, R) under held strain is
            sigma' = -lambda_1 phi,  X' = (C - gamma X) phi,  R' = b (Q - R) phi,
        (lambda_1 = ``flow_modulus``, 3 mu for isotropic E): its Jacobian at X = R = 0 is
        J = phi' u v^T - diag(0, gamma phi, b phi), u = (-lambda_1, C, b Q), v = (1, -1, -1);
        with P = diag(1, -1, -1), |P J P| is entrywise at most the nonnegative
        phi' |u| (1, 1, 1)^T + max(gamma, b) phi I, so (Perron-Frobenius) its spectral
        radius is at most

            r(S) = phi'(S - k) (lambda_1 + C + b |Q|) + max(gamma, b) phi(S - k),

        the transverse (deviatoric) directions relaxing at phi / ||sigma - X||_VM <= phi'.
        The explicit update is stable for k r(S) <= 2.

        Args:
            S: the stress scale [Pa] (app/post/divergence.stress_scale).

        Returns:
            r(S) [1/s]; inf where it overflows (n = 200, K = 1e-90: no time step is stable
            at that stress); None where it vanishes (S <= k: no flow).
        """
        with np.errstate(over="ignore", invalid="ignore"):
            x = max(float(S) - self.k, 0.0) / np.float64(self.K)
            if x == 0.0:
                return None
            phi = x ** self.n
            slope = self.n / np.float64(self.K) * x ** (self.n - 1.0)
            r = float(slope * (flow_modulus(self.elasticity, self.plane_strain) + self.C
                               + self.b * abs(self.Q)) + max(self.gamma, self.b) * phi)
        return overflowed_rate(r)

    def _overstress(self, t, kappa):
        """sigma - X in 3D t-coordinates, its von Mises norm, (3/2) dev(sigma - X) and f."""
        if self.plane_strain is not None:
            s = self.plane_strain.stress(t, kappa[:, 8])
        else:
            s = np.zeros((t.shape[0], 6))
            s[:, self._in3d] = t
        seq, seq_N = flow_direction(s - kappa[:, :6], _M3, _W3)
        return seq, seq_N, seq - kappa[:, 6] - self.k

    def flow(self, t: np.ndarray, kappa: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """p' = <f/K>^n and eps_vp' = p' N(sigma - X).

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, m) internal variables (X, R, p(, eps_vp33)).

        Returns:
            (eps_vp' rows (n, 6) in 3D t-coordinates (tensor components), p' (n,)).
        """
        seq, seq_N, f = self._overstress(t, kappa)
        with np.errstate(over="ignore"):
            p_rate = (np.maximum(f, 0.0) / self.K) ** self.n
        scale = np.divide(p_rate, seq, out=np.zeros_like(seq), where=seq > 0.0)
        return scale[:, None] * seq_N, p_rate

    def rates(self, t, kappa):
        """G = -E eps_vp' (its in-plane part in 2D; plane strain: -(C3 eps_vp')_in-plane),
        Gk = (X', R', p'(, eps_vp33')).

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, m) internal variables (X, R, p(, eps_vp33)).

        Returns:
            (G rows (n, mt), Gk (n, m)).
        """
        eps_vp, p_rate = self.flow(t, kappa)
        Gk = np.empty_like(kappa)
        Gk[:, :6] = (2.0 / 3.0 * self.C) * eps_vp - self.gamma * kappa[:, :6] * p_rate[:, None]
        Gk[:, 6] = self.b * (self.Q - kappa[:, 6]) * p_rate
        Gk[:, 7] = p_rate
        if self.plane_strain is not None:
            Gk[:, 8] = eps_vp[:, 2]
            return self.plane_strain.G(eps_vp), Gk
        return -self.elasticity.apply(eps_vp[:, self._in3d]), Gk

    def elastic(self, t, kappa):
        """No flow exactly where f <= 0 (the rates are exactly 0 there).

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, m) internal variables (X, R, p(, eps_vp33)).

        Returns:
            (n,) booleans.
        """
        return ~(self._overstress(t, kappa)[2] > 0.0)


def _check(vp: dict, source: str) -> None:
    """X, R, p start at 0 (kappa0 only 0), and the yield radius k + R tends to k + Q >= 0.

    Args:
        vp: the material.viscoplastic section (default-filled, its keys present).
        source: the case file, for messages.

    Raises:
        CaseError: kappa0 != 0, or k + Q < 0.
    """
    if vp["kappa0"] != 0:
        raise CaseError(f"{source}: material.viscoplastic.kappa0: law chaboche starts from "
                        "X = 0, R = 0, p = 0 (allowed: 0 or absent)")
    if vp["k"] + vp["Q"] < 0:
        raise CaseError(f"{source}: material.viscoplastic.Q: k + Q must be >= 0 (the yield "
                        f"radius k + R tends to k + Q), got {vp['k'] + vp['Q']:g}")


def _growth(vp, T: float, S: float) -> float:
    """||X||_VM stays below the bound S (X moves toward sigma - X), R between 0 and Q, and
    p' = <f/K>^n <= (2 S / K)^n: the largest of S, |Q| and T (2 S / K)^n.

    Args:
        vp: K, n, Q as attributes.
        T: the final time.
        S: the bound of ||sigma||_VM.

    Returns:
        The growth bound.

    Raises:
        OverflowError: (2 S / K)^n overflows.
    """
    return max(S, abs(vp.Q), T * (2.0 * S / vp.K) ** vp.n)


def _stress_scaling(vp: dict, factor: float) -> dict[str, float]:
    """sigma -> factor sigma with E: k, K, C, Q by ``factor`` (f / K unchanged; gamma, b, n
    are pure numbers).

    Args:
        vp: the material.viscoplastic section as given.
        factor: the scaling factor.

    Returns:
        {key: factor} of those keys present in the section.
    """
    return {k: factor for k in ("k", "K", "C", "Q") if k in vp}


# the declaration of the law (app/model/lawspec.py), collected by app/model/lawregistry.py
SPEC = LawSpec(
    name="chaboche", title="Chaboche",
    summary="unified viscoplasticity with nonlinear kinematic and isotropic hardening: f = "
            "||sigma - X||_VM - R - k, p' = <f/K>^n, eps_vp' = p' N(sigma - X), X' = 2/3 C "
            "eps_vp' - gamma X p', R' = b (Q - R) p', kappa = (X, R, p), m = 8, starting "
            "from 0, G = -E eps_vp' (plane strain: kappa = (X, R, p, eps_vp33), m = 9)",
    kappa0="only 0, its X, R, p start at 0", kappa_unit="-",
    keys={"k": LawKey(NONNEGATIVE, "the initial yield stress, in Pa", "Pa",
                      doc="the initial yield stress k of f = ||sigma - X||_VM - R - k [Pa]"),
          "K": LawKey(POSITIVE, "the drag stress, in Pa", "Pa",
                      doc="the drag stress K of p' = <f/K>^n [Pa]"),
          "n": LawKey(EXPONENT, "the exponent n >= 1 of <f/K>^n", "-"),
          "C": LawKey(NONNEGATIVE, "the kinematic modulus, in Pa", "Pa",
                      doc="the kinematic hardening modulus C of X' = 2/3 C eps_vp' - gamma X "
                          "p' [Pa]"),
          "gamma": LawKey(NONNEGATIVE, "the dynamic recovery", "-",
                          doc="the dynamic recovery gamma of X' = 2/3 C eps_vp' - gamma X p' "
                              "(dimensionless; 0: linear kinematic hardening)"),
          "Q": LawKey(NUMBER, "the saturated isotropic hardening, in Pa", "Pa",
                      doc="the saturated isotropic hardening Q of R' = b (Q - R) p' [Pa] "
                          "(negative: softening, with k + Q >= 0)"),
          "b": LawKey(NONNEGATIVE, "the isotropic rate", "-",
                      doc="the rate b of the isotropic hardening R' = b (Q - R) p' "
                          "(dimensionless)")},
    build=lambda vp, elasticity, plane: Chaboche(elasticity, vp.k, vp.K, vp.n, vp.C,
                                                 vp.gamma, vp.Q, vp.b, plane),
    kappa_growth=_growth, shown=("k", "K", "n", "C", "gamma", "Q", "b"), check=_check,
    carries_sigma33=True, stress_scaling=_stress_scaling)
