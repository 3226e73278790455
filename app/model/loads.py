"""Time- and space-dependent data of a case as UFL: loads f0(t), f2(t), initial values.

A component of a load vector is one of
- a number (constant in time and space);
- {"table": [[t0, v0], [t1, v1], ...]}: piecewise linear in t (constant beyond the ends);
- an expression string in t, x, y, z (app/case/expressions.py).
Time enters through dolfinx Constants updated by ``set_time`` at every step, so the compiled
forms do not change with t.
"""
from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from vpcontact.case import expressions


def is_zero(component) -> bool:
    """Whether a load component is the number 0.

    Args:
        component: a number, table or expression string.

    Returns:
        True for the number 0 (a table or expression never counts as zero).
    """
    return isinstance(component, (int, float)) and component == 0


class TimeData:
    """Builds UFL for case data and keeps the time-dependent Constants up to date.

    Args:
        mesh: the dolfinx mesh (its coordinates are x, y, z).

    Attributes:
        t: the time Constant.
        symbols: t, x, y, z as UFL, for expressions.
    """

    def __init__(self, mesh):
        self.mesh = mesh
        self.t = fem.Constant(mesh, PETSc.ScalarType(0.0))
        self._tables: list[tuple[fem.Constant, np.ndarray, np.ndarray]] = []
        x = ufl.SpatialCoordinate(mesh)
        self.symbols = {"t": self.t, "x": x[0], "y": x[1],
                        "z": x[2] if mesh.geometry.dim == 3 else 0.0}

    def scalar(self, component):
        """UFL for one component.

        Args:
            component: a number, {"table": [[t, value], ...]} or an expression string.

        Returns:
            A Constant (number, table) or a UFL expression.
        """
        if isinstance(component, (int, float)):   # a Constant: no recompilation per value
            return fem.Constant(self.mesh, PETSc.ScalarType(component))
        if isinstance(component, dict):
            pts = np.asarray(component["table"], dtype=float)
            c = fem.Constant(self.mesh, PETSc.ScalarType(pts[0, 1]))
            self._tables.append((c, pts[:, 0], pts[:, 1]))
            return c
        return self.on_mesh(expressions.to_ufl(expressions.parse(component), self.symbols))

    def on_mesh(self, value):
        """The UFL of a value, tied to the mesh.

        UFL folds an expression without x, y, z and t, or one that is identically zero
        ("0*t", "0*x"), to a number or ``Zero``, which has no domain: dolfinx can neither
        interpolate it (fem.Expression) nor integrate it (fem.form).  Adding a zero
        Constant of the mesh gives it the domain (UFL reduces Zero + c to c).

        Args:
            value: a number or a UFL expression.

        Returns:
            A UFL expression with the mesh as its domain.
        """
        value = ufl.as_ufl(value)
        if ufl.domain.extract_domains(value):
            return value
        zero = fem.Constant(self.mesh, np.zeros(value.ufl_shape, dtype=PETSc.ScalarType))
        return value + zero

    def vector(self, components):
        """UFL vector of a load.

        Args:
            components: one component per space direction.

        Returns:
            The UFL vector, or None if every component is 0.
        """
        if all(is_zero(c) for c in components):
            return None
        return ufl.as_vector([self.scalar(c) for c in components])

    def depends_on_time(self, form) -> bool:
        """Whether a form changes with t: it holds t or a table's Constant, or a Function
        (whose values the run may change; conservatively so).

        Args:
            form: a UFL form built with this TimeData (no derivative left to expand: the
                Function it is taken with would count).

        Returns:
            False if assembling it at one time serves every time.
        """
        timed = {id(self.t)} | {id(c) for c, _, _ in self._tables}
        return bool(form.coefficients()) or any(id(c) in timed for c in form.constants())

    def set_time(self, t: float) -> None:
        """Set t and the tables' Constants to their values at t (t_n of the step).

        Args:
            t: the time.
        """
        self.t.value = t
        for c, ts, vs in self._tables:
            c.value = np.interp(t, ts, vs)
