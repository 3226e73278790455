"""The cell-strain operator of P1 displacements cell by cell (cells.c), and its numpy
reference.

Per cell c with vertices nodes[c] (local node numbers: dofs node * d + k) and
G[c, a] = |c| grad phi_a of its d + 1 vertex functions, (D u)_c = |c| eps_c(u) =
sym(sum_a u_a (x) G_a) (app/model/strain.py).  ``cell_pass`` gives eps, sigma = E eps + H (3.2),
its von Mises norm and the squared norms ||u||_V^2 = ||eps(u)||^2 and ||sigma||_Q^2;
``cell_load`` the pre-stress load D^T H = (H, eps(v)) of (3.4).  The ``_numpy`` functions
compute the same in numpy (the tests' reference).
"""
from __future__ import annotations

import numpy as np

from vpcontact.kernels.build import buf

# cells from which two threads share a pass over the cells (cell_pass, the Perzyna update):
# the cells are independent; below it the threads gain next to nothing (docs/performance.md,
# sections 7 and 9)
SPLIT_MIN_CELLS = 10000


def split_threads(threads: int, ncells: int) -> int:
    """The threads a pass over ``ncells`` cells runs on: 2 if ``threads`` allows two and
    there are SPLIT_MIN_CELLS cells, else 1.

    Args:
        threads: the threads the caller may use.
        ncells: the cells of the pass.

    Returns:
        1 or 2.
    """
    return 2 if threads >= 2 and ncells >= SPLIT_MIN_CELLS else 1


def cell_pass(module, nodes, G, vol, lmbda, two_mu, u, H=None, sigma=None,
              vm=None, threads: int = 1) -> tuple[float, float]:
    """The C cell_pass over the cells of ``nodes``.

    Args:
        module: the compiled kernels (kernels.load()).
        nodes: the vertices of each cell, intc (ncells, d + 1).
        G: |c| grad phi_a per cell, float64 (ncells, d + 1, d).
        vol: the cell volumes |c| (ncells).
        lmbda: Lame's lambda of E (plane stress in 2D: the effective one).
        two_mu: 2 mu of E.
        u: the displacement dofs (node * d + k), flat.
        H: the history tensor per cell, flat (ncells * d * d), or None (0).
        sigma: where sigma = E eps(u) + H goes (ncells * d * d), or None (not computed).
        vm: where ||sigma||_VM goes (ncells); required with sigma.
        threads: 2 splits the cells between two threads from SPLIT_MIN_CELLS cells (the
            same sigma; the sums added in another order).

    Returns:
        (sum_c |c| eps_c : eps_c, sum_c |c| sigma_c : sigma_c (0 without sigma)).
    """
    if sigma is not None and vm is None:
        raise ValueError("cell_pass: sigma needs vm")
    ffi = module.ffi
    ss = ffi.new("double *")
    d = G.shape[-1]
    e2 = module.lib.cell_pass(len(nodes), d, buf(ffi, nodes), buf(ffi, G), buf(ffi, vol),
                              lmbda, two_mu, buf(ffi, u), buf(ffi, H), buf(ffi, sigma),
                              buf(ffi, vm), ss, split_threads(threads, len(nodes)))
    return e2, ss[0]


def cell_pass_numpy(nodes, G, vol, lmbda, two_mu, u, H=None, sigma=None,
                    vm=None) -> tuple[float, float]:
    """``cell_pass`` in numpy (the reference); same arguments except ``module``.

    Args:
        nodes, G, vol, lmbda, two_mu, u, H, sigma, vm: as for ``cell_pass``.

    Returns:
        (sum_c |c| eps_c : eps_c, sum_c |c| sigma_c : sigma_c (0 without sigma)).
    """
    d = G.shape[-1]
    ua = np.asarray(u).reshape(-1, d)[nodes]                       # (ncells, d + 1, d)
    gu = np.einsum("cak,caj->ckj", ua, G)
    e = 0.5 * (gu + gu.transpose(0, 2, 1)) / vol[:, None, None]
    e2 = float(vol @ np.einsum("cij,cij->c", e, e))
    if sigma is None:
        return e2, 0.0
    s = two_mu * e + (0.0 if H is None else np.asarray(H).reshape(-1, d, d))
    s = s + lmbda * np.trace(e, axis1=1, axis2=2)[:, None, None] * np.eye(d)
    s2 = np.einsum("cij,cij->c", s, s)
    trs = np.trace(s, axis1=1, axis2=2)
    sigma[:] = s.reshape(-1)
    vm[:] = np.sqrt(np.maximum(1.5 * s2 - 0.5 * trs**2, 0.0))
    return e2, float(vol @ s2)


def cell_load(module, nodes, G, H, b) -> None:
    """The C cell_load: b[dofs of c] += D_c^T H_c for every cell.

    Args:
        module: the compiled kernels (kernels.load()).
        nodes: the vertices of each cell, intc (ncells, d + 1).
        G: |c| grad phi_a per cell, float64 (ncells, d + 1, d).
        H: the tensor per cell, flat (ncells * d * d).
        b: the dof vector (node * d + k), added to.
    """
    ffi = module.ffi
    module.lib.cell_load(len(nodes), G.shape[-1], buf(ffi, nodes), buf(ffi, G), buf(ffi, H),
                         buf(ffi, b))


def cell_load_numpy(nodes, G, H, b) -> None:
    """``cell_load`` in numpy (the reference): (D_c^T H_c)_ak = sum_j G_aj (H_kj + H_jk) / 2.

    Args:
        nodes, G, H, b: as for ``cell_load`` (b is added to).
    """
    d = G.shape[-1]
    Hc = np.asarray(H).reshape(-1, d, d)
    Hs = 0.5 * (Hc + Hc.transpose(0, 2, 1))
    contrib = np.einsum("caj,ckj->cak", G, Hs)                   # (ncells, d + 1, d)
    np.add.at(b.reshape(-1, d), nodes, contrib)
