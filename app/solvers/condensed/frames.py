"""The coordinates of the condensed Gamma3 problem: global where every Gamma3 node has the
same axis-aligned normal and no rotated frame (the paper's flat bottom), else the nodal frames
of app/model/frames.py with the normal first (T_i = (nu_i, the tangents), y = T y_w).  In
them the non-penetration condition u_nu <= g_i of (3.4) is a bound on one dof per node.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vpcontact.io.errors import CaseError


@dataclass
class WorkFrames:
    """The Gamma3 problem's coordinates, bounds and prescribed components, in G order.

    Attributes:
        T: the nodal frames T_i (n, d, d), or None in the global coordinates.
        fixed: the prescribed components (m,) (their values are set per step).
        lb, ub: the bounds (n, d): u_nu <= g_i, infinite elsewhere.
        normal: the normal in these coordinates (NodalContact's nu).
    """
    T: np.ndarray | None
    fixed: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    normal: np.ndarray

    def to_work(self, y: np.ndarray) -> np.ndarray:
        """Gamma3 values in the problem's coordinates: y_w = T^T y.

        Args:
            y: values in the global coordinates (m,).

        Returns:
            y_w (y itself in the global coordinates).
        """
        if self.T is None:
            return y
        return np.einsum("iab,ia->ib", self.T, y.reshape(-1, self.T.shape[1])).ravel()

    def from_work(self, y_w: np.ndarray) -> np.ndarray:
        """Back to the global coordinates: y = T y_w.

        Args:
            y_w: values in the problem's coordinates (m,).

        Returns:
            y (y_w itself in the global coordinates).
        """
        if self.T is None:
            return y_w
        return np.einsum("iab,ib->ia", self.T, y_w.reshape(-1, self.T.shape[1])).ravel()

    def work_matrix(self, S: np.ndarray) -> np.ndarray:
        """S in the problem's coordinates: S_w = T^T S T.

        Args:
            S: the Schur complement in the global coordinates (m, m).

        Returns:
            S_w (S itself in the global coordinates).
        """
        if self.T is None:
            return S
        n, d = self.T.shape[:2]
        return np.einsum("ica,icjb,jbe->iaje", self.T, S.reshape(n, d, n, d),
                         self.T).reshape(n * d, n * d)


def normal_first(fr, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The nodal frames with the normal first, T_i = (nu_i, the tangents): the columns of
    Q_i in the order (slot, the others ascending), the slot's times sign_i.

    Args:
        fr: the ContactFrames (app/model/frames.py).
        pos: the nodes' positions in ``fr.nodes``.

    Returns:
        (T (n, d, d), the column order (n, d)).
    """
    Q, slot, sign = fr.Q[pos], fr.slot[pos], fr.sign[pos]
    d = Q.shape[1]
    order = np.argsort(np.arange(d)[None, :] != slot[:, None], axis=1, kind="stable")
    T = np.take_along_axis(Q, order[:, None, :], axis=2)
    T[:, :, 0] *= sign[:, None]                   # T_i = (nu_i, the tangents)
    return T, order


def work_frames(disc, layout) -> WorkFrames:
    """The coordinates of the Gamma3 problem, from the nodal frames (collective).

    Args:
        disc: the Discretisation (frames, Gamma3 nodes, Dirichlet data).
        layout: the Gamma3Layout.

    Returns:
        The WorkFrames.

    Raises:
        CaseError: a Gamma3 node has prescribed components and a normal that lies in them
            without being an axis.
    """
    d = disc.dim
    fr, n = disc.frames, len(layout.g_nodes)
    pos = np.searchsorted(fr.nodes, disc.gamma3.nodes)
    Q, slot, sign = fr.Q[pos], fr.slot[pos], fr.sign[pos]
    T, order = normal_first(fr, pos)
    axis = np.abs(Q).max(axis=1) == 1.0            # (nodes, d): column is +-e_a
    col_axis = np.argmax(np.abs(Q), axis=1)
    fixed_nodes = disc.dirichlet.fixed[disc.gamma3.nodes]
    fixedQ = axis & np.take_along_axis(fixed_nodes, col_axis, axis=1)
    if (fixedQ.sum(axis=1) != fixed_nodes.sum(axis=1)).any():
        raise CaseError(f"{disc.case.source}: solver.method: the condensed solver cannot hold the "
                        "prescribed components of a Gamma3 node whose normal lies in them "
                        "and is not an axis (allowed here: snes_vi)")
    fixedT = np.take_along_axis(fixedQ, order, axis=1)
    g = fr.g[pos] if fr.g is not None else np.full(len(pos), np.inf)
    g = np.where(fr.bounded[pos], g, np.inf)
    place, on_all = layout.local_owned_g, layout.place_on_all
    T = on_all(place, T, (n, d, d))
    g = on_all(place, g, n)
    nu0 = on_all(place, sign[:, None] * np.eye(d)[slot], (n, d))
    uniform = not fr.rotated and (len(nu0) == 0 or (nu0 == nu0[0]).all())
    fixed = on_all(place, fixedQ if uniform else fixedT, (n, d), dtype=bool).ravel()
    lb, ub = np.full((n, d), -np.inf), np.full((n, d), np.inf)
    if not uniform:
        ub[:, 0] = g
        return WorkFrames(T, fixed, lb, ub, np.eye(d)[0])
    normal = nu0[0] if n else np.eye(d)[0]
    comp = int(np.argmax(np.abs(normal)))
    (ub[:, comp], lb[:, comp]) = (g, -np.inf) if normal[comp] > 0 else (np.inf, -g)
    return WorkFrames(None, fixed, lb, ub, normal)
