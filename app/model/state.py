"""The state of scheme (3.2)-(3.4): u_n, sigma_n, H_n, kappa_n in R^m and, on Gamma3, xi_n
and s_n, as the live fields a step reads and writes and a committed copy.

During step n the live fields are the trial state: the explicit history update writes H_n,
kappa_n (3.2)-(3.3), the step solve u_n (3.4), the stress update sigma_n (3.2) (the implicit
variant writes sigma at every residual and H_n, kappa_n at the converged u_n).  ``commit()``
keeps a copy of the live state after a converged step and ``restore()`` puts it back (the
adaptive step control's rollback); a run that never rolls back keeps no copy.  Checkpoints
write and read the state through ``fields()`` and the Gamma3 history's ``state()`` /
``load_state()`` (app/io/checkpoint.py), after the fenics-constitutive pattern of a problem
holding committed and trial history.
"""
from __future__ import annotations

import numpy as np
from dolfinx import fem

from vpcontact.model.material import FROM


def kappa_function(Y, m: int) -> fem.Function:
    """The internal variables kappa in R^m per cell: a DG0 scalar Function for m = 1 (the
    paper's Perzyna law), else DG0 with m components.

    Args:
        Y: the DG0 scalar space Y^h.
        m: the law's number of internal variables.

    Returns:
        The Function "kappa" (zero).
    """
    space = Y if m == 1 else fem.VectorFunctionSpace(Y.mesh, ("DG", 0), dim=m)
    return fem.Function(space, name="kappa")


class KappaOutput:
    """The internal variables kappa as the fields solution.xdmf writes, each a DG0 field
    that XDMF stores per cell (dolfinx 0.5 writes a DG0 Function per cell only if it is a
    scalar, a d-vector or a d x d tensor): kappa itself for m = 1; for a law that names its
    variables (its ``fields``: (name, components) in kappa's order) one Function each, a
    scalar for 1 component, and for 6 the symmetric 3 x 3 tensor in the 3D t-order (11, 22,
    33, 23, 13, 12) of app/model/material.py (Chaboche's back stress X): in 3D the tensor
    itself, in 2D its in-plane d x d tensor ``X`` and its out-of-plane ``X_33`` (X_13 = X_23
    = 0 there); otherwise (m > 1, no names) one scalar kappa_i per component.

    Cells whose law has not a component (an elastic material, or a material whose law has
    fewer than m variables, app/model/materials.py) carry NaN in it: ParaView shows them as
    absent.

    Args:
        kappa: the State's kappa Function (DG0, m components).
        layout: the law's ``fields``, or None.
        present: (rows, m) booleans, which rows have which components (None: all).

    Attributes:
        functions: the Functions to write.
    """

    def __init__(self, kappa: fem.Function, layout=None, present=None):
        self.kappa, self.parts, self.present = kappa, [], present
        bs = kappa.function_space.dofmap.index_map_bs
        if layout is None and bs == 1 and present is None:
            self.functions = [kappa]
            return
        mesh = kappa.function_space.mesh
        d = mesh.topology.dim
        scalar = fem.FunctionSpace(mesh, ("DG", 0))
        tensor = fem.TensorFunctionSpace(mesh, ("DG", 0))
        start = 0
        names = [("kappa", 1)] if bs == 1 else [(f"kappa_{i}", 1) for i in range(bs)]
        for name, size in layout or names:
            if size == 1:
                self.parts.append((fem.Function(scalar, name=name), [start]))
            else:                              # the 3D t-coordinates of a symmetric tensor
                t3 = start + np.arange(6)
                rows = t3[FROM[3]] if d == 3 else t3[[0, 5, 5, 1]]
                self.parts.append((fem.Function(tensor, name=name), list(rows)))
                if d == 2:
                    self.parts.append((fem.Function(scalar, name=f"{name}_33"), [start + 2]))
            start += size
        self.functions = [f for f, _ in self.parts]

    def update(self) -> None:
        """Copy kappa's components into the named Functions (owned and ghost cells)."""
        if not self.parts:
            return
        bs = self.kappa.function_space.dofmap.index_map_bs
        cells = self.kappa.x.array.reshape(-1, bs)
        if self.present is not None:
            cells = np.where(self.present, cells, np.nan)
        for f, columns in self.parts:
            f.x.array[:] = cells[:, columns].reshape(-1)


