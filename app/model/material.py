"""Elasticity and the von Mises projection of the paper (Section 4), in 2D and 3D.

Stresses are stored per cell (DG0) as d x d arrays; the per-cell algebra uses coordinates
t = (t11, t22, t12) in 2D and t = (t11, t22, t33, t23, t13, t12) in 3D, vectorised over cells:
- E acts as  (E tau) = Cmat t;  E tau = lmbda tr(tau) I + two_mu tau (plane stress in 2D,
  isotropic Hooke in 3D, see forms/elasticity.py);
- the energy form (E tau):tau = t^T A t,  A = diag(1.., 2..) Cmat  (shears counted twice);
- the von Mises form ||tau||_VM^2 = t^T M t: in 2D t11^2 + t22^2 - t11 t22 + 3 t12^2 (the
  paper), in 3D 3/2 dev(tau):dev(tau).

E is isotropic and homogeneous (Elasticity: the paper's), any homogeneous matrix
(MatrixElasticity: orthotropic, a Voigt matrix) or one matrix per cell (CellElasticity: E(x)
in L-infinity, DG0); the laws use only ``apply``, ``Cmat``, ``A``, ``von_mises`` and the
projection, and so work per cell (app/model/stiffness.py builds E from a case).

The projection P = P_K(kappa) onto K(kappa) = {||tau||_VM <= kappa} in the energy inner
product, exact in both dimensions (VonMisesProjection for any homogeneous E, its closed form
RadialReturn for an isotropic E in 3D, CellProjection per cell), is the Perzyna law's
(app/model/viscoplastic.py).
"""
from __future__ import annotations

from contextlib import contextmanager, nullcontext
from dataclasses import dataclass

import numpy as np

from vpcontact.forms.elasticity import PAIRS as _PAIRS  # (row, col) of each t_i
from vpcontact.forms.elasticity import lame_constants

# flat (row-major d x d) positions of the coordinates, and of every tensor entry
FLAT = {d: np.array([i * d + j for i, j in _PAIRS[d]]) for d in (2, 3)}
FROM = {d: np.array([next(k for k, p in enumerate(_PAIRS[d]) if set(p) == {i, j})
                      for i in range(d) for j in range(d)]) for d in (2, 3)}


def to_voigt(tau: np.ndarray, dim: int = 2) -> np.ndarray:
    """Symmetric tensors to t-coordinates.

    The tensors are symmetric (sigma, H, eps), so the upper triangle is read.

    Args:
        tau: (n, d, d) symmetric tensors, or their flat (row-major) array.
        dim: space dimension d.

    Returns:
        The (n, m) coordinates (m = 3 in 2D, 6 in 3D).
    """
    return np.asarray(tau).reshape(-1, dim * dim)[:, FLAT[dim]]


def from_voigt(t: np.ndarray, dim: int = 2) -> np.ndarray:
    """t-coordinates to symmetric tensors.

    Args:
        t: (n, m) coordinates (or their flat array).
        dim: space dimension d.

    Returns:
        The (n, d, d) symmetric tensors.
    """
    t = np.asarray(t).reshape(-1, len(_PAIRS[dim]))
    return t[:, FROM[dim]].reshape(-1, dim, dim)


def _von_mises_matrix(dim: int) -> np.ndarray:
    if dim == 2:
        return np.array([[1.0, -0.5, 0.0], [-0.5, 1.0, 0.0], [0.0, 0.0, 3.0]])
    M = np.zeros((6, 6))
    M[:3, :3] = -0.5
    np.fill_diagonal(M[:3, :3], 1.0)
    M[3:, 3:] = 3.0 * np.eye(3)
    return M


