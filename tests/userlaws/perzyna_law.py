"""Laws written as a user would, for --law-module in the tests: Perzyna's law of the paper
(Section 4) in tensors (UserPerzyna, and UserPerzynaTangent with its derivatives by finite
differences of its own G, Gk), and laws that break the protocol (a wrong m, wrong shapes,
non-finite values, wrong shapes during the run, a G or a constructor that raises or calls
sys.exit, a G that raises above a stress level)."""
import numpy as np

from vpcontact.model.material import make_projection


class UserPerzyna:
    """G = -1/(2 lambda1) E (sigma - P sigma), Gk = 2/(3 lambda2) ||sigma - P sigma||_VM,
    P the energy-norm projection onto {||tau||_VM <= kappa}, kappa clipped at 0."""

    m = 1
    name = "user perzyna"

    def __init__(self, elasticity, lambda1, lambda2):
        self.el, self.lambda1, self.lambda2 = elasticity, lambda1, lambda2
        self.project = make_projection(elasticity)

    def _excess(self, sigma, kappa):
        t = self.el.to_voigt(sigma)
        return t - self.project(t, np.maximum(kappa[:, 0], 0.0))

    def G(self, sigma, eps, kappa):
        excess = self._excess(sigma, kappa)
        return self.el.from_voigt((-0.5 / self.lambda1) * self.el.apply(excess))

    def Gk(self, sigma, eps, kappa):
        vm = self.el.von_mises(self._excess(sigma, kappa))
        return ((2.0 / (3.0 * self.lambda2)) * vm)[:, None]

    def rate_bound(self):
        return float(np.max(np.linalg.eigvalsh(self.el.Cmat))) / (2.0 * self.lambda1)


class UserPerzynaTangent(UserPerzyna):
    """UserPerzyna with dG, dGk: central differences of G, Gk by each entry of sigma (the
    pair (a, b), (b, a) moved together, half the derivative to each) and by kappa."""

    def _by_sigma(self, f, sigma, eps, kappa):
        d = sigma.shape[1]
        out = []
        for a in range(d):
            row = []
            for b in range(d):
                h = 1e-6 * (np.abs(sigma).max() + 1.0)
                e = np.zeros((d, d))
                e[a, b] = e[b, a] = h
                diff = (f(sigma + e, eps, kappa) - f(sigma - e, eps, kappa)) / (2 * h)
                row.append(diff if a == b else 0.5 * diff)
            out.append(np.stack(row, axis=-1))
        return np.stack(out, axis=-2)

    def _by_kappa(self, f, sigma, eps, kappa):
        h = 1e-6 * (np.abs(kappa).max() + 1.0)
        return ((f(sigma, eps, kappa + h) - f(sigma, eps, kappa - h)) / (2 * h))[..., None]

    def dG(self, sigma, eps, kappa):
        return self._by_sigma(self.G, sigma, eps, kappa), self._by_kappa(self.G, sigma, eps,
                                                                          kappa)

    def dGk(self, sigma, eps, kappa):
        return self._by_sigma(self.Gk, sigma, eps, kappa), self._by_kappa(self.Gk, sigma,
                                                                           eps, kappa)


class WrongM(UserPerzyna):
    """m is not an integer >= 1."""

    m = 0


class WrongShape(UserPerzyna):
    """Gk returned flat, (n,) instead of (n, m)."""

    def Gk(self, sigma, eps, kappa):
        return super().Gk(sigma, eps, kappa)[:, 0]


class NotFinite(UserPerzyna):
    """G is NaN wherever sigma is zero (a flow direction divided by ||sigma||)."""

    def G(self, sigma, eps, kappa):
        norm = np.sqrt(np.einsum("nij,nij->n", sigma, sigma))
        with np.errstate(invalid="ignore"):
            return sigma / norm[:, None, None]


class RaisesInG(UserPerzyna):
    """G raises (a KeyError of the user's code) wherever it is called."""

    def G(self, sigma, eps, kappa):
        raise KeyError("x")


class FailingInit(UserPerzyna):
    """The constructor raises something other than TypeError (a RuntimeError)."""

    def __init__(self, elasticity, lambda1, lambda2):
        raise RuntimeError("no licence for this law")


class ExitsInInit(UserPerzyna):
    """The constructor calls sys.exit(0)."""

    def __init__(self, elasticity, lambda1, lambda2):
        import sys
        sys.exit(0)


class ExitsInG(UserPerzyna):
    """G calls sys.exit(0) once sigma is not zero (after the probe at the zero state)."""

    def G(self, sigma, eps, kappa):
        if np.any(sigma != 0.0):
            import sys
            sys.exit(0)
        return super().G(sigma, eps, kappa)


class RaisesAbove(UserPerzyna):
    """UserPerzyna without a rate bound (the run estimates its rate at every step) whose G
    raises a RuntimeError once max ||sigma||_VM over the cells it is given exceeds
    ``level``."""

    def __init__(self, elasticity, lambda1, lambda2, level):
        super().__init__(elasticity, lambda1, lambda2)
        self.level = level

    def rate_bound(self):
        return None

    def G(self, sigma, eps, kappa):
        if len(sigma) and self.el.von_mises(self.el.to_voigt(sigma)).max() > self.level:
            raise RuntimeError("stress too large for my law")
        return super().G(sigma, eps, kappa)


class ShapeLater(UserPerzyna):
    """Gk flat, (n,) instead of (n, m), once sigma is not zero (after the probe)."""

    def Gk(self, sigma, eps, kappa):
        gk = super().Gk(sigma, eps, kappa)
        return gk[:, 0] if np.any(sigma != 0.0) else gk
