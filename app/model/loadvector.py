"""The loads of step n at the nodes, f_n(phi_i) = (f0, phi_i) + sum of (f2, phi_i) over the
traction and pressure parts of Gamma2, as one ghosted PETSc vector.

The condensed solver's right-hand side (app/solvers/condensed/rhs.py) and the boundary
layer's nodal forces (app/model/layer.py) read it.  Loads that do not change with t
(``TimeData.depends_on_time``: no t, no table, no Function in the form) are assembled once
per run, the others when t has changed since the last assembly.
"""
from __future__ import annotations

from dolfinx import fem
from petsc4py import PETSc


class LoadVector:
    """f_n as a ghosted vector of V (collective).

    Args:
        form: the UFL form f_n(v) (StepForms.loads).
        time_data: the TimeData the form was built with (its t).
    """

    def __init__(self, form, time_data):
        self.form = fem.form(form)
        self.time_data = time_data
        self.timed = time_data.depends_on_time(form)
        self.vector = fem.petsc.create_vector(self.form)
        self._t = None                  # the time of the last assembly (None: none yet)
        self.assemblies = 0

    def at_current_time(self) -> PETSc.Vec:
        """f_n at the TimeData's current t, ghost contributions added to their owners.

        Returns:
            The vector (owned entries valid; do not modify).
        """
        t = float(self.time_data.t.value)
        if self._t is None or (self.timed and t != self._t):
            with self.vector.localForm() as loc:
                loc.set(0.0)
            fem.petsc.assemble_vector(self.vector, self.form)
            self.vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            self._t = t
            self.assemblies += 1
        return self.vector

    def destroy(self) -> None:
        """Free the PETSc vector."""
        self.vector.destroy()
