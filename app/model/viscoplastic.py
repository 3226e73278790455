"""The built-in viscoplastic laws (the protocol ViscoplasticLaw is app/model/laws.py):
sigma' = E eps(u') + G(sigma, kappa), kappa' = Gk(sigma, kappa) (1.2)-(1.3).

Perzyna's law of the paper's Section 4 (m = 1) uses its compiled update
(app/kernels/perzyna.c) where a C compiler is available; PowerLaw, Perzyna's with a power
overstress r^(n-1), uses the protocol's defaults; Norton's creep law and Chaboche's are in
modules of their own (app/model/norton.py, app/model/chaboche.py).  Each law is declared once
(its keys, title, checks, kappa's growth bound and factory: app/model/lawspec.py), here
PERZYNA and POWER at the end of the module; ``viscoplastic_law`` of
app/model/lawregistry.py builds the law a case names.  In 2D plane strain Perzyna and
PowerLaw keep the paper's 2D norm (sigma_33 = 0 in ||sigma||_VM, as in plane stress: the
paper's results bit for bit); Norton and Chaboche carry sigma_33 there
(app/model/planestrain.py).
"""
from __future__ import annotations

import numpy as np

from vpcontact import kernels, threads
from vpcontact.model.laws import ExplicitUpdate, ViscoplasticLaw
from vpcontact.model.lawspec import EXPONENT, POSITIVE, LawKey, LawSpec
from vpcontact.model.material import (
    FLAT,
    FROM,
    Elasticity,
    VonMisesProjection,
    make_projection,
)


class Perzyna(ViscoplasticLaw):
    """The paper's Perzyna law (Section 4), m = 1:
    G(sigma, kappa) = -1/(2 lambda1) E (sigma - P sigma),
    Gk(sigma, kappa) = 2/(3 lambda2) ||sigma - P sigma||_VM,
    P = P_K(kappa) the energy-norm projection onto K(kappa) = {||tau||_VM <= kappa}.

    Args:
        elasticity: the elasticity E.
        lambda1: viscosity of the stress rate G.
        lambda2: viscosity of the hardening rate Gk.
    """

    m = 1
    name = "perzyna"

    def __init__(self, elasticity: Elasticity, lambda1: float, lambda2: float):
        super().__init__(elasticity)
        self.lambda1, self.lambda2 = lambda1, lambda2
        self._project = make_projection(elasticity)

    def constants(self):
        """Returns: lambda1 [N s/m^2], lambda2 [s] (as the case file's keys)."""
        return PERZYNA.constants_of(self)

    def lipschitz_constant(self) -> float:
        """L_G = lambda_max(E) / (2 lambda1) in the energy norm |tau|_E = (E tau : tau)^1/2:
        I - P_K(kappa) is nonexpansive in that norm for every kappa (P_K the projection onto
        a closed convex set in its inner product), and E, self-adjoint in it, has
        |E tau|_E <= lambda_max(E) |tau|_E.  In 2D the bound is attained at kappa = 0 (K(0) =
        {0}, G = -E sigma / (2 lambda1)); in 3D, where P keeps the hydrostatic part, the
        isotropic law's smallest constant is 2 mu / (2 lambda1) and this is a bound.

        Returns:
            L_G [1/s], equal to the relaxation rate r_max.
        """
        return self.relaxation_rate()

    def project(self, t: np.ndarray, kappa: np.ndarray) -> np.ndarray:
        """The projection P_K(kappa).

        Args:
            t: rows (n, mt) of t-coordinates.
            kappa: (n,) radii >= 0.

        Returns:
            The rows (n, mt) of P_K(kappa) t.
        """
        return self._project(t, kappa)

    def rates(self, t, kappa):
        """G = -1/(2 lambda1) E (sigma - P sigma), Gk = 2/(3 lambda2) ||sigma - P sigma||_VM.

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, 1) hardening values.

        Returns:
            (G rows (n, mt), Gk (n, 1)).
        """
        excess = t - self._project(t, kappa[:, 0])
        return (-0.5 / self.lambda1) * self.elasticity.apply(excess), \
            ((2.0 / (3.0 * self.lambda2)) * self.elasticity.von_mises(excess))[:, None]

    def elastic(self, t, kappa):
        """Inside the ball K(kappa): ||sigma||_VM <= kappa.

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, 1) hardening values.

        Returns:
            (n,) booleans.
        """
        return ~(self.elasticity.von_mises(t) > kappa[:, 0])

    def implicit_residual(self, z, s_tr, kappa_prev, k):
        """The backward-Euler residual of Perzyna's law, kappa clipped at 0 in P:
        R_s = sigma - s_tr + k/(2 lambda1) E (sigma - P_kappa sigma),
        R_k = kappa - kappa_{n-1} - k 2/(3 lambda2) ||sigma - P_kappa sigma||_VM.

        Args:
            z: (n, mt + 1) unknowns: sigma in t-coordinates, then kappa.
            s_tr: (n, mt) trial stresses E eps(u_n) + H_{n-1}.
            kappa_prev: (n, 1) kappa_{n-1}.
            k: the time step k_n.

        Returns:
            The (n, mt + 1) residuals.
        """
        mt = self.elasticity.m
        s, kap = z[:, :mt], z[:, mt]
        excess = s - self.project(s, np.maximum(kap, 0.0))
        r = np.empty_like(z)
        r[:, :mt] = s - s_tr + (0.5 * k / self.lambda1) * self.elasticity.apply(excess)
        r[:, mt] = kap - kappa_prev[:, 0] \
            - (2.0 * k / (3.0 * self.lambda2)) * self.elasticity.von_mises(excess)
        return r

    def relaxation_rate(self) -> float:
        """Near the ball the update relaxes the excess by (I - k E/(2 lambda1)).

        Returns:
            r_max = lambda_max(E) / (2 lambda1), E acting on symmetric tensors.
        """
        return self.elasticity.bounds()[1] / (2.0 * self.lambda1)

    def explicit(self):
        """The explicit update (3.2)-(3.3) compiled (app/kernels/perzyna.c), or in numpy
        where no C compiler is available.

        Returns:
            A CompiledPerzynaUpdate or an ExplicitUpdate.
        """
        module = kernels.load()   # the kernel takes one E: numpy for E per cell
        return ExplicitUpdate(self) if module is None or not self.elasticity.homogeneous \
            else CompiledPerzynaUpdate(self, module)


