"""The elasticity data of ``material.elasticity`` as given (hypothesis H(E)): orthotropic
engineering constants with material axes, or a Voigt matrix; their matrices and their rules.
Numpy only: the case layer refuses bad data (exit 2) with them and the model builds E from
them (app/model/stiffness.py).

Matrices in t-coordinates: (E tau)_t = C t(tau), t in the case file's Voigt order (11, 22,
12) in 2D, (11, 22, 33, 23, 13, 12) in 3D (app/model/material.py).  A Voigt matrix D of the
case file acts on engineering strains (shears 2 eps_ij): C = D diag(1, .., 2, ..).

Orthotropic: in the material axes a1, a2, a3 (a3 = a1 x a2 in 3D; in 2D a2 is a1 turned by
+90 degrees and a3 = z) the compliance in engineering Voigt order is
    S = [[1/E1, -nu12/E1, -nu13/E1], [-nu12/E1, 1/E2, -nu23/E2], [-nu13/E1, -nu23/E2, 1/E3]]
on the normal block and diag(1/G23, 1/G13, 1/G12) on the shears (nu_ij = -eps_j / eps_i
under a uniaxial stress along a_i; nu21 = nu12 E2/E1).  In 2D plane stress takes the
in-plane block of S (E: [E1, E2], nu: [nu12], G: [G12] suffice), D = S_p^-1 with p = (11,
22, 12); plane strain needs the 3D data (E: [E1, E2, E3], nu: [nu12, nu13, nu23], G: [G12,
G13, G23]) and takes D = (S^-1)_pp, the inverse of the reduced compliance S_pp - S_p3 S_3p /
S_33 (eps_33 = 0).  The matrix in the global axes is T^-1 C_local T, T the change of
t-coordinates to the material axes.  The axes must be nonzero and orthogonal (|cos| <= 1e-8;
refused otherwise: a silent orthonormalisation would change the material the user meant);
their lengths do not matter.
"""
from __future__ import annotations

import numpy as np

# the Voigt order of the case file: (row, col) of each coordinate
VOIGT_ORDER = {2: [(0, 0), (1, 1), (0, 1)],
               3: [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]}
_PLANE = [0, 1, 5]                     # (11, 22, 12) in the 3D order


def weights(dim: int) -> np.ndarray:
    """The Frobenius weights of the coordinates (2 on the shears).

    Args:
        dim: space dimension d.

    Returns:
        (m,) weights.
    """
    return np.array([1.0 if i == j else 2.0 for i, j in VOIGT_ORDER[dim]])


def voigt_matrix(D, dim: int) -> np.ndarray:
    """C in t-coordinates from a Voigt matrix on engineering strains.

    Args:
        D: the (m, m) matrix: stresses from engineering strains, the case file's order.
        dim: space dimension d.

    Returns:
        C = D diag(weights).
    """
    return np.asarray(D, dtype=float) * weights(dim)[None, :]


def material_axes(axes, dim: int) -> np.ndarray:
    """The rotation R whose rows are the unit material axes.

    Args:
        axes: [a1] in 2D, [a1, a2] in 3D.
        dim: space dimension d.

    Returns:
        R (d x d), orthogonal with det 1.

    Raises:
        ValueError: an axis is zero or the axes are not orthogonal (|cos| > 1e-8).
    """
    a = [np.asarray(v, dtype=float) for v in axes]
    if len(a) != dim - 1 or any(v.shape != (dim,) for v in a):
        raise ValueError(f"{'[a1]' if dim == 2 else '[a1, a2]'} expected: {dim - 1} "
                         f"vector(s) of {dim} components")
    norms = [float(np.linalg.norm(v)) for v in a]
    if not all(np.isfinite(norms)) or min(norms) == 0.0:
        raise ValueError("an axis is zero (or not finite)")
    a = [v / n for v, n in zip(a, norms)]
    if dim == 2:
        return np.array([a[0], [-a[0][1], a[0][0]]])
    cos = float(a[0] @ a[1])
    if abs(cos) > 1e-8:
        raise ValueError(f"a1 and a2 are not orthogonal (cos = {cos:.3g})")
    a2 = a[1] - cos * a[0]
    a2 /= np.linalg.norm(a2)
    return np.array([a[0], a2, np.cross(a[0], a2)])