class ElasticityForms:
    """The quadratic forms in t-coordinates of an elasticity E given by its matrix ``Cmat``
    (t-coordinates of E tau from those of tau): the energy form A, the von Mises form M, E
    tau and the coordinates.  The subclasses give ``Cmat`` and ``dim``:
    Elasticity (isotropic), MatrixElasticity (any homogeneous E), CellElasticity (one matrix
    per cell, E(x) in L-infinity).

    Attributes:
        isotropic: E is isotropic and the same in every cell (the 3D closed-form projection
            RadialReturn applies).
        homogeneous: one matrix for every cell (``Cmat`` is (m, m), not per row).
    """

    isotropic = False
    homogeneous = True

    @property
    def m(self) -> int:
        """The number of t-coordinates (3 in 2D, 6 in 3D)."""
        return len(_PAIRS[self.dim])

    @property
    def weights(self) -> np.ndarray:
        """Frobenius weights of the coordinates: tau:sigma = sum w_i t_i s_i."""
        return np.array([1.0] * self.dim + [2.0] * (self.m - self.dim))

    @property
    def A(self) -> np.ndarray:
        """The energy form: (E tau):tau = t^T A t (shears counted twice)."""
        return np.diag(self.weights) @ self.Cmat

    @property
    def M(self) -> np.ndarray:
        """The von Mises form: ||tau||_VM^2 = t^T M t."""
        return _von_mises_matrix(self.dim)

    def apply(self, t: np.ndarray) -> np.ndarray:
        """E tau.

        Args:
            t: rows (n, m) of t-coordinates.

        Returns:
            The rows (n, m) of E tau.
        """
        return t @ self.Cmat.T

    def von_mises(self, t: np.ndarray) -> np.ndarray:
        """The von Mises norm.

        Args:
            t: rows (n, m) of t-coordinates.

        Returns:
            ||tau||_VM per row, (n,).
        """
        return np.sqrt(np.maximum(np.einsum("ni,ni->n", t @ self.M, t), 0.0))

    def to_voigt(self, tau):
        """``to_voigt`` in this dimension.

        Args:
            tau: (n, d, d) symmetric tensors, or their flat array.

        Returns:
            The (n, m) t-coordinates.
        """
        return to_voigt(tau, self.dim)

    def from_voigt(self, t):
        """``from_voigt`` in this dimension.

        Args:
            t: (n, m) t-coordinates.

        Returns:
            The (n, d, d) symmetric tensors.
        """
        return from_voigt(t, self.dim)

    def rows(self, index=None):
        """Select the cells the rows of the next calls are (a homogeneous E: nothing to
        select; CellElasticity.rows).

        Args:
            index: row indices (ignored here).

        Returns:
            A context manager.
        """
        return nullcontext()

    def bounds(self) -> tuple[float, float]:
        """m_E and M_E: the smallest and largest eigenvalue of E on symmetric tensors in the
        Frobenius inner product (the eigenvalues of Cmat: Cmat = W^-1 A), over all cells.

        Returns:
            (m_E, M_E).
        """
        lam = np.linalg.eigvals(self.Cmat).real
        return float(np.min(lam)), float(np.max(lam))


@dataclass(frozen=True)
class Elasticity(ElasticityForms):
    """The isotropic elasticity operator E and the quadratic forms in t-coordinates
    (d = 2 or 3).

    Attributes:
        E: Young's modulus.
        nu: Poisson's ratio.
        dim: space dimension d (2: the paper's plane stress, 3: isotropic Hooke).
    """

    E: float
    nu: float
    dim: int = 2
    isotropic = True

    @property
    def Cmat(self) -> np.ndarray:
        """The (m, m) matrix of E in t-coordinates: (E tau) = Cmat t."""
        lmbda, two_mu = lame_constants(self.E, self.nu, self.dim)
        d, m = self.dim, self.m
        C = two_mu * np.eye(m)
        C[:d, :d] += lmbda
        return C


class _Described:
    """The description of an elasticity built from a case (summary.json's "laws", check):
    ``name`` and ``constants()`` as the laws give them (app/model/laws.py)."""

    name = "elasticity"
    _constants: dict | None = None

    def describe_as(self, name: str, constants: dict):
        """Set the description.

        Args:
            name: e.g. "orthotropic, plane stress".
            constants: name -> (value, unit) (values numbers or text).

        Returns:
            self.
        """
        self.name, self._constants = name, dict(constants)
        return self

    def constants(self) -> dict:
        """Returns: name -> (value, unit), as given to ``describe_as`` (else empty)."""
        return dict(self._constants or {})