class State:
    """u_n (P1), sigma_n and its von Mises norm, H_n (DG0 tensors), kappa_n (DG0, m
    components) and the Gamma3 history (xi_n, s_n), live and committed.

    Args:
        V: the P1 vector space V^h.
        Q: the DG0 tensor space Q^h.
        Y: the DG0 scalar space Y^h.
        has_H: whether the scheme has the pre-stress H_n (a viscoplastic law or initial
            values).
        m: the law's number of internal variables, or None without a viscoplastic law.
        rollback: keep a committed copy (adaptive steps); else ``commit`` copies nothing.
        sigma_33: whether sigma has an out-of-plane component (2D plane strain).

    Attributes:
        u, sigma, sigma_vm, H, kappa: the live Functions (H, kappa None when absent).
        sigma_33: the out-of-plane stress per cell in 2D plane strain (DG0 scalar,
            app/model/fullstress.py; derived from sigma and kappa like sigma_vm), else None.
        m: the number of internal variables (None without a law).
        gamma3: the Gamma3 history (app/model/gamma3.py: xi_n, s_n), or None; set by
            ``attach_gamma3``.
        committed: the committed copy (None before the first ``commit`` or without
            rollback).
    """

    def __init__(self, V, Q, Y, has_H: bool, m: int | None, rollback: bool = False,
                 sigma_33: bool = False):
        self.u = fem.Function(V, name="u")
        self.sigma = fem.Function(Q, name="sigma")
        self.sigma_vm = fem.Function(Y, name="sigma_vm")
        self.sigma_33 = fem.Function(Y, name="sigma_33") if sigma_33 else None
        self.H = fem.Function(Q, name="H") if has_H else None
        self.m = m
        self.kappa = kappa_function(Y, m) if m is not None else None
        self.gamma3 = None
        self.rollback = rollback
        self.committed = None

    def attach_gamma3(self, history) -> None:
        """Make the Gamma3 history (xi_n, s_n) part of the state.

        Args:
            history: a Gamma3History, or None.
        """
        self.gamma3 = history

    @property
    def kappa_cells(self) -> np.ndarray | None:
        """kappa per local cell as a (cells, m) view of the live Function (None without a
        law)."""
        return None if self.kappa is None else self.kappa.x.array.reshape(-1, self.m)

    @property
    def xi(self) -> np.ndarray | None:
        """xi_n at the local Gamma3 nodes (None without the memory term)."""
        g3 = self.gamma3
        return g3.memory.xi if g3 is not None and g3.memory is not None else None

    @property
    def s(self) -> np.ndarray | None:
        """s_n at the local Gamma3 nodes (None without slip dependence)."""
        g3 = self.gamma3
        return g3.slip.s if g3 is not None and g3.slip is not None else None

    def fields(self) -> dict[str, fem.Function]:
        """The cell and node fields of the state, in the checkpoint's order.

        Returns:
            {"u", "sigma"(, "H")(, "kappa")} -> Function.
        """
        out = {"u": self.u, "sigma": self.sigma}
        if self.H is not None:
            out["H"] = self.H
        if self.kappa is not None:
            out["kappa"] = self.kappa
        return out

    def snapshot(self) -> dict:
        """A copy of the live state (local arrays, owned and ghost entries).

        Returns:
            {"fields": {name: array}, "gamma3": the Gamma3 history's state() or None}.
        """
        return {"fields": {k: f.x.array.copy() for k, f in self.fields().items()},
                "gamma3": self.gamma3.state() if self.gamma3 is not None else None}

    def load(self, snapshot: dict) -> None:
        """Set the live state from ``snapshot()`` of the same run.

        Args:
            snapshot: as returned by ``snapshot()``.
        """
        for name, f in self.fields().items():
            f.x.array[:] = snapshot["fields"][name]
        if self.gamma3 is not None:
            self.gamma3.load_state(snapshot["gamma3"])

    def commit(self) -> None:
        """Trial -> committed, after a converged step (a copy only with ``rollback``)."""
        if self.rollback:
            self.committed = self.snapshot()

    def restore(self) -> None:
        """Committed -> trial: undo a step (``commit`` must have been called)."""
        self.load(self.committed)