def rotation_matrix(R: np.ndarray) -> np.ndarray:
    """T: t(R tau R^T) = T t(tau), the t-coordinates of tau in the axes of R's rows.

    Args:
        R: d x d orthogonal, rows the new axes.

    Returns:
        T (m x m).
    """
    pairs = VOIGT_ORDER[R.shape[0]]
    T = np.empty((len(pairs), len(pairs)))
    for k, (i, j) in enumerate(pairs):
        tau = np.zeros(R.shape)
        tau[i, j] = tau[j, i] = 1.0
        rotated = R @ tau @ R.T
        T[:, k] = [rotated[p, q] for p, q in pairs]
    return T


def orthotropic_compliance(E, nu, G) -> np.ndarray:
    """S (engineering Voigt order) in the material axes: 6 x 6 from the 3D data, or the
    in-plane block (11, 22, 12) from E1, E2, nu12, G12.

    Args:
        E: [E1, E2, E3] or [E1, E2].
        nu: [nu12, nu13, nu23] or [nu12].
        G: [G12, G13, G23] or [G12].

    Returns:
        S (6 x 6 or 3 x 3).
    """
    if len(E) == 2:
        (E1, E2), n12, G12 = E, nu[0], G[0]
        return np.array([[1 / E1, -n12 / E1, 0.0], [-n12 / E1, 1 / E2, 0.0],
                         [0.0, 0.0, 1 / G12]])
    (E1, E2, E3), (n12, n13, n23), (G12, G13, G23) = E, nu, G
    S = np.zeros((6, 6))
    S[:3, :3] = [[1 / E1, -n12 / E1, -n13 / E1], [-n12 / E1, 1 / E2, -n23 / E2],
                 [-n13 / E1, -n23 / E2, 1 / E3]]
    S[3:, 3:] = np.diag([1 / G23, 1 / G13, 1 / G12])
    return S


def orthotropic_matrix(data: dict, dim: int, plane: str | None = "stress") -> np.ndarray:
    """C of ``material.elasticity.orthotropic`` in the global axes (module docstring).

    Args:
        data: the section: E, nu, G lists and axes.
        dim: space dimension d.
        plane: in 2D "stress" or "strain".

    Returns:
        C (m x m) in t-coordinates.

    Raises:
        ValueError: a message starting with the offending key (E, nu, G, axes): wrong
            lengths, a modulus <= 0, plane strain with 2D data, a compliance that is not
            positive definite, bad axes.
    """
    E, nu, G = (list(map(float, data[k])) for k in ("E", "nu", "G"))
    sizes = ((3, 3, 3),) if dim == 3 else ((2, 1, 1), (3, 3, 3))
    if (len(E), len(nu), len(G)) not in sizes:
        raise ValueError("E, nu, G: " + (" or ".join(
            f"{a}, {b}, {c} entries" for a, b, c in sizes)) + f" in {dim}D")
    if min(E) <= 0 or min(G) <= 0:
        raise ValueError("E, G: the moduli must be > 0")
    if dim == 2 and len(E) == 2 and plane == "strain":
        raise ValueError("E: plane strain needs the 3D data (E: [E1, E2, E3], nu: [nu12, "
                         "nu13, nu23], G: [G12, G13, G23])")
    S = orthotropic_compliance(E, nu, G)
    if np.linalg.eigvalsh(S).min() <= 0:
        raise ValueError("nu: the compliance is not positive definite (Poisson's ratios "
                         "too large for the moduli)")
    try:
        R = material_axes(data["axes"], dim)
    except ValueError as e:
        raise ValueError(f"axes: {e}") from None
    if dim == 3 or len(S) == 3:
        D = np.linalg.inv(S)
    elif plane == "strain":
        D = np.linalg.inv(S)[np.ix_(_PLANE, _PLANE)]
    else:
        D = np.linalg.inv(S[np.ix_(_PLANE, _PLANE)])
    T = rotation_matrix(R)
    return np.linalg.solve(T, voigt_matrix(0.5 * (D + D.T), dim) @ T)


def out_of_plane_row(data: dict) -> np.ndarray:
    """Plane strain with orthotropic 3D data: the row r of sigma_33 = r . t(sigma) at eps_33
    = 0 (t the in-plane t-coordinates (11, 22, 12) in the global axes).  With C3 = S^-1
    (engineering Voigt order) sigma_33 = C3[33, p] e_p and e_p = (C3[p, p])^-1 sigma_p in
    the material axes (p = (11, 22, 12), e engineering strains); the stress coordinates
    there are T t(sigma) (T of ``rotation_matrix``), so r = C3[33, p] (C3[p, p])^-1 T.

    Args:
        data: the ``orthotropic`` section with 3D data (E, nu, G of 3 entries) and axes.

    Returns:
        r (3,).
    """
    E, nu, G = (list(map(float, data[k])) for k in ("E", "nu", "G"))
    C3 = np.linalg.inv(orthotropic_compliance(E, nu, G))
    local = np.linalg.solve(C3[np.ix_(_PLANE, _PLANE)].T, C3[2, _PLANE])
    return local @ rotation_matrix(material_axes(data["axes"], 2))


