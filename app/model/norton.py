"""Norton's creep law (no yield surface), kappa = p the accumulated creep strain (m = 1;
in plane strain kappa = (p, eps_vp33), m = 2): with sigma_eq = ||sigma||_VM and the flow
direction N = d sigma_eq / d sigma (= (3/2) dev(sigma) / sigma_eq in 3D),
    eps_vp' = A sigma_eq^n N,   G(sigma, kappa) = -E eps_vp',   p' = A sigma_eq^n,
the pair (G, Gk) of (1.2)-(1.3).

The flow direction is the gradient of the body's von Mises form ||tau||_VM^2 = t^T M t
(app/model/material.py) with respect to the tensor: in t-coordinates the shears count twice
in tau : sigma (Elasticity.weights w), so N_t = M t / (w sigma_eq).  In 3D this is
(3/2) dev(sigma) / sigma_eq.  In 2D:
- plane stress (sigma_33 = 0, the stress state of a thin plate): the norm is the paper's
  t11^2 + t22^2 - t11 t22 + 3 t12^2, the 3D von Mises norm of the in-plane stress, N its
  gradient; the in-plane part of eps_vp' drives the stress (the out-of-plane creep strain
  -(N11 + N22) only thins the plate).
- plane strain (eps_33 = 0, a long body): sigma_33 = nu (sigma_11 + sigma_22) - E eps_vp33
  is not 0 (app/model/planestrain.py); sigma_eq and N are the 3D ones of (sigma_11,
  sigma_22, sigma_33, sigma_12), the creep is isochoric, kappa carries eps_vp33
  (eps_vp33' = A sigma_eq^n N_33) and G = -(C3 eps_vp')_in-plane, the 3D E on the 3D creep
  rate (-2 mu eps_vp' in the plane for isotropic E, the creep being isochoric).

SPEC, at the end of the module, declares the law (app/model/lawspec.py): its keys A and n,
its rule in plane strain, kappa's growth bound and its factory.
"""
from __future__ import annotations

import numpy as np

from vpcontact.io.errors import CaseError
from vpcontact.model.laws import ViscoplasticLaw
from vpcontact.model.lawspec import EXPONENT, POSITIVE, LawKey, LawSpec
from vpcontact.model.material import Elasticity, _von_mises_matrix
from vpcontact.model.planestrain import PlaneStrain

M3 = _von_mises_matrix(3)                       # the 3D von Mises form and weights
W3 = np.array([1.0, 1.0, 1.0, 2.0, 2.0, 2.0])


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


def overflowed_rate(r: float) -> float | None:
    """A law's rate r(S) > 0 computed in floating point as it is, inf where the computation
    overflowed (inf, or NaN from inf - inf or 0 inf: the true rate is positive and beyond
    the largest float), None where it is 0 (the law does not flow at S).

    Args:
        r: the computed rate (>= 0, or not finite).

    Returns:
        r, inf or None.
    """
    if not np.isfinite(r):
        return float("inf")
    return r if r > 0.0 else None


def flow_modulus(elasticity: Elasticity, plane_strain: PlaneStrain | None) -> float:
    """lambda_1 = the largest eigenvalue of sigma -> E N' sigma, N' sigma = sigma_eq N
    (= (3/2) dev(sigma) in 3D): the stress relaxes under held strain at the rate lambda_1
    times the flow's scalar factor (A sigma_eq^(n-1) for Norton's law).  3 mu for an
    isotropic E in 3D and in plane stress (a uniaxial or shear stress in the plane is the
    3D one); in plane strain 3 mu with the 3D shear modulus (the state (sigma, eps_vp33)
    under held strain is the 3D one); the largest over the cells for an E per cell.

    Args:
        elasticity: the elasticity E (its Cmat, von Mises form M and weights).
        plane_strain: the PlaneStrain of sigma_33, or None (3D, plane stress).

    Returns:
        lambda_1 [Pa].
    """
    if plane_strain is not None:
        return 1.5 * float(np.max(plane_strain.lame()[1]))
    linear = elasticity.Cmat @ (elasticity.M / elasticity.weights[:, None])
    return float(np.max(np.linalg.eigvals(linear).real))