class MatrixElasticity(_Described, ElasticityForms):
    """A homogeneous elasticity E given by its matrix in t-coordinates (anisotropic:
    orthotropic or a Voigt matrix, app/model/stiffness.py builds it from a case).

    Args:
        Cmat: the (m, m) matrix, (E tau) = Cmat t; A = diag(weights) Cmat must be
            symmetric positive definite (checked by the builders).
        dim: space dimension d.

    Attributes:
        out_of_plane: 2D plane strain from orthotropic 3D data: the row r of sigma_33 = r .
            t(sigma) (app/model/fullstress.py), else None (set by the builder).
    """

    out_of_plane = None

    def __init__(self, Cmat: np.ndarray, dim: int):
        self.dim = dim
        self._C = np.array(Cmat, dtype=float).reshape(self.m, self.m)
        self._C.flags.writeable = False

    @property
    def Cmat(self) -> np.ndarray:
        """The (m, m) matrix of E in t-coordinates."""
        return self._C


class CellElasticity(_Described, ElasticityForms):
    """E(x) in L-infinity: one matrix per cell (DG0), vectorised over cells.

    The rows of the per-cell arrays of a run are the cells of the DG0 spaces (owned and
    ghost, in the DG0 dof order: the rows of sigma.x.array reshaped (n, d * d)).  The
    distinct matrices ``mats`` are stored once and ``index`` gives each row's.  A law
    evaluates on all rows, or on a subset of them selected with ``rows`` (the implicit
    update's flowing cells): ``Cmat``, ``A``, ``apply`` and the projection then act on the
    selected rows.  ``von_mises`` does not depend on E.

    Args:
        mats: (g, m, m) distinct matrices in t-coordinates.
        index: (n,) the matrix of each row.
        dim: space dimension d.
        extremes: the global (m_E, M_E) over every rank's cells (``bounds``), computed
            from ``mats`` if not given (then this rank's only).
    """

    homogeneous = False

    def __init__(self, mats: np.ndarray, index: np.ndarray, dim: int,
                 extremes: tuple[float, float] | None = None):
        self.dim = dim
        self.mats = np.array(mats, dtype=float).reshape(-1, self.m, self.m)
        self.index = np.asarray(index, dtype=np.intp).reshape(-1)
        self._selection = [np.arange(len(self.index))]
        lam = np.linalg.eigvals(self.mats).real if len(self.mats) else np.zeros(1)
        self._extremes = extremes if extremes is not None else \
            (float(lam.min()), float(lam.max()))

    @classmethod
    def from_rows(cls, Cmats: np.ndarray, dim: int,
                  extremes: tuple[float, float] | None = None) -> CellElasticity:
        """From one matrix per row (equal matrices are stored once).

        Args:
            Cmats: (n, m, m) matrices in t-coordinates, one per row.
            dim: space dimension d.
            extremes: as for the constructor.

        Returns:
            The CellElasticity.
        """
        m = len(_PAIRS[dim])
        flat = np.asarray(Cmats, dtype=float).reshape(-1, m * m)
        mats, index = np.unique(flat, axis=0, return_inverse=True)
        return cls(mats.reshape(-1, m, m), index, dim, extremes)

    @classmethod
    def from_pieces(cls, n: int, pieces, dim: int,
                    extremes: tuple[float, float] | None = None) -> CellElasticity:
        """From the elasticities of disjoint sets of rows (materials per group of cells).

        Args:
            n: the number of rows.
            pieces: (rows, elasticity) pairs: row indices and a homogeneous elasticity
                (Elasticity, MatrixElasticity) or a CellElasticity over all n rows (its
                rows ``rows`` are taken); together they must cover every row once.
            dim: space dimension d.
            extremes: as for the constructor.

        Returns:
            The CellElasticity.

        Raises:
            ValueError: if the pieces do not cover every row exactly once.
        """
        m = len(_PAIRS[dim])
        Cmats = np.full((n, m, m), np.nan)
        count = np.zeros(n, dtype=int)
        for rows, el in pieces:
            rows = np.asarray(rows, dtype=np.intp)
            np.add.at(count, rows, 1)
            Cmats[rows] = el.Cmat if el.homogeneous else el.mats[el.index[rows]]
        if np.any(count != 1):
            raise ValueError("the pieces of a CellElasticity must cover every row once")
        return cls.from_rows(Cmats, dim, extremes)

    @property
    def selected(self) -> np.ndarray:
        """The rows the calls act on (all rows unless ``rows`` selected some)."""
        return self._selection[-1]

    @contextmanager
    def rows(self, index=None):
        """Let the calls inside act on the rows ``index`` of the current selection
        (selections nest: inside rows(a), rows(b) selects a[b]).

        Args:
            index: row indices (or a boolean mask) into the current selection; None: all.

        Yields:
            None.
        """
        sel = self.selected
        self._selection.append(sel if index is None else sel[np.asarray(index)])
        try:
            yield
        finally:
            self._selection.pop()

    @property
    def Cmat(self) -> np.ndarray:
        """(n, m, m): the matrices of the selected rows."""
        return self.mats[self.index[self.selected]]

    @property
    def A(self) -> np.ndarray:
        """(n, m, m): the energy forms of the selected rows."""
        return self.weights[None, :, None] * self.Cmat

    def apply(self, t: np.ndarray) -> np.ndarray:
        """E tau per row.

        Args:
            t: rows (n, m) of t-coordinates, one per selected row.

        Returns:
            The rows (n, m) of E tau.

        Raises:
            ValueError: if the rows are not the selected cells.
        """
        t = np.asarray(t, dtype=float).reshape(-1, self.m)
        sel = self.selected
        if t.shape[0] != len(sel):
            raise ValueError(f"per-cell elasticity: {t.shape[0]} rows for {len(sel)} "
                             "selected cells (select them with elasticity.rows)")
        return np.einsum("nij,nj->ni", self.mats[self.index[sel]], t)

    def bounds(self) -> tuple[float, float]:
        """m_E and M_E over every cell (see ElasticityForms.bounds).

        Returns:
            (m_E, M_E).
        """
        return self._extremes