def energy_minimum(C: np.ndarray, dim: int) -> float:
    """m_E: the smallest eigenvalue of E on symmetric tensors in the Frobenius inner
    product (the generalised eigenvalues of A = diag(w) C against diag(w)).

    Args:
        C: (m, m) or (n, m, m) matrices in t-coordinates.
        dim: space dimension d.

    Returns:
        m_E (<= 0: not positive definite).

    Raises:
        ValueError: A = diag(w) C is not symmetric (relative 1e-12).
    """
    w = weights(dim)
    A = w[:, None] * np.asarray(C, dtype=float)
    At = np.swapaxes(A, -1, -2)
    if np.abs(A - At).max() > 1e-12 * np.abs(A).max():
        raise ValueError("not symmetric")
    s = 1.0 / np.sqrt(w)
    return float(np.linalg.eigvalsh(0.5 * (A + At) * s[:, None] * s[None, :]).min())


def elasticity_matrix(spec: dict, dim: int, plane: str | None = "stress") -> np.ndarray:
    """C of a ``material.elasticity`` section, checked.

    Args:
        spec: {"orthotropic": {...}} or {"voigt": [[...]]} (the other key absent or None).
        dim: space dimension d.
        plane: in 2D "stress" or "strain" (orthotropic only; a Voigt matrix in 2D is the
            in-plane law itself).

    Returns:
        C (m x m) in t-coordinates.

    Raises:
        ValueError: a message starting with the key path below ``material.elasticity``.
    """
    if spec.get("orthotropic") is not None:
        try:
            return orthotropic_matrix(spec["orthotropic"], dim, plane)
        except ValueError as e:
            raise ValueError(f"orthotropic.{e}") from None
    m = len(VOIGT_ORDER[dim])
    D = np.asarray(spec["voigt"], dtype=float)
    if D.shape != (m, m) or not np.isfinite(D).all():
        raise ValueError(f"voigt: a {m} x {m} matrix of numbers expected in {dim}D "
                         f"(order {', '.join(f'{i + 1}{j + 1}' for i, j in VOIGT_ORDER[dim])})")
    if np.abs(D - D.T).max() > 1e-12 * np.abs(D).max():
        raise ValueError("voigt: not symmetric")
    C = voigt_matrix(D, dim)
    if energy_minimum(C, dim) <= 0:
        raise ValueError("voigt: not positive definite")
    return C


def check_material_elasticity(material: dict, dim: int) -> None:
    """The rules of a material section's elasticity as given: E and nu (isotropic), or
    ``elasticity`` with exactly one of orthotropic and voigt, whose matrix is symmetric
    positive definite (values of E, nu expressions are checked at the sample points and
    per cell on the mesh).

    Args:
        material: the section (after the schema's check).
        dim: space dimension d.

    Raises:
        ValueError: a message starting with the offending key path (material...).
    """
    spec = material.get("elasticity")
    iso = [k for k in ("E", "nu") if k in material]
    if spec is None:
        if len(iso) < 2:
            missing = " and ".join(k for k in ("E", "nu") if k not in material)
            raise ValueError(f"material: {missing} required (or elasticity: orthotropic or "
                             "voigt, instead of E and nu)")
        return
    if iso:
        raise ValueError(f"material.elasticity: instead of E and nu; give either (found "
                         f"{' and '.join(iso)})")
    kinds = [k for k in ("orthotropic", "voigt") if k in spec]
    if len(kinds) != 1:
        raise ValueError("material.elasticity: give exactly one of orthotropic and voigt")
    try:
        elasticity_matrix(spec, dim, material.get("plane", "stress"))
    except ValueError as e:
        raise ValueError(f"material.elasticity.{e}") from None


def largest_modulus(C: np.ndarray, dim: int) -> float:
    """M_E: the largest eigenvalue of E on symmetric tensors (a stress scale per strain).

    Args:
        C: (m, m) matrix in t-coordinates (A = diag(w) C symmetric).
        dim: space dimension d.

    Returns:
        M_E.
    """
    s = np.sqrt(weights(dim))
    A = weights(dim)[:, None] * np.asarray(C, dtype=float)
    return float(np.linalg.eigvalsh(0.5 * (A + A.T) / s[:, None] / s[None, :]).max())