class CompiledPerzynaUpdate:
    """Perzyna's explicit update (3.2)-(3.3) by the compiled kernel (kernels.PerzynaKernel,
    which keeps each cell's last root as the next start).

    Args:
        law: the Perzyna law.
        module: the compiled kernels (kernels.load()).
    """

    def __init__(self, law: Perzyna, module):
        el = law.elasticity
        self.kernel = kernels.PerzynaKernel(el, VonMisesProjection(el), law.lambda1,
                                            law.lambda2, module, FLAT[el.dim], FROM[el.dim])

    def __call__(self, sigma, H, kappa, k) -> None:
        """As ExplicitUpdate.__call__ (nothing is written if a cell's root search fails).

        Args:
            sigma: sigma_{n-1} per cell, flat (ncells * d * d).
            H: H_{n-1} per cell, same layout; becomes H_n.
            kappa: kappa_{n-1}, (ncells, 1); becomes kappa_n.
            k: the step k_n.

        Raises:
            RuntimeError: the secular equation of the projection did not converge.
        """
        if self.kernel.advance(sigma, H, kappa.reshape(-1), k, threads.own_cores()):
            raise RuntimeError("von Mises projection: secular equation did not converge")


class PowerLaw(ViscoplasticLaw):
    """Perzyna's law with a power overstress, m = 1: with r = ||sigma - P sigma||_VM / s_ref,
    G(sigma, kappa) = -r^(n-1)/(2 lambda1) E (sigma - P sigma),
    Gk(sigma, kappa) = 2 r^(n-1)/(3 lambda2) ||sigma - P sigma||_VM,
    P = P_K(kappa) the projection of Perzyna's law (app/model/material.py).  n = 1 is
    Perzyna's law.  The explicit update is the interface's numpy ExplicitUpdate, the
    implicit one solves the interface's default residual; the relaxation rate
    r^(n-1) lambda_max(E)/(2 lambda1) grows without bound with the overstress, so the law
    gives none (no stability indicator).

    Args:
        elasticity: the elasticity E.
        lambda1: viscosity of the stress rate G [N s/m^2].
        lambda2: viscosity of the hardening rate Gk [s].
        n: the exponent n >= 1 of the overstress.
        s_ref: the stress scale s_ref > 0 of the overstress [N/m^2].
    """

    m = 1
    name = "power"

    def __init__(self, elasticity: Elasticity, lambda1: float, lambda2: float, n: float,
                 s_ref: float):
        super().__init__(elasticity)
        self.lambda1, self.lambda2, self.n, self.s_ref = lambda1, lambda2, n, s_ref
        self._project = make_projection(elasticity)

    def constants(self):
        """Returns: lambda1 [N s/m^2], lambda2 [s], n [-], s_ref [N/m^2]."""
        return POWER.constants_of(self)

    def lipschitz_constant(self) -> float | None:
        """L_G: Perzyna's lambda_max(E) / (2 lambda1) for n = 1; for n > 1 the slope
        r^(n-1) grows without bound with the overstress.

        Returns:
            L_G [1/s] for n = 1, else None.
        """
        if self.n != 1:
            return None
        return self.elasticity.bounds()[1] / (2.0 * self.lambda1)

    def rates(self, t, kappa):
        """G = -r^(n-1)/(2 lambda1) E (sigma - P sigma), Gk = 2 r^(n-1)/(3 lambda2)
        ||sigma - P sigma||_VM, r = ||sigma - P sigma||_VM / s_ref; P with kappa clipped at
        0 (the implicit update's Newton iterates may step below).

        Args:
            t: rows (n, mt) of sigma in t-coordinates.
            kappa: (n, 1) hardening values.

        Returns:
            (G rows (n, mt), Gk (n, 1)).
        """
        excess = t - self._project(t, np.maximum(kappa[:, 0], 0.0))
        vm = self.elasticity.von_mises(excess)
        with np.errstate(over="ignore"):
            f = (vm / self.s_ref) ** (self.n - 1.0)        # 0^0 = 1: n = 1 is Perzyna's
        return ((-0.5 / self.lambda1) * f)[:, None] * self.elasticity.apply(excess), \
            (((2.0 / (3.0 * self.lambda2)) * f) * vm)[:, None]