def PlaneStress(E: float, nu: float) -> Elasticity:
    """The paper's plane-stress elasticity (d = 2).

    Args:
        E: Young's modulus.
        nu: Poisson's ratio.

    Returns:
        Elasticity(E, nu, 2).
    """
    return Elasticity(E, nu, 2)


class RadialReturn:
    """Closed-form projection onto K(kappa) in 3D for isotropic E.

    With tau = dev(tau) + tr(tau)/3 I, both forms split: (E tau):tau = two_mu dev:dev +
    (lmbda + two_mu/3) tr^2 and ||tau||_VM^2 = 3/2 dev:dev.  On deviators the energy form is
    a multiple of the Frobenius one, so the closest point in the energy norm keeps the
    hydrostatic part and scales the deviator radially:
        P tau = tr(tau)/3 I + min(1, kappa / ||tau||_VM) dev(tau).

    Args:
        elasticity: the (3D) elasticity.

    Raises:
        ValueError: if ``elasticity`` is not 3D.
    """

    def __init__(self, elasticity: Elasticity):
        if elasticity.dim != 3 or not elasticity.isotropic:
            raise ValueError("RadialReturn is the 3D projection of an isotropic E")
        self.elasticity = elasticity

    def __call__(self, s: np.ndarray, kappa: np.ndarray) -> np.ndarray:
        """Project rows s (n, 6) onto K(kappa) (kappa: (n,) >= 0); returns (n, 6)."""
        s = np.asarray(s, dtype=float).reshape(-1, 6)
        kappa = np.broadcast_to(np.asarray(kappa, dtype=float), (s.shape[0],))
        vm = self.elasticity.von_mises(s)
        scale = np.where(vm > kappa, kappa / np.where(vm > 0, vm, 1.0), 1.0)
        mean = s[:, :3].mean(axis=1, keepdims=True)
        out = s * scale[:, None]
        out[:, :3] = mean + (s[:, :3] - mean) * scale[:, None]
        return out


