"""The discrete step problem of scheme (3.2)-(3.4) on one mesh.

Spaces (MODEL.md section 3): V^h = continuous P1 vectors, Q^h = DG0 tensors (sigma, H_n),
Y^h = DG0 scalars (kappa).  The problem object holds the unknown u, the pre-stress H_n, the
compiled forms, the Dirichlet condition on Gamma1, the box bounds of U^h on the normal dofs
of Gamma3 nodes, and computes the derived quantities: sigma_n, norms, contact forces.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from forms.contact import gamma3_measure
from forms.elasticity import elasticity_operator, eps
from forms.step import build_step_forms
from meshes import BOUNDARY_TAGS

from .case import Case
from .material import PlaneStress, to_voigt

GAMMA1, GAMMA3 = "left", "bottom"


@dataclass
class Gamma3Nodes:
    """The locally owned Gamma3 nodes (not on Gamma1), with their dof indices and weights."""

    nodes: np.ndarray    # local node (block) indices, owned, sorted by x
    x: np.ndarray        # (m, 2) coordinates
    weight: np.ndarray   # int_Gamma3 phi_i ds (the nodal rule's weight)


class _Constants(dict):
    """Named dolfinx Constants of the forms (physical parameters, loads, delta)."""

    def __init__(self, mesh):
        super().__init__()
        self._mesh = mesh

    def __call__(self, name, value):
        self[name] = fem.Constant(self._mesh, PETSc.ScalarType(value) if np.ndim(value) == 0
                                  else np.asarray(value, dtype=PETSc.ScalarType))
        return self[name]


class ContactProblem:
    """Forms and data of the step problem for a case on a mesh (a ``RectangleMesh``)."""

    def __init__(self, case: Case, rect):
        self.case, self.rect = case, rect
        msh = self.mesh = rect.mesh
        self.comm = msh.comm
        self.law = PlaneStress(case.material.E, case.material.nu)
        self.V = fem.VectorFunctionSpace(msh, ("CG", 1))
        self.Q = fem.TensorFunctionSpace(msh, ("DG", 0))
        self.Y = fem.FunctionSpace(msh, ("DG", 0))
        self.u = fem.Function(self.V, name="u")
        self.sigma = fem.Function(self.Q, name="sigma")
        self.sigma_vm = fem.Function(self.Y, name="sigma_vm")
        # H_n exists only when there is a history (viscoplastic law); see history.py.
        self.H = fem.Function(self.Q, name="H") if case.material.viscoplastic else None
        self.normal = np.array(rect.normal)
        self.tangent = np.array(rect.tangent)

        fdim = msh.topology.dim - 1
        ft = rect.facet_tags
        self._facets = {name: ft.indices[ft.values == tag] for name, tag in BOUNDARY_TAGS.items()}
        clamped = fem.locate_dofs_topological(self.V, fdim, self._facets[GAMMA1])
        self.bcs = [fem.dirichletbc(np.zeros(2, dtype=PETSc.ScalarType), clamped, self.V)]
        self._clamped_nodes = clamped

        ds = ufl.Measure("ds", domain=msh, subdomain_data=ft)
        c = case.contact
        self.ds_c = gamma3_measure(msh, ft, BOUNDARY_TAGS[GAMMA3], case.numerics.quadrature,
                                   case.numerics.gauss_degree)
        # Parameters enter the forms as Constants: one compiled form serves every value.
        const = self.constants = _Constants(msh)
        E, nu = const("E", case.material.E), const("nu", case.material.nu)
        f0 = const("f0", case.loads.f0) if any(case.loads.f0) else None
        tractions = [(const(f"traction_{name}", t), BOUNDARY_TAGS[name])
                     for name, t in case.loads.traction.items() if any(t)]
        friction = None
        if c.friction is not None:
            friction = {k: const(k, getattr(c.friction, k)) for k in ("b", "c1", "c2", "u1")}
        self.forms = build_step_forms(
            self.u, self.H, E=E, nu=nu, f0=f0, tractions=tractions, ds=ds, ds_c=self.ds_c,
            normal=tuple(self.normal),
            c_nu=const("c_nu", c.c_nu) if c.c_nu is not None else None,
            friction=friction,
            delta=const("delta", case.numerics.delta) if friction else None)
        self.F_form = fem.form(self.forms.residual)
        self.J_form = fem.form(self.forms.jacobian)
        self._bulk_form = fem.form(self.forms.bulk_residual)

        # sigma_n = E eps(u_n) + H_n evaluated per cell (exact: eps(u) is constant on cells).
        C = elasticity_operator(E, nu)
        expr = C(eps(self.u)) if self.H is None else C(eps(self.u)) + self.H
        self._sigma_expr = fem.Expression(expr, self.Q.element.interpolation_points())
        self._norm_forms = {
            "V": fem.form(ufl.inner(eps(self.u), eps(self.u)) * ufl.dx),
            "Q": fem.form(ufl.inner(self.sigma, self.sigma) * ufl.dx),
        }
        self.gamma3 = self._gamma3_nodes() if c.active else None

    # ------------------------------------------------------------------ sizes
    @property
    def num_cells(self) -> int:
        return self.mesh.topology.index_map(2).size_global

    @property
    def num_vertices(self) -> int:
        return self.mesh.topology.index_map(0).size_global

    @property
    def num_dofs(self) -> int:
        return self.V.dofmap.index_map.size_global * self.V.dofmap.index_map_bs

    @property
    def num_owned_cells(self) -> int:
        return self.mesh.topology.index_map(2).size_local

    # ------------------------------------------------------------------ Gamma3 and bounds
    def _gamma3_nodes(self) -> Gamma3Nodes:
        fdim = self.mesh.topology.dim - 1
        nodes = fem.locate_dofs_topological(self.V, fdim, self._facets[GAMMA3])
        nodes = np.setdiff1d(nodes, self._clamped_nodes)
        self._gamma3_local = nodes  # owned and ghost
        owned = nodes[nodes < self.V.dofmap.index_map.size_local]
        # weights w_i = int_Gamma3 phi_i ds, exact (phi_i is linear on each facet)
        v = ufl.TestFunction(self.V)
        wvec = fem.petsc.assemble_vector(fem.form(ufl.inner(ufl.as_vector([1.0, 1.0]), v)
                                                  * gamma3_measure(self.mesh, self.rect.facet_tags,
                                                                   BOUNDARY_TAGS[GAMMA3])))
        wvec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        weight = wvec.array_r[2 * owned]
        wvec.destroy()
        x = self.V.tabulate_dof_coordinates()[owned, :2]
        order = np.lexsort((x[:, 1], x[:, 0]))
        return Gamma3Nodes(owned[order], x[order], weight[order])

    def bounds(self) -> tuple[PETSc.Vec, PETSc.Vec]:
        """Box bounds of U^h: u_nu <= g on the normal dofs of Gamma3 nodes, +-inf elsewhere."""
        lb, ub = self.u.vector.duplicate(), self.u.vector.duplicate()
        with lb.localForm() as lo, ub.localForm() as up:
            lo.set(PETSc.NINFINITY)
            up.set(PETSc.INFINITY)
            g = self.case.contact.g
            if g is not None:
                comp = int(np.argmax(np.abs(self.normal)))
                sign = self.normal[comp]
                dofs = 2 * self._gamma3_local + comp
                if sign > 0:   # u_nu = +u_comp <= g
                    up.array[dofs] = g
                else:          # u_nu = -u_comp <= g  <=>  u_comp >= -g
                    lo.array[dofs] = -g
        return lb, ub

    # ------------------------------------------------------------------ derived quantities
    def update_sigma(self) -> None:
        """sigma_n = E eps(u_n) + H_n (3.2) and its von Mises norm, per cell."""
        self.sigma.interpolate(self._sigma_expr)
        self.sigma.x.scatter_forward()
        self.sigma_vm.x.array[:] = self.law.von_mises(to_voigt(self.sigma.x.array))
        self.sigma_vm.x.scatter_forward()

    def _reduce(self, value: float, op) -> float:
        from mpi4py import MPI
        return self.comm.allreduce(value, op=getattr(MPI, op))

    def norm(self, which: str) -> float:
        """||u||_V = ||eps(u)||_L2 ("V") or ||sigma||_Q ("Q"), reduced over ranks."""
        return float(np.sqrt(self._reduce(fem.assemble_scalar(self._norm_forms[which]), "SUM")))

    def cell_norm(self, f) -> float:
        """L2 norm of a DG0 scalar function (||kappa||_Y), reduced over ranks."""
        n = self.num_owned_cells
        vol = self._cell_volumes()[:n]
        return float(np.sqrt(self._reduce(float(np.sum(vol * f.x.array[:n] ** 2)), "SUM")))

    def cell_max(self, f) -> float:
        n = self.num_owned_cells
        local = float(np.max(f.x.array[:n])) if n else -np.inf
        return float(self._reduce(local, "MAX"))

    def _cell_volumes(self) -> np.ndarray:
        if not hasattr(self, "_vol"):
            w = ufl.TestFunction(self.Y)
            vec = fem.petsc.assemble_vector(fem.form(w * ufl.dx))
            self._vol = vec.array_r.copy()
            vec.destroy()
        return self._vol

    def contact_table(self) -> dict[str, np.ndarray]:
        """Per owned Gamma3 node: coordinates, displacement, u_nu, u_tau and the contact
        force densities -sigma_nu, -sigma_tau.

        The force at node i is minus the bulk residual r_i = (sigma_n, eps(phi_i)) - f(phi_i)
        divided by the node's weight w_i = int phi_i ds: with the nodal rule this is exactly
        p(u_nu) + (bound multiplier)/w_i in the normal direction and the friction force in
        the tangential one.
        """
        gm = self.gamma3
        r = fem.petsc.assemble_vector(self._bulk_form)
        r.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        rr = r.array_r.reshape(-1, 2)[gm.nodes]
        r.destroy()
        uu = self.u.x.array.reshape(-1, 2)[gm.nodes]
        return {
            "x": gm.x[:, 0], "y": gm.x[:, 1], "u_x": uu[:, 0], "u_y": uu[:, 1],
            "u_nu": uu @ self.normal, "u_tau": uu @ self.tangent,
            "neg_sigma_nu": -(rr @ self.normal) / gm.weight,
            "neg_sigma_tau": -(rr @ self.tangent) / gm.weight,
        }
