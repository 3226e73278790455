"""The discrete step problem of scheme (3.2)-(3.4) on one mesh (2D or 3D).

Spaces: V^h = continuous P1 vectors, Q^h = DG0 tensors (sigma, H_n),
Y^h = DG0 scalars (kappa).  The problem object holds the unknown u, the pre-stress H_n, the
Gamma3 nodal fields xi_n (memory) and theta(s_n) (slip dependence) when the case has them,
the compiled forms, the Dirichlet condition on Gamma1, the box bounds of U^h on the normal
dofs of Gamma3 nodes, and computes derived quantities: sigma_n, norms, contact forces.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import ufl
from dolfinx import cpp as dcpp
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact.forms.contact import gamma3_measure
from vpcontact.forms.elasticity import elasticity_operator, eps, plane_strain_moduli
from vpcontact.forms.step import BulkData, ContactData, build_step_forms
from vpcontact.io.case import Case, CaseError
from vpcontact.meshes.bodycheck import interior_role
from vpcontact.model.dirichlet import build_dirichlet, check_rigid_motions
from vpcontact.model.frames import ContactFrames, build_frames, facet_normals, gap_values
from vpcontact.model.gamma3 import NodalField
from vpcontact.model.history import ImplicitViscoplasticHistory
from vpcontact.model.loads import TimeData
from vpcontact.model.material import Elasticity
from vpcontact.model.state import State
from vpcontact.model.strain import StrainOperator
from vpcontact.model.viscoplastic import viscoplastic_law


@dataclass
class Gamma3Nodes:
    """The locally owned Gamma3 nodes (not on Gamma1), with their weights."""

    nodes: np.ndarray    # local node (block) indices, owned, sorted by coordinates
    x: np.ndarray        # (m, d) coordinates
    weight: np.ndarray   # int_Gamma3 phi_i ds (the nodal rule's weight)


class _Constants(dict):
    """Named dolfinx Constants of the forms (physical parameters, delta)."""

    def __init__(self, mesh):
        super().__init__()
        self._mesh = mesh

    def __call__(self, name, value):
        self[name] = fem.Constant(self._mesh, PETSc.ScalarType(value))
        return self[name]


class ContactProblem:
    """Forms and data of the step problem (3.4) for a case on a mesh.

    Args:
        case: the validated case.
        body: the mesh with its facet tags and named boundary groups (meshes.RectangleMesh,
            BoxMesh or FileMesh).

    Attributes:
        elasticity: the Elasticity E of the case (app/model/material.py).
        law: the viscoplastic law (app/model/viscoplastic.py), or None (elastic body).
        V, Q, Y: the spaces V^h (P1 vectors), Q^h (DG0 tensors), Y^h (DG0 scalars).
        state: the State (u, sigma, H, kappa, xi, s; app/model/state.py).
        u, sigma, sigma_vm: u_n, sigma_n and its von Mises norm (the State's).
        H: the pre-stress H_n of (3.2), or None without history and initial values.
        implicit_update: the implicit scheme's local update (the residual hook's), or None.
        xi, theta: the Gamma3 nodal fields xi_n (memory) and theta(s_n) (slip), or None.
        forms: the StepForms of J_n (forms/step.py).
        dirichlet: the Dirichlet data (Gamma1 and loads.displacement); ``bcs`` its conditions.
        gamma3: the owned Gamma3 nodes and their weights, or None without contact.
        frames: the nodal normals, frames and gaps of Gamma3 (owned and ghost nodes), or None.
    """

    def __init__(self, case: Case, body):
        self.case, self.body = case, body
        msh = self.mesh = body.mesh
        self.comm = msh.comm
        d = self.dim = msh.topology.dim
        self.E, self.nu = (plane_strain_moduli(case.material.E, case.material.nu)
                           if d == 2 and case.material.plane == "strain"
                           else (case.material.E, case.material.nu))
        self.elasticity = Elasticity(self.E, self.nu, d)
        self.law = viscoplastic_law(case.material.viscoplastic, self.elasticity)
        self.V = fem.VectorFunctionSpace(msh, ("CG", 1))
        self.Q = fem.TensorFunctionSpace(msh, ("DG", 0))
        self.Y = fem.FunctionSpace(msh, ("DG", 0))
        # H_n exists only with a history (viscoplastic law) or nonzero initial values.
        init = case.initial
        has_H = self.law is not None or init.u0 is not None or init.sigma0 is not None
        self.state = State(self.V, self.Q, self.Y, has_H,
                           self.law.m if self.law is not None else None,
                           rollback=case.time.adaptive is not None)
        # Implicit history variant: the forms take sigma and the algorithmic tangent per
        # cell (updated by the residual hook before every residual), not E eps(u) + H_n.
        self.implicit = case.time.scheme == "implicit" and self.law is not None
        self.C_alg = None
        self.k = None                      # the step k_n of set_time (the implicit update's)
        if self.implicit:
            m = self.elasticity.m
            self.C_alg = fem.Function(fem.TensorFunctionSpace(msh, ("DG", 0), shape=(m, m)),
                                      name="C_alg")
        self.time_data = TimeData(msh)
        self._setup_boundaries()

        c = case.contact
        self.gamma3 = self.frames = None
        self.xi = self.theta = None
        if c.active:
            self.gamma3 = self._gamma3_nodes()
            self.frames = self._frames()
            if c.memory is not None:
                self.xi = NodalField(self.V, self.gamma3_local_nodes, "xi")
            if c.friction is not None and c.friction.slip is not None:
                self.theta = NodalField(self.V, self.gamma3_local_nodes, "theta")
                self.theta.function.x.array[:] = 1.0

        self.forms = self._step_forms()
        self._bulk_form = fem.form(self.forms.bulk_residual)

        # sigma_n = E eps(u_n) + H_n per cell (exact: eps(u) is constant on cells),
        # app/model/strain.py
        self._C = elasticity_operator(self.constants["E"], self.constants["nu"], d)
        self.strain_operator = StrainOperator(self.V, self.Q, self.E, self.nu)
        # the implicit scheme's local update, run by the residual hook (before_residual)
        self.implicit_update = ImplicitViscoplasticHistory(self, self.law) \
            if self.implicit else None

    # the live fields of the State (app/model/state.py)
    @property
    def u(self):
        """u_n (the State's)."""
        return self.state.u

    @property
    def sigma(self):
        """sigma_n (the State's)."""
        return self.state.sigma

    @property
    def sigma_vm(self):
        """||sigma_n||_VM per cell (the State's)."""
        return self.state.sigma_vm

    @property
    def H(self):
        """H_n, or None without history and initial values (the State's)."""
        return self.state.H

    # ------------------------------------------------------------------ boundary groups
    def group_tag(self, ref, key: str) -> int:
        """The facet tag of a boundary group.

        Args:
            ref: a group name or a physical tag number.
            key: the case key naming it, for the message.

        Returns:
            The tag.

        Raises:
            CaseError: for a group the mesh does not have.
        """
        groups, tags = self.body.groups, self.body.tags
        if isinstance(ref, str) and ref in groups:
            return groups[ref]
        if isinstance(ref, int) and not isinstance(ref, bool) and ref in tags:
            return ref
        other = getattr(self.body, "other_groups", {})
        if ref in other:
            raise CaseError(f"{self.case.source}: {key}: {ref!r} is a group of dimension "
                            f"{other[ref]}; boundary groups have dimension {self.dim - 1}")
        names = ", ".join(sorted(groups)) or "none"
        numbers = ", ".join(str(t) for t in tags) or "none"
        hint = ""
        if not isinstance(ref, str) and str(ref) in groups:
            hint = f"; {ref} unquoted is a physical number: write '{ref}' for the group named so"
        elif isinstance(ref, str) and ref.strip().isdigit() and int(ref) in tags:
            hint = (f"; '{ref}' quoted is a name: write {int(ref)} without quotes for the "
                    "physical group of that number")
        raise CaseError(f"{self.case.source}: {key}: no boundary group {ref!r} in the mesh "
                        f"(names: {names}; numbers: {numbers}){hint}")

    def _setup_boundaries(self) -> None:
        """Facets of the named groups, the Dirichlet data and the rigid-motion check."""
        case, ft = self.case, self.body.facet_tags
        b, loads = case.boundaries, case.loads
        keys = [(r, "boundaries.clamped") for r in b.clamped] + \
            [(r, "boundaries.contact") for r in b.contact] + \
            [(r, f"loads.traction.{r}") for r in loads.traction] + \
            [(r, f"loads.pressure.{r}") for r in loads.pressure] + \
            [(r, f"loads.displacement.{r}") for r in loads.displacement]
        self.tags = {ref: self.group_tag(ref, key) for ref, key in keys}
        self._check_roles()
        for ref, key in keys:                   # a role on an embedded curve: refused
            if (why := interior_role(self.body, key, ref, self.tags[ref])) is not None:
                raise CaseError(f"{case.source}: {why}")
        self._facets = {ref: ft.indices[ft.values == tag] for ref, tag in self.tags.items()}
        self.dirichlet = build_dirichlet(self.V, self._facets, list(b.clamped),
                                         dict(loads.displacement), self.time_data)
        self.bcs = self.dirichlet.bcs
        check_rigid_motions(self.V, self.dirichlet.fixed, case.source)
        self._clamped_nodes = self.dirichlet.clamped_nodes

    def _check_roles(self) -> None:
        """The rules validation applies to the groups' spellings (app/io/case.py: no group
        twice in a role, clamped and contact disjoint, no load on a clamped group nor, in a
        case with contact, on Gamma3), applied to the groups themselves: a group's name and
        its physical tag are one group.

        Raises:
            CaseError: naming both spellings and the tag.
        """
        b, loads, source = self.case.boundaries, self.case.loads, self.case.source
        roles = [("boundaries.clamped", b.clamped), ("boundaries.contact", b.contact)] + \
            [(f"loads.{kind}", tuple(getattr(loads, kind)))
             for kind in ("traction", "pressure", "displacement")]
        for key, refs in roles:
            seen = {}
            for ref in refs:
                if self.tags[ref] in seen:
                    raise CaseError(f"{source}: {key}: {seen[self.tags[ref]]!r} and {ref!r} "
                                    f"are the same group (physical tag {self.tags[ref]}); "
                                    "give it once")
                seen[self.tags[ref]] = ref
        clamped = {self.tags[r]: r for r in b.clamped}
        contact = {self.tags[r]: r for r in b.contact} if self.case.contact.active else {}
        for key, refs in roles[1:]:
            for ref in refs:
                where = key if key.startswith("boundaries") else f"{key}.{ref}"
                if self.tags[ref] in clamped:
                    raise CaseError(f"{source}: {where}: {ref!r} is the clamped group "
                                    f"{clamped[self.tags[ref]]!r} (physical tag "
                                    f"{self.tags[ref]}; boundaries.clamped: u = 0 there)")
                if key.startswith("loads") and self.tags[ref] in contact:
                    raise CaseError(f"{source}: {where}: {ref!r} is the contact group "
                                    f"{contact[self.tags[ref]]!r} (physical tag "
                                    f"{self.tags[ref]}, Gamma3); a {key[6:]} there is "
                                    "only allowed in a case without a contact section")

    @property
    def gamma3_tags(self) -> tuple:
        """The facet tags of Gamma3 (the contact groups)."""
        return tuple(sorted({self.tags[r] for r in self.case.boundaries.contact}))

    def set_time(self, t: float, k: float | None = None) -> None:
        """The data of step n: loads f_n and the prescribed displacements at t_n, and the
        step k_n (the implicit scheme's local update uses it at every residual).

        Args:
            t: the time t_n.
            k: the step k_n (None: unchanged).
        """
        if k is not None:
            self.k = k
        self.time_data.set_time(t)
        self.dirichlet.set_time()

    def _step_forms(self):
        """J_n's data (loads, laws (4.1)-(4.2), history fields) and forms/step.py's forms."""
        case, msh, ft, d = self.case, self.mesh, self.body.facet_tags, self.dim
        c = case.contact
        ds = ufl.Measure("ds", domain=msh, subdomain_data=ft)
        self.ds_c = gamma3_measure(msh, ft, self.gamma3_tags, case.numerics.quadrature,
                                   case.numerics.gauss_degree) if c.active else None
        # Parameters enter the forms as Constants: one compiled form serves every value.
        const = self.constants = _Constants(msh)
        E, nu = const("E", self.E), const("nu", self.nu)
        f0 = self.time_data.vector(case.loads.f0) if case.loads.f0 else None
        tractions = []
        for name, comps in case.loads.traction.items():
            vec = self.time_data.vector(comps)
            if vec is not None:
                tractions.append((vec, self.tags[name]))
        n_facet = ufl.FacetNormal(msh)
        for name, p in case.loads.pressure.items():
            tractions.append((-self.time_data.scalar(p) * n_facet, self.tags[name]))
        bulk = BulkData(E, nu, d, H=None if self.implicit else self.H, f0=f0,
                        tractions=tractions, ds=ds,
                        stress=self.sigma if self.implicit else None, tangent=self.C_alg)
        return build_step_forms(self.u, bulk, self._contact_data() if c.active else None)

    def _contact_data(self) -> ContactData:
        """The Gamma3 part of J_n: the normal field and the laws' parameters."""
        c, const = self.case.contact, self.constants
        friction = None
        if c.friction is not None:
            friction = {k: const(k, getattr(c.friction, k)) for k in ("b", "c1", "c2", "u1")}
        needs_delta = c.friction is not None or c.memory is not None
        return ContactData(
            self.ds_c, self._normal_ufl(),
            c_nu=const("c_nu", c.c_nu) if c.c_nu is not None else None,
            friction=friction,
            theta=self.theta.function if self.theta else None,
            xi=self.xi.function if self.xi else None,
            delta=const("delta", self.case.numerics.delta) if needs_delta else None)

    def _normal_ufl(self):
        """nu in the forms: a constant vector where every Gamma3 node has the same normal
        (a flat Gamma3 or a fixed direction), else the P1 field of the nodal normals (exact
        at the nodes, where the nodal rule evaluates the Gamma3 terms)."""
        nu = self.frames.normal
        first = nu[0] if len(nu) else None
        firsts = [f for f in self.comm.allgather(first) if f is not None]
        ref = firsts[0] if firsts else np.zeros(self.dim)
        same = np.abs(nu - ref).max(initial=0.0) <= 1e-12 and all(
            np.abs(f - ref).max() <= 1e-12 for f in firsts)
        if self.comm.allreduce(bool(same), op=MPI.LAND):
            return ufl.as_vector([float(v) for v in ref])
        field = self.nu_h = fem.Function(self.V, name="nu")
        arr = field.x.array.reshape(-1, self.dim)
        arr[:] = self._facet_normals
        arr[self.frames.nodes] = nu
        return field

    @cached_property
    def _facet_normals(self) -> np.ndarray:
        """The area-weighted outward unit normals of Gamma3 at all local nodes."""
        return facet_normals(self.V, self.gamma3_exact_measure())

    # The step residual and Jacobian (SNES VI) and the strain interpolation (the numpy
    # stress path) are compiled when first used: the fast solver with the compiled kernels
    # needs none of them (25 ms of set-up at h = 1/128; collective, like every use of them).
    @cached_property
    def F_form(self):
        """The compiled residual of (3.4) (dolfinx Form)."""
        return fem.form(self.forms.residual)

    @cached_property
    def J_form(self):
        """The compiled Jacobian of the residual (dolfinx Form)."""
        return fem.form(self.forms.jacobian)

    @cached_property
    def _eps_fn(self):
        return fem.Function(self.Q)

    @cached_property
    def _eps_expr(self):
        return fem.Expression(eps(self.u), self.Q.element.interpolation_points())

    @property
    def length_scale(self) -> float:
        """The largest side of the body's bounding box (the mesh's ``bbox``)."""
        lo, hi = self.body.bbox
        return float(np.max(hi - lo))

    @property
    def gap_scale(self) -> float | None:
        """The largest gap g on Gamma3 (collective), or None without the bound."""
        fr = self.frames
        if fr is None or fr.g is None:
            return None
        return float(self._reduce(float(np.max(fr.g, initial=0.0)), "MAX"))

    # ------------------------------------------------------------------ sizes
    @property
    def num_cells(self) -> int:
        """Cells of the mesh (all ranks)."""
        return self.mesh.topology.index_map(self.dim).size_global

    @property
    def num_vertices(self) -> int:
        """Vertices of the mesh (all ranks)."""
        return self.mesh.topology.index_map(0).size_global

    @property
    def num_dofs(self) -> int:
        """Degrees of freedom of V^h (all ranks)."""
        return self.V.dofmap.index_map.size_global * self.V.dofmap.index_map_bs

    @property
    def num_gamma3_nodes(self) -> int:
        """Gamma3 nodes carrying contact (all ranks; 0 without contact)."""
        n = len(self.gamma3.nodes) if self.gamma3 is not None else 0
        return int(self.comm.allreduce(n))

    @property
    def num_owned_cells(self) -> int:
        """Cells owned by this rank."""
        return self.mesh.topology.index_map(self.dim).size_local

    # ------------------------------------------------------------------ initial values
    def set_initial_values(self) -> None:
        """u = u0, H_0 = sigma0 - E eps(u0) (3.2), kappa = kappa0 (3.3) (cell averages) in
        the State.

        Raises:
            CaseError: if the initial values are not finite, kappa0 < 0 somewhere, or u0
                violates u = 0 on Gamma1 or u_nu <= g on Gamma3 (on every rank).
        """
        init, scalar = self.case.initial, self.time_data.scalar
        kappa = self.state.kappa
        if init.u0 is not None:
            vec = ufl.as_vector([scalar(c) for c in init.u0])
            self.u.interpolate(fem.Expression(vec, self.V.element.interpolation_points()))
            self.u.x.scatter_forward()
            self._check_initial_u()
        if self.H is not None:
            H0 = -self._C(eps(self.u))
            if init.sigma0 is not None:
                H0 = H0 + ufl.as_matrix([[scalar(c) for c in row]
                                         for row in init.sigma0])
            self._cell_average(H0, self.H)
            self._refuse(not np.isfinite(self.H.x.array).all(), "initial.sigma0",
                         "not a finite number in a cell of the mesh")
        if kappa is not None:
            k0 = self.case.material.viscoplastic.kappa0
            if isinstance(k0, str):
                self._cell_average(scalar(k0), kappa)
                self._refuse(not (kappa.x.array >= 0).all(), "material.viscoplastic.kappa0",
                             "must be a finite number >= 0 everywhere")
            else:
                kappa.x.array[:] = k0

    def _cell_average(self, expr, f) -> None:
        """f = P_{Q^h} expr, the L2 projection onto DG0 (cell averages)."""
        w = ufl.TestFunction(f.function_space)
        vec = fem.petsc.assemble_vector(fem.form(ufl.inner(expr, w) * ufl.dx))
        bs = f.function_space.dofmap.index_map_bs
        owned = vec.array.size
        vol = np.repeat(self._cell_volumes()[:owned // bs], bs)
        f.x.array[:owned] = vec.array / vol
        f.x.scatter_forward()
        vec.destroy()

    def _refuse(self, bad: bool, key: str, why: str) -> None:
        """Raise CaseError on every rank if ``bad`` on any (the exact check on the mesh)."""
        if self.comm.allreduce(bool(bad), op=MPI.LOR):
            raise CaseError(f"{self.case.source}: {key}: {why}")

    def _check_initial_u(self) -> None:
        """u0 at the mesh nodes: zero on Gamma1 (up to round-off of its largest value),
        u_nu <= g on Gamma3 (the case's validation checked sample points already)."""
        uu = self.u.x.array.reshape(-1, self.dim)
        self._refuse(not np.isfinite(uu).all(), "initial.u0",
                     "not a finite number at a node of the mesh")
        scale = self._reduce(float(np.abs(uu).max(initial=0.0)), "MAX")
        self._refuse(np.abs(uu[self._clamped_nodes]).max(initial=0.0) > 1e-12 * scale,
                     "initial.u0", "must vanish on Gamma1 (boundaries.clamped)")
        fr = self.frames
        if fr is not None and fr.g is not None:
            u_nu = np.einsum("ij,ij->i", uu[fr.nodes], fr.normal)
            self._refuse((fr.bounded & (u_nu > fr.g + 1e-12 * np.maximum(fr.g, scale))).any(),
                         "initial.u0", "violates u_nu <= g on Gamma3")

    # ------------------------------------------------------------------ Gamma3 and bounds
    def gamma3_facet_coordinates(self) -> np.ndarray:
        """The vertex coordinates of this rank's Gamma3 facets (contact.xdmf's facet mesh).

        Returns:
            Shape (facets, vertices per facet, 3).
        """
        msh, fdim = self.mesh, self.dim - 1
        facets = np.unique(np.concatenate([self._facets[r] for r in self.case.boundaries.contact]
                                          or [np.zeros(0, dtype=np.int32)]))
        msh.topology.create_connectivity(fdim, self.dim)
        cpp_mesh = getattr(msh, "_mesh", msh)          # the C++ mesh behind dolfinx's wrapper
        idx = dcpp.mesh.entities_to_geometry(cpp_mesh, fdim, facets.astype(np.int32), False)
        facet_type = dcpp.mesh.cell_entity_type(msh.topology.cell_type, fdim, 0)
        nv = dcpp.mesh.cell_num_vertices(facet_type)
        return msh.geometry.x[idx.reshape(len(facets), nv)]

    def gamma3_exact_measure(self):
        """Gamma3 with a Gauss rule exact for P1 functions (weights, facet normals).

        Returns:
            The UFL measure ds on the contact groups.
        """
        return gamma3_measure(self.mesh, self.body.facet_tags, self.gamma3_tags, "gauss", 2)

    def _gamma3_nodes(self) -> Gamma3Nodes:
        fdim = self.mesh.topology.dim - 1
        facets = np.concatenate([self._facets[r] for r in self.case.boundaries.contact])
        nodes = fem.locate_dofs_topological(self.V, fdim, np.unique(facets))
        fixed = self.dirichlet.fixed[nodes].all(axis=1)
        nodes = np.sort(nodes[~fixed])                # fully prescribed nodes take no contact
        self.gamma3_local_nodes = nodes  # owned and ghost
        owned = nodes[nodes < self.V.dofmap.index_map.size_local]
        # weights w_i = int_Gamma3 phi_i ds, exact (phi_i is linear on each facet)
        v = ufl.TestFunction(self.V)
        wvec = fem.petsc.assemble_vector(fem.form(v[0] * self.gamma3_exact_measure()))
        wvec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        weight = wvec.array_r[self.dim * owned]
        wvec.destroy()
        x = self.V.tabulate_dof_coordinates()[owned, :self.dim]
        order = np.lexsort(tuple(x[:, i] for i in reversed(range(self.dim))))
        return Gamma3Nodes(owned[order], x[order], weight[order])

    def _frames(self) -> ContactFrames:
        """Normals, frames and gaps at the Gamma3 nodes (app/model/frames.py)."""
        c, nodes = self.case.contact, self.gamma3_local_nodes
        frames = build_frames(self.V, nodes, self._facet_normals[nodes],
                              self.dirichlet.fixed[nodes], c.direction, self.case.source)
        if c.g is not None:
            x = self.V.tabulate_dof_coordinates()[nodes, :self.dim]
            frames.g = gap_values(c.g, x, self.case.source, self.comm)
        return frames

    def bounds(self) -> tuple[PETSc.Vec, PETSc.Vec]:
        """Box bounds of U^h: u_nu <= g at the Gamma3 nodes, in the nodal frames (the
        dof ``slot`` of node i is sign_i u_nu), +-inf elsewhere.

        Returns:
            (lower, upper) bound vectors like u (owned and ghost entries set).
        """
        lb, ub = self.u.vector.duplicate(), self.u.vector.duplicate()
        with lb.localForm() as lo, ub.localForm() as up:
            lo.set(PETSc.NINFINITY)
            up.set(PETSc.INFINITY)
            fr = self.frames
            if fr is not None and fr.g is not None:
                on = fr.bounded
                dofs = self.dim * fr.nodes[on] + fr.slot[on]
                plus = fr.sign[on] > 0
                up.array[dofs[plus]] = fr.g[on][plus]       # u_nu = +u_slot <= g
                lo.array[dofs[~plus]] = -fr.g[on][~plus]    # u_nu = -u_slot <= g
        return lb, ub

    # ------------------------------------------------------------------ derived quantities
    def update_sigma(self) -> tuple[float, float] | None:
        """sigma_n = E eps(u_n) + H_n (3.2) and its von Mises norm, per cell.

        Returns:
            (||u_n||_V, ||sigma_n||_Q) where the compiled cell pass computed them on the way
            (the step record's norms without a second pass), else None.
        """
        sums = self.strain_operator.update_sigma(self.u, self.H, self.sigma, self.sigma_vm)
        if sums is None:
            self.update_vm()
            return None
        return float(np.sqrt(max(sums[0], 0.0))), float(np.sqrt(max(sums[1], 0.0)))

    def update_vm(self) -> None:
        """sigma_vm = ||sigma||_VM per cell, from sigma."""
        el = self.elasticity
        self.sigma_vm.x.array[:] = el.von_mises(el.to_voigt(self.sigma.x.array))
        self.sigma_vm.x.scatter_forward()

    def strain_voigt(self) -> np.ndarray:
        """eps(u) per cell.

        Returns:
            (cells, m) strains in t-coordinates, owned and ghost cells.
        """
        self._eps_fn.interpolate(self._eps_expr)
        self._eps_fn.x.scatter_forward()
        return self.elasticity.to_voigt(self._eps_fn.x.array)

    def before_residual(self) -> bool:
        """Called with the current u before every residual assembly: the implicit variant's
        local stress update.

        Returns:
            False if the update failed (the residual is then NaN), else True.
        """
        if self.implicit_update is None:
            return True
        return self.implicit_update.trial(self, self.k)

    def _reduce(self, value: float, op) -> float:
        return self.comm.allreduce(value, op=getattr(MPI, op))

    def norm(self, which: str) -> float:
        """A norm of the step record, reduced over ranks; collective.

        Exact cell sums (eps(u) and sigma are constant on cells).

        Args:
            which: "V" for ||u||_V = ||eps(u)||_L2, "Q" for ||sigma||_Q.

        Returns:
            The norm.
        """
        op = self.strain_operator
        if which == "V":
            return float(np.sqrt(max(op.strain_norm2(self.u), 0.0)))
        local = op.energy_norm2(self.sigma.x.array[:op.n_owned * self.dim**2])
        return float(np.sqrt(self._reduce(local, "SUM")))

    def cell_norm(self, f) -> float:
        """L2 norm of a DG0 scalar function (||kappa||_Y), reduced over ranks; collective.

        Args:
            f: a DG0 scalar Function on the mesh.

        Returns:
            The norm.
        """
        n = self.num_owned_cells
        vol = self._cell_volumes()[:n]
        return float(np.sqrt(self._reduce(float(np.sum(vol * f.x.array[:n] ** 2)), "SUM")))

    def cell_max(self, f) -> float:
        """The largest cell value of a DG0 scalar function, over ranks; collective.

        Args:
            f: a DG0 scalar Function on the mesh.

        Returns:
            The maximum (-inf without cells).
        """
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

    @cached_property
    def _boundary_residual_form(self):
        """The bulk residual on the cells that touch a vertex of a Dirichlet group or of
        Gamma3 (exact at those nodes, a thin layer of the mesh: the step records' forces
        cost a fraction of a full assembly)."""
        msh, tdim = self.mesh, self.dim
        refs = [g.name for g in self.dirichlet.groups] + list(self.case.boundaries.contact)
        facets = np.unique(np.concatenate([self._facets[r] for r in refs] or
                                          [np.zeros(0, np.int32)])).astype(np.int32)
        msh.topology.create_connectivity(tdim - 1, 0)
        msh.topology.create_connectivity(0, tdim)
        verts = dmesh.compute_incident_entities(msh, facets, tdim - 1, 0)
        cells = np.unique(dmesh.compute_incident_entities(msh, verts, 0, tdim)).astype(np.int32)
        tags = dmesh.meshtags(msh, tdim, cells, np.ones(len(cells), dtype=np.int32))
        layer = []
        for itg in self.forms.bulk_residual.integrals():
            if itg.integral_type() == "cell":
                itg = itg.reconstruct(subdomain_id=1, subdomain_data=tags)
            layer.append(itg)
        return fem.form(ufl.Form(layer))

    def bulk_residual(self, layer: bool = False) -> np.ndarray:
        """The bulk residual r = (sigma_n, eps(phi_i)) - f_n(phi_i) at the owned nodes: the
        force the boundary (supports, contact) exerts on the body at each node.

        Args:
            layer: assemble only the cells touching Dirichlet and Gamma3 vertices (exact
                there, not elsewhere).

        Returns:
            (owned nodes, d) nodal forces.
        """
        r = fem.petsc.assemble_vector(self._boundary_residual_form if layer
                                      else self._bulk_form)
        r.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        out = r.array_r.reshape(-1, self.dim).copy()
        r.destroy()
        return out

    def contact_table(self, r: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Per owned Gamma3 node: coordinates, displacement, u_nu, tangential components in
        the nodal frame, and the contact force densities -sigma_nu, -sigma_tau (and xi,
        theta(s), the gap where it varies).

        The force at node i is the bulk residual r_i = (sigma_n, eps(phi_i)) - f(phi_i)
        divided by the node's weight w_i = int phi_i ds: with the nodal rule this is exactly
        p(u_nu) + memory force + (bound multiplier)/w_i in the normal direction and the
        friction force in the tangential ones.

        Args:
            r: the bulk residual (bulk_residual()), or None to assemble it.

        Returns:
            Column name -> values of the owned Gamma3 nodes (sorted by coordinates).
        """
        gm, d, fr = self.gamma3, self.dim, self.frames
        rr = (self.bulk_residual(layer=True) if r is None else r)[gm.nodes]
        uu = self.u.x.array.reshape(-1, d)[gm.nodes]
        pos = np.searchsorted(fr.nodes, gm.nodes)
        nu, tau = fr.normal[pos], fr.tangents[pos]
        axes = "xyz"[:d]
        table = {a: gm.x[:, i] for i, a in enumerate(axes)}
        table.update({f"u_{a}": uu[:, i] for i, a in enumerate(axes)})
        table["u_nu"] = np.einsum("ij,ij->i", uu, nu)
        u_tau = np.einsum("ij,ikj->ik", uu, tau)
        f_tau = -np.einsum("ij,ikj->ik", rr, tau) / gm.weight[:, None]
        suffix = [""] if d == 2 else ["1", "2"]
        for k, sfx in enumerate(suffix):
            table[f"u_tau{sfx}"] = u_tau[:, k]
        if d == 3:
            table["u_tau"] = np.linalg.norm(u_tau, axis=1)
        table["neg_sigma_nu"] = -np.einsum("ij,ij->i", rr, nu) / gm.weight
        for k, sfx in enumerate(suffix):
            table[f"neg_sigma_tau{sfx}"] = f_tau[:, k]
        if self.xi is not None:
            table["xi"] = self.xi.function.x.array[self.xi.dofs[pos]]
        if self.theta is not None:
            table["theta"] = self.theta.function.x.array[self.theta.dofs[pos]]
        if isinstance(self.case.contact.g, str):
            table["g"] = fr.g[pos]
        # hidden (not a CSV column): the Dirichlet data prescribe u_nu here, so the force is
        # a support's reaction, not a contact pressure
        table["_prescribed"] = ~fr.bounded[pos]
        return table

    def forces(self, r: np.ndarray | None = None) -> dict:
        """The reaction force resultant on each Dirichlet group and the total contact
        force, both exerted on the body (collective).  With the loads they sum to zero
        (equilibrium, up to the solver's tolerance).

        Args:
            r: the bulk residual (bulk_residual()), or None to assemble it.

        Returns:
            {"reactions": {group: [F_x, F_y(, F_z)]}, "contact_force": [...] (Gamma3 dofs
            that no Dirichlet condition prescribes) or None without contact}.
        """
        r = (self.bulk_residual(layer=True) if r is None else r).ravel()
        d = self.dim
        reactions = {}
        for grp in self.dirichlet.groups:
            local = np.bincount(grp.dofs % d, weights=r[grp.dofs], minlength=d)
            reactions[str(grp.name)] = [float(v) for v in self.comm.allreduce(local)]
        contact = None
        if self.gamma3 is not None:
            nodes = self.gamma3.nodes
            free = ~self.dirichlet.fixed[nodes]
            local = (r.reshape(-1, d)[nodes] * free).sum(axis=0)
            contact = [float(v) for v in self.comm.allreduce(local)]
        return {"reactions": reactions, "contact_force": contact}