def make_projection(elasticity: Elasticity):
    """The exact energy-norm projection P_K(kappa) onto the von Mises ball.

    Args:
        elasticity: the elasticity E that defines the energy inner product.

    Returns:
        A callable (t, kappa) -> P t: RadialReturn for an isotropic homogeneous E in 3D,
        VonMisesProjection for any other homogeneous E, CellProjection for E per cell.
    """
    if not elasticity.homogeneous:
        return CellProjection(elasticity)
    if elasticity.dim == 3 and elasticity.isotropic:
        return RadialReturn(elasticity)
    return VonMisesProjection(elasticity)


class VonMisesProjection:
    """Exact projection onto K(kappa) = {||tau||_VM <= kappa} in the norm (E tau : tau)^1/2.

    With V such that V^T A V = I and V^T M V = diag(lam) (computed once per material),
    P s = V diag(1 / (1 + mu lam)) V^T A s, and the root mu of ||P s||_VM = kappa solves the
    secular equation  1/sqrt(q(mu)) = 1/kappa,  q(mu) = sum_i lam_i z_i^2 / (1 + mu lam_i)^2,
    z = V^T A s.  1/sqrt(q) is concave and increasing in mu, so Newton from mu = 0 converges
    monotonically (as for the trust-region subproblem); iterations are vectorised over cells.
    Equal eigenvalues are grouped (in plane stress lam takes two values: the directions
    (1, -1, 0) and (0, 0, 1) share one), so q costs one term per distinct eigenvalue.

    Args:
        elasticity: the elasticity E that defines the energy inner product.
        rtol: relative tolerance of the secular equation.
        max_iter: Newton iterations allowed.
    """

    def __init__(self, elasticity: Elasticity, rtol: float = 1e-14, max_iter: int = 100):
        A, M = elasticity.A, elasticity.M
        self.m = A.shape[0]
        L = np.linalg.cholesky(A)
        Linv = np.linalg.inv(L)
        lam, W = np.linalg.eigh(Linv @ M @ Linv.T)
        self.lam = np.where(lam > 1e-12 * lam.max(), lam, 0.0)   # M may be singular (3D)
        self.V = Linv.T @ W
        self.AV = A @ self.V                  # z = s @ AV
        self.A, self.M = A, M
        self.rtol, self.max_iter = rtol, max_iter
        groups: list[list[int]] = []
        for i, li in enumerate(self.lam):
            for g in groups:
                if abs(self.lam[g[0]] - li) <= 1e-12 * self.lam.max():
                    g.append(i)
                    break
            else:
                groups.append([i])
        self.groups = groups

    def __call__(self, s: np.ndarray, kappa: np.ndarray) -> np.ndarray:
        """Project onto K(kappa).

        Args:
            s: rows (n, m) of t-coordinates.
            kappa: (n,) radii >= 0 (or a scalar).

        Returns:
            The rows (n, m) of P_K(kappa) s; NaN rows for non-finite input.

        Raises:
            RuntimeError: if the secular equation does not converge.
        """
        s = np.asarray(s, dtype=float).reshape(-1, self.m)
        kappa = np.broadcast_to(np.asarray(kappa, dtype=float), (s.shape[0],))
        out = s.copy()
        vm2 = np.einsum("ni,ni->n", s @ self.M, s)
        bad = ~(np.isfinite(vm2) & np.isfinite(kappa))
        with np.errstate(invalid="ignore", over="ignore"):
            outside = (vm2 > kappa * kappa) & ~bad
        out[bad] = np.nan                        # non-finite input propagates as NaN
        huge = bad & np.isfinite(s).all(axis=1) & np.isfinite(kappa) if bad.any() else bad
        if huge.any():                         # |s|^2 overflowed: project the scaled rows
            c = np.abs(s[huge]).max(axis=1)      # (P is positively homogeneous)
            out[huge] = self(s[huge] / c[:, None], kappa[huge] / c) * c[:, None]
        if not np.any(outside):
            return out
        every = bool(outside.all())              # the common case: no fancy indexing
        # P is positively homogeneous: project s / c onto K(kappa / c) with c = ||s||_VM, so
        # that nothing in the secular equation can overflow however large the stresses
        c = np.sqrt(vm2 if every else vm2[outside])
        z = ((s if every else s[outside]) @ self.AV) / c[:, None]   # z = V^T A s / c per row
        k = (kappa if every else kappa[outside]) / c
        # kappa/|s| below 1e-150 would underflow q ~ kappa^2: project onto {0} (kappa = 0)
        zero = k <= 1e-150
        kk2 = np.where(zero, 1.0, k * k)
        lam = [self.lam[g[0]] for g in self.groups]
        w = [lam_g * sum(z[:, i] ** 2 for i in g) for lam_g, g in zip(lam, self.groups)]
        # start at the lower bound of the root from q(mu) >= sum(w) / (1 + mu lam_max)^2, so
        # the iterates increase monotonically to the root (left of it, phi is concave)
        lam_max = max(lam)
        mu = np.maximum((np.sqrt(sum(w) / kk2) - 1.0) / lam_max, 0.0) if lam_max > 0 \
            else np.zeros(z.shape[0])
        for _ in range(self.max_iter):   # whole-array Newton steps on phi = q^-1/2 - 1/kappa
            q = np.zeros_like(mu)
            dq = np.zeros_like(mu)
            for lam_g, w_g in zip(lam, w):
                r = 1.0 / (1.0 + mu * lam_g)
                t = w_g * r * r
                q += t
                dq -= (2.0 * lam_g) * t * r
            # 1 - q/kappa^2 ~ 2 kappa phi near the root; the Newton step in closed form
            res = np.abs(1.0 - q / kk2)
            if np.where(zero, 0.0, res).max(initial=0.0) <= 2.0 * self.rtol:
                break
            sq = np.sqrt(q)
            mu = mu + 2.0 * q * (1.0 - sq / np.sqrt(kk2)) / dq
        else:
            raise RuntimeError("von Mises projection: secular equation did not converge")
        factor = 1.0 / (1.0 + mu[:, None] * self.lam[None, :])
        # kappa = 0: mu -> infinity keeps only the directions with lam = 0 (none in plane stress).
        factor[zero] = (self.lam[None, :] == 0.0).astype(float)
        if every:
            out = ((z * factor) @ self.V.T) * c[:, None]
        else:
            out[outside] = ((z * factor) @ self.V.T) * c[:, None]
        return out