class Norton(ViscoplasticLaw):
    """Norton's creep law (see the module docstring), m = 1, kappa = p (plane strain: m = 2,
    kappa = (p, eps_vp33)): G = -E eps_vp' with eps_vp' = A sigma_eq^n N, p' = A sigma_eq^n.
    The explicit update is the protocol's numpy ExplicitUpdate; the law flows wherever
    sigma_eq != 0, so ``elastic`` (the implicit update's cells kept at the trial state) is
    exactly sigma_eq = 0.  The relaxation rate n A sigma_eq^(n-1) E grows with the stress: a
    rate (and the stability indicator) only for n = 1.

    Args:
        elasticity: the elasticity E.
        A: the Norton coefficient A > 0 [Pa^-n s^-1].
        n: the Norton exponent n >= 1.
        plane: in 2D, "stress" (sigma_33 = 0) or "strain" (eps_33 = 0: sigma_33 carried,
            an isotropic E only; app/model/planestrain.py); not used in 3D.

    Attributes:
        fields: kappa as output fields, (name, components): p (and eps_vp33).
        plane_strain: the PlaneStrain of sigma_33, or None (3D, plane stress).
    """

    m = 1
    name = "norton"
    fields = (("p", 1),)         # kappa written to solution.xdmf as the field p

    def __init__(self, elasticity: Elasticity, A: float, n: float, plane: str = "stress"):
        super().__init__(elasticity)
        self.A, self.n = A, n
        self._M, self._w = elasticity.M, elasticity.weights
        self.plane_strain = PlaneStrain(elasticity) \
            if elasticity.dim == 2 and plane == "strain" else None
        if self.plane_strain is not None:
            self.m, self.fields = 2, (("p", 1), ("eps_vp33", 1))

    def constants(self):
        """Returns: A [Pa^-n s^-1], n [-] (as the case file's keys)."""
        return SPEC.constants_of(self)

    def _linear_part(self) -> np.ndarray:
        """The matrix of sigma -> E N' sigma in t-coordinates, N' sigma = sigma_eq N
        (= (3/2) dev(sigma) in 3D): G = -A E N' sigma for n = 1 (sigma_33 = 0)."""
        return self.elasticity.Cmat @ (self._M / self._w[:, None])

    def relaxation_rate(self) -> float | None:
        """For n = 1 the law is linear, sigma' = -A E N' sigma: E N' = W^-1 A_E W^-1 M (A_E
        the energy form, W the weights) has real eigenvalues >= 0, and the largest, times A,
        is the rate (3 mu A in 3D, on the deviators).  In plane strain the state (sigma,
        eps_vp33) under held strain is the 3D one under held strain: 3 mu A, mu the 3D
        shear modulus (the largest over the cells).  For n > 1 the rate n A sigma_eq^(n-1)
        grows with the stress: None.

        Returns:
            r_max [1/s] for n = 1, else None.
        """
        if self.n != 1:
            return None
        return self.A * flow_modulus(self.elasticity, self.plane_strain)

    def rate_at_stress(self, S: float) -> float | None:
        """The relaxation rate of the explicit update (3.2) linearised at stresses of von
        Mises norm up to S: G = -A sigma_eq^(n-1) E N' sigma has the Jacobian
        -A sigma_eq^(n-1) E (N' + (n - 1) (N' sigma)(N' sigma)^T / sigma_eq^2), whose
        second term is at most (n - 1) N' (Cauchy-Schwarz in the von Mises form), so its
        spectral radius is at most

            r(S) = n A S^(n-1) lambda_1,   lambda_1 = ``flow_modulus`` (3 mu, isotropic E),

        attained for a radial perturbation of a deviatoric stress under held strain.  The
        explicit update is stable for k r(S) <= 2 (k E n A S^(n-1) <= 2 for a uniaxial bar,
        whose stress relaxes with E instead of 3 mu).  n = 1: the relaxation rate.

        Args:
            S: the stress scale [Pa] (app/post/divergence.stress_scale).

        Returns:
            r(S) [1/s]; inf where it overflows (A = 1e-3, n = 300 at S = 9: no time step
            is stable at that stress); None where it vanishes (S = 0, n > 1).
        """
        with np.errstate(over="ignore"):
            r = float(self.n * self.A * np.float64(S) ** (self.n - 1.0)
                      * flow_modulus(self.elasticity, self.plane_strain))
        return overflowed_rate(r)

    def lipschitz_constant(self) -> float | None:
        """L_G of H(G) in the energy norm |tau|_E = (E tau : tau)^1/2: for n = 1, A times
        the operator norm of E N' in that norm (r_max where E and N' commute, as for
        isotropic E; in plane strain the map of sigma at fixed eps_vp33, whose N' takes
        sigma_33 = nu (sigma_11 + sigma_22) too); for n > 1 none (not Lipschitz).

        Returns:
            L_G [1/s] for n = 1, else None.
        """
        if self.n != 1:
            return None
        T = self._linear_part() if self.plane_strain is None else self._plane_strain_part()
        A_E = self.elasticity.A
        adjoint_T = np.linalg.solve(A_E, np.swapaxes(T, -1, -2) @ A_E)   # per cell too
        return self.A * float(np.sqrt(np.max(np.linalg.eigvals(adjoint_T @ T).real)))

    def _plane_strain_part(self) -> np.ndarray:
        """In plane strain, the matrix T of sigma -> (C3 N' sigma3)_in-plane (sigma3 with
        sigma_33 = nu (sigma_11 + sigma_22)): G = -A T sigma + (terms of eps_vp33), n = 1;
        per cell (n, 3, 3) for an E per cell."""
        lmbda = self.plane_strain.lame()[0]
        nu = np.asarray(self.plane_strain.young_poisson()[1])[..., None, None]
        S = np.zeros(nu.shape[:-2] + (6, 3))            # sigma -> sigma3, 3D t-coordinates
        S[..., [0, 1, 5], [0, 1, 2]] = 1.0
        S[..., 2, :2] = nu[..., 0, :]
        N = (M3 / W3[:, None]) @ S                      # sigma -> N' sigma3 = (3/2) dev
        C3 = np.zeros(nu.shape[:-2] + (3, 6))           # (C3 e)_in-plane in t-coordinates
        C3[..., :, [0, 1, 5]] = self.elasticity.Cmat
        C3[..., :2, 2] = np.asarray(lmbda)[..., None]
        return C3 @ N

    def creep_rate(self, t: np.ndarray, kappa: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
        """The creep strain rate eps_vp' = A sigma_eq^n N and p' = A sigma_eq^n.

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, m) internal variables (plane strain: eps_vp33 in column 1 gives
                sigma_33; else not used).

        Returns:
            (eps_vp' rows (n, mt) in t-coordinates (tensor components), in plane strain
            (n, 6) in 3D t-coordinates with eps_vp33'; p' (n,)).
        """
        if self.plane_strain is None:
            seq, seq_N = flow_direction(t, self._M, self._w)
        else:
            seq, seq_N = flow_direction(self.plane_strain.stress(t, kappa[:, 1]), M3, W3)
        with np.errstate(over="ignore"):
            f = self.A * seq ** (self.n - 1.0)           # 0^0 = 1: n = 1 at sigma = 0
        return f[:, None] * seq_N, f * seq

    def rates(self, t, kappa):
        """G = -E eps_vp' = -A sigma_eq^n E N, Gk = p' = A sigma_eq^n (kappa = p does not
        enter); in plane strain G = -(C3 eps_vp')_in-plane and Gk = (p', eps_vp33').

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, m) internal variables: p (unused), in plane strain then eps_vp33.

        Returns:
            (G rows (n, mt), Gk (n, m)).
        """
        eps_vp, p_rate = self.creep_rate(t, kappa)
        if self.plane_strain is None:
            return -self.elasticity.apply(eps_vp), p_rate[:, None]
        return self.plane_strain.G(eps_vp), np.stack([p_rate, eps_vp[:, 2]], axis=1)

    def elastic(self, t, kappa):
        """No creep exactly where sigma_eq = 0 (the rates are exactly 0 there).

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, m) internal variables (plane strain: eps_vp33 enters sigma_33).

        Returns:
            (n,) booleans.
        """
        if self.plane_strain is not None:
            return flow_direction(self.plane_strain.stress(t, kappa[:, 1]), M3, W3)[0] == 0.0
        return flow_direction(t, self._M, self._w)[0] == 0.0


def _check_plane_strain(vp: dict, source: str) -> None:
    """In plane strain kappa = (p, eps_vp33) starts at 0: kappa0 only 0.

    Args:
        vp: the material.viscoplastic section (default-filled).
        source: the case file, for messages.

    Raises:
        CaseError: kappa0 != 0.
    """
    if vp["kappa0"] != 0:
        raise CaseError(f"{source}: material.viscoplastic.kappa0: law norton in plane strain "
                        "(material.plane: strain) starts from p = 0, eps_vp33 = 0 (allowed: "
                        "0 or absent)")


def _growth(vp, T: float, S: float) -> float:
    """kappa = p, p' = A sigma_eq^n <= A S^n: p moves at most T A S^n in [0, T].

    Args:
        vp: A and n as attributes.
        T: the final time.
        S: the bound of ||sigma||_VM.

    Returns:
        The growth bound.

    Raises:
        OverflowError: S^n overflows.
    """
    return T * vp.A * S ** vp.n


def _stress_scaling(vp: dict, factor: float) -> dict[str, float] | str:
    """sigma -> factor sigma with E: A by factor^-n (A sigma_eq^n unchanged; p is a strain).

    Args:
        vp: the material.viscoplastic section as given.
        factor: the scaling factor.

    Returns:
        {"A": factor^-n}, or the reason where n is not a number.
    """
    if not isinstance(vp.get("n"), (int, float)):
        return "Norton's exponent n is not a number"
    return {"A": factor ** -vp["n"]}


# the declaration of the law (app/model/lawspec.py), collected by app/model/lawregistry.py
SPEC = LawSpec(
    name="norton", title="Norton",
    summary="creep without a yield surface: eps_vp' = A sigma_eq^n N, sigma_eq = "
            "||sigma||_VM (2D plane stress: the paper's norm, sigma_33 = 0), N = d sigma_eq / "
            "d sigma, kappa = p the accumulated creep strain, p' = A sigma_eq^n, G = -E "
            "eps_vp' (plane strain: kappa = (p, eps_vp33), m = 2)",
    kappa0="the initial accumulated creep strain p0, dimensionless, only 0 in plane strain",
    kappa_unit="-",
    keys={"A": LawKey(POSITIVE, "the coefficient of eps_vp' = A sigma_eq^n N, in Pa^-n s^-1",
                      "Pa^-n s^-1", doc="the Norton coefficient A of eps_vp' = A sigma_eq^n "
                                        "N [Pa^-n s^-1]"),
          "n": LawKey(EXPONENT, "the exponent n >= 1 of sigma_eq^n", "-")},
    build=lambda vp, elasticity, plane: Norton(elasticity, vp.A, vp.n, plane),
    kappa_growth=_growth, shown=("A", "n"), check_plane_strain=_check_plane_strain,
    carries_sigma33=True, stress_scaling=_stress_scaling)