# the declarations of the two laws (app/model/lawspec.py), collected by app/model/lawregistry.py
_LAMBDA1 = LawKey(POSITIVE, "the viscosity of G, in N s/m^2", "N s/m^2",
                  doc="the viscosity lambda1 of G [N s/m^2]")
_LAMBDA2 = LawKey(POSITIVE, "the viscosity of Gk, in s", "s",
                  doc="the viscosity lambda2 of the kappa law Gk [s]")
_HARDENING = "the initial hardening kappa0 [N/m^2], the radius of K(kappa0)"


def _perzyna_growth(vp, T: float, S: float) -> float:
    """kappa' = 2/(3 lambda2) ||sigma - P sigma||_VM <= 2/(3 lambda2) S: kappa moves at most
    2 T S / (3 lambda2) in [0, T].

    Args:
        vp: lambda2 as an attribute.
        T: the final time.
        S: the bound of ||sigma||_VM.

    Returns:
        The growth bound.
    """
    return 2.0 * T / (3.0 * vp.lambda2) * S


def _power_growth(vp, T: float, S: float) -> float:
    """Perzyna's bound times the overstress factor r^(n-1), r = S / s_ref, at least 1.

    Args:
        vp: lambda2, n, s_ref as attributes.
        T: the final time.
        S: the bound of ||sigma||_VM.

    Returns:
        The growth bound.

    Raises:
        OverflowError: the factor overflows (no bound on kappa).
    """
    return _perzyna_growth(vp, T, S) * max(1.0, S / vp.s_ref) ** (vp.n - 1.0)


def _lambda1_scaling(vp: dict, factor: float) -> dict[str, float]:
    """sigma -> factor sigma with E: lambda1 and kappa0 (G = -E (sigma - P sigma) / (2
    lambda1)) and the power law's s_ref scale by ``factor``.

    Args:
        vp: the material.viscoplastic section as given.
        factor: the scaling factor.

    Returns:
        {key: factor} of those keys present in the section.
    """
    return {k: factor for k in ("lambda1", "kappa0", "s_ref") if k in vp}


PERZYNA = LawSpec(
    name="perzyna", title="Perzyna",
    summary="the paper's G = -1/(2 lambda1) E (sigma - P sigma), Gk = 2/(3 lambda2) "
            "||sigma - P sigma||_VM",
    kappa0=_HARDENING, kappa_unit="N/m^2",
    keys={"lambda1": _LAMBDA1, "lambda2": _LAMBDA2},
    build=lambda vp, elasticity, plane: Perzyna(elasticity, vp.lambda1, vp.lambda2),
    kappa_growth=_perzyna_growth, stress_scaling=_lambda1_scaling)

POWER = LawSpec(
    name="power", title="power-law Perzyna",
    summary="Perzyna with a power overstress: both rates times r^(n-1), r = ||sigma - P "
            "sigma||_VM / s_ref (n = 1: perzyna)",
    kappa0=_HARDENING, kappa_unit="N/m^2",
    keys={"lambda1": _LAMBDA1, "lambda2": _LAMBDA2,
          "n": LawKey(EXPONENT, "the exponent n >= 1 of the overstress r^(n-1)", "-", 1.0),
          "s_ref": LawKey(POSITIVE, "the stress scale of the overstress r = ||sigma - P "
                                    "sigma||_VM / s_ref, in Pa", "N/m^2",
                          doc="the stress scale s_ref of the overstress r = ||sigma - P "
                              "sigma||_VM / s_ref [N/m^2 = Pa]")},
    build=lambda vp, elasticity, plane: PowerLaw(elasticity, vp.lambda1, vp.lambda2, vp.n,
                                                 vp.s_ref),
    kappa_growth=_power_growth, shown=("n", "s_ref"), stress_scaling=_lambda1_scaling)