class CellProjection:
    """VonMisesProjection's exact projection for E per cell (CellElasticity), batched: the
    Cholesky factor and eigenbasis (V, lam) of each distinct matrix are computed once, and
    the secular equation is solved for all rows at once with each row's lam (no grouping
    of equal eigenvalues; the same Newton iteration from the same lower bound).  The
    projection changes with the shape of E (anisotropy; nu(x) in plane stress, not for an
    isotropic 3D E), not with a factor on E: P is invariant under scaling A.  The rows are
    the elasticity's selected ones (CellElasticity.rows).

    Args:
        elasticity: the CellElasticity.
        rtol: relative tolerance of the secular equation.
        max_iter: Newton iterations allowed.
    """

    def __init__(self, elasticity: CellElasticity, rtol: float = 1e-14, max_iter: int = 100):
        self.elasticity = elasticity
        self.m = elasticity.m
        A = elasticity.weights[None, :, None] * elasticity.mats
        M = elasticity.M
        Linv = np.linalg.inv(np.linalg.cholesky(A))
        lam, W = np.linalg.eigh(Linv @ M @ Linv.transpose(0, 2, 1))
        top = lam.max(axis=1, keepdims=True)
        self.lam = np.where(lam > 1e-12 * top, lam, 0.0)       # M may be singular (3D)
        self.V = Linv.transpose(0, 2, 1) @ W
        self.AV = A @ self.V                                  # z = s @ AV per matrix
        self.rtol, self.max_iter = rtol, max_iter

    def __call__(self, s: np.ndarray, kappa: np.ndarray) -> np.ndarray:
        """Project onto K(kappa), row by row with each selected cell's E.

        Args:
            s: rows (n, m) of t-coordinates, one per selected row of the elasticity.
            kappa: (n,) radii >= 0 (or a scalar).

        Returns:
            The rows (n, m) of P_K(kappa) s; NaN rows for non-finite input.

        Raises:
            RuntimeError: if the secular equation does not converge.
            ValueError: if the rows are not the selected cells.
        """
        s = np.asarray(s, dtype=float).reshape(-1, self.m)
        g = self.elasticity.index[self.elasticity.selected]
        if len(g) != s.shape[0]:
            raise ValueError(f"per-cell projection: {s.shape[0]} rows for {len(g)} "
                             "selected cells")
        kappa = np.broadcast_to(np.asarray(kappa, dtype=float), (s.shape[0],))
        out = s.copy()
        vm2 = np.einsum("ni,ni->n", s @ self.elasticity.M, s)
        bad = ~(np.isfinite(vm2) & np.isfinite(kappa))
        out[bad] = np.nan
        huge = np.flatnonzero(bad & np.isfinite(s).all(axis=1) & np.isfinite(kappa))
        if len(huge):                          # |s|^2 overflowed: project the scaled rows
            c = np.abs(s[huge]).max(axis=1)
            with self.elasticity.rows(huge):
                out[huge] = self(s[huge] / c[:, None], kappa[huge] / c) * c[:, None]
        with np.errstate(invalid="ignore", over="ignore"):
            outside = np.flatnonzero((vm2 > kappa * kappa) & ~bad)
        if len(outside) == 0:
            return out
        gi = g[outside]
        c = np.sqrt(vm2[outside])                      # P is positively homogeneous
        z = np.einsum("ni,nij->nj", s[outside], self.AV[gi]) / c[:, None]
        k = kappa[outside] / c
        zero = k <= 1e-150
        mu, lam = self._secular(z, np.where(zero, 1.0, k * k), self.lam[gi], zero)
        factor = 1.0 / (1.0 + mu[:, None] * lam)
        factor[zero] = (lam[zero] == 0.0).astype(float)
        out[outside] = np.einsum("nij,nj->ni", self.V[gi], z * factor) * c[:, None]
        return out

    def _secular(self, z, kk2, lam, zero):
        """The root mu >= 0 of q(mu) = kappa^2 per row (VonMisesProjection's Newton
        iteration on 1/sqrt(q) - 1/kappa, from the lower bound of the root)."""
        w = lam * z * z
        lam_max = lam.max(axis=1)
        mu = np.where(lam_max > 0, np.maximum(
            (np.sqrt(w.sum(axis=1) / kk2) - 1.0) / np.where(lam_max > 0, lam_max, 1.0), 0.0),
            0.0)
        for _ in range(self.max_iter):
            r = 1.0 / (1.0 + mu[:, None] * lam)
            t = w * r * r
            q = t.sum(axis=1)
            dq = -(2.0 * lam * t * r).sum(axis=1)
            res = np.abs(1.0 - q / kk2)
            if np.where(zero, 0.0, res).max(initial=0.0) <= 2.0 * self.rtol:
                return mu, lam
            mu = mu + 2.0 * q * (1.0 - np.sqrt(q) / np.sqrt(kk2)) / dq
        raise RuntimeError("von Mises projection: secular equation did not converge")
