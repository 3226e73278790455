"""The step problem of scheme (3.2)-(3.4) on one mesh (2D or 3D): the forms of J_n and
its derivatives (3.4), the data of step n (loads f_n at t_n, the step k_n) and the residual
hook, and the stress update sigma_n = E eps(u_n) + H_n (3.2).

It is built on the case's Discretisation (app/model/discretisation.py: spaces, groups,
Dirichlet data, Gamma3 nodes and frames, the box bounds of U^h), which it holds as ``disc``
without repeating its attributes, and holds the State (app/model/state.py: u, sigma,
H, kappa, xi, s) whose fields the forms read; the quantities derived from a solved step
(norms, forces, the contact table) are app/post/quantities.py's.
"""
from __future__ import annotations

from functools import cached_property

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact.case import Case, CaseError
from vpcontact.forms.contact import gamma3_measure
from vpcontact.forms.elasticity import eps, plane_strain_moduli
from vpcontact.forms.step import (
    BulkData,
    ContactData,
    build_boundary_forms,
    build_step_forms,
)
from vpcontact.model.contact_laws import ContactLaw, replace_laws, varies_in_space
from vpcontact.model.contactregistry import contact_law
from vpcontact.model.discretisation import Discretisation
from vpcontact.model.fullstress import full_stress
from vpcontact.model.gamma3 import NodalField
from vpcontact.model.history import ImplicitViscoplasticHistory
from vpcontact.model.lawmodule import python_contact_laws
from vpcontact.model.lawregistry import viscoplastic_law
from vpcontact.model.layer import BoundaryLayer
from vpcontact.model.loads import TimeData
from vpcontact.model.loadvector import LoadVector
from vpcontact.model.material import Elasticity
from vpcontact.model.materials import body_materials
from vpcontact.model.semicoercive import ContactHold
from vpcontact.model.state import State
from vpcontact.model.stiffness import case_elasticity, stress_operator
from vpcontact.model.strain import StrainOperator
from vpcontact.model.userlaw import as_viscoplastic_law


class _Constants(dict):
    """Named dolfinx Constants of the forms (physical parameters, delta)."""

    def __init__(self, mesh):
        super().__init__()
        self._mesh = mesh

    def __call__(self, name, value):
        self[name] = fem.Constant(self._mesh, PETSc.ScalarType(value))
        return self[name]


class ContactProblem:
    """The step problem (3.4) of a case on a mesh: forms, bounds, step data, residual hook.

    Args:
        case: the validated case.
        body: the mesh with its facet tags and named boundary groups (meshes.RectangleMesh,
            BoxMesh or FileMesh).
        law: a viscoplastic law that replaces the case's (a ViscoplasticLaw, a user's law
            object, or a class / callable elasticity -> law; app/model/userlaw.py), or None.
        contact_laws: contact laws that replace parts of the case's, {"normal": P,
            "friction": psi} (ScalarLaws; app/model/contact_laws.py: ``replace_laws``), or
            None.

    Attributes:
        disc: the Discretisation (app/model/discretisation.py): the mesh, its spaces V, Q,
            Y, groups, Dirichlet data ``dirichlet``/``bcs``, Gamma3 nodes ``gamma3`` and
            ``frames``, the bounds of U^h (``bounds``); read as ``problem.disc.V``, ...
        elasticity: the elasticity E of the case (app/model/material.py: Elasticity, or
            MatrixElasticity / CellElasticity built by app/model/stiffness.py).
        elastic_operator: tau -> E tau in UFL (forms.elasticity).
        law: the viscoplastic law (app/model/viscoplastic.py), or None (elastic body).
        contact_replacements: the contact laws that replace parts of the case's: the case's
            laws written by the user (``law: python``, app/model/lawmodule.py) and those
            given through the API ({} if none).
        state: the State (u, sigma, H, kappa, xi, s; app/model/state.py).
        u, sigma, sigma_vm: u_n, sigma_n and its von Mises norm (the State's).
        H: the pre-stress H_n of (3.2), or None without history and initial values.
        xi, theta: the Gamma3 nodal fields xi_n (memory) and theta(s_n) (slip; times
            mu p_n with Coulomb friction), or None.
        forms: the StepForms of J_n (forms/step.py); ``constants`` their Constants.
        time_data: the loads' time constants (app/model/loads.py).
        k: the step k_n given to ``set_time``.
        implicit_update: the implicit scheme's local update (the residual hook's), or None.
    """

    def __init__(self, case: Case, body, law=None, contact_laws=None):
        self.case = case
        given = dict(contact_laws or {})
        if given and not case.contact.active:
            raise CaseError(f"{case.source}: contact_laws: the case has no contact section")
        # the case's contact laws written by the user (law: python, --law-module) replace
        # their parts like the API's; a part given through the API takes precedence
        self.contact_replacements = {**python_contact_laws(case.contact, skip=given), **given}
        self.time_data = TimeData(body.mesh)
        disc = self.disc = Discretisation(case, body, self.time_data)
        d = disc.dim
        # materials: one per group of cells (app/model/materials.py), E per cell, their laws
        self.materials = body_materials(case, body, disc.Q) if case.materials else None
        try:     # E(x), orthotropic or voigt (app/model/stiffness.py); None: numbers E, nu
            general = self.materials.elasticity if self.materials else \
                case_elasticity(case.material, d, disc.Q)
        except ValueError as e:
            raise CaseError(f"{case.source}: {e}") from None
        if general is None:
            self.E, self.nu = (plane_strain_moduli(case.material.E, case.material.nu)
                               if d == 2 and case.material.plane == "strain"
                               else (case.material.E, case.material.nu))
            self.elasticity = Elasticity(self.E, self.nu, d)
        else:
            self.E = self.nu = None
            self.elasticity = general
        # a law object of the Python API replaces the case's (app/model/userlaw.py)
        self.law = (self.materials.law if self.materials else
                    viscoplastic_law(case.material.viscoplastic, self.elasticity,
                                     case.material.plane)) \
            if law is None else as_viscoplastic_law(law, self.elasticity)
        # H_n exists only with a history (viscoplastic law) or nonzero initial values.
        init = case.initial
        has_H = self.law is not None or init.u0 is not None or init.sigma0 is not None
        plane_strain = d == 2 and case.all_materials[0].plane == "strain"
        self.state = State(disc.V, disc.Q, disc.Y, has_H,
                           self.law.m if self.law is not None else None,
                           rollback=case.time.adaptive is not None, sigma_33=plane_strain)
        # sigma_33 and the 3D von Mises norm in plane strain (app/model/fullstress.py)
        self.full_stress = full_stress(self)
        # Implicit history variant: the forms take sigma and the algorithmic tangent per
        # cell (updated by the residual hook before every residual), not E eps(u) + H_n.
        self.implicit = case.time.scheme == "implicit" and self.law is not None
        self.C_alg = None
        self.k = None                      # the step k_n of set_time (the implicit update's)
        if self.implicit:
            m = self.elasticity.m
            self.C_alg = fem.Function(fem.TensorFunctionSpace(disc.mesh, ("DG", 0),
                                                              shape=(m, m)), name="C_alg")
        self.xi = self.theta = None
        c = case.contact
        if c.active:
            if any(s.memory is not None for s in c.sections):
                self.xi = NodalField(disc.V, disc.gamma3_local_nodes, "xi")
            if any(s.friction is not None and (s.friction.slip is not None or s.friction.coulomb
                                               is not None) for s in c.sections):
                self.theta = NodalField(disc.V, disc.gamma3_local_nodes, "theta")
                self.theta.function.x.array[:] = 1.0
        # two bodies: the Gamma3 terms act on w, the relative displacement less the
        # initial distance at the Gamma3 nodes (app/model/pairs.py)
        self.w = fem.Function(disc.V, name="w") if disc.pairs is not None else None
        self.pair_forms = None
        self.forms = self._step_forms()
        # sigma_n = E eps(u_n) + H_n per cell (exact: eps(u) is constant on cells),
        # app/model/strain.py
        self.strain_operator = StrainOperator(
            disc.V, disc.Q, self.E, self.nu,
            None if isinstance(self.elasticity, Elasticity) else self.elastic_operator)
        # the implicit scheme's local update, run by the residual hook (before_residual)
        self.implicit_update = ImplicitViscoplasticHistory(self, self.law) \
            if self.implicit else None
        # a body held only by contact: its loads checked for every step
        # (app/model/semicoercive.py)
        held = disc.held_by_contact
        self.hold = ContactHold(self, held) if held else None
        if self.hold is not None:
            self.hold.check_loads(case.time.times[1:])

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
    def sigma_33(self):
        """sigma_33 per cell in 2D plane strain (the State's; DG0), else None (3D: sigma is
        3 x 3; plane stress: sigma_33 = 0 by definition)."""
        return self.state.sigma_33

    def stress_3d(self) -> np.ndarray:
        """The full 3 x 3 stress of every owned cell: sigma itself in 3D; in 2D sigma with
        sigma_33 (plane strain: ``sigma_33``, app/model/fullstress.py; plane stress: 0)
        and sigma_13 = sigma_23 = 0.

        Returns:
            (owned cells, 3, 3).
        """
        n, d = self.disc.num_owned_cells, self.disc.dim
        sig = self.sigma.x.array.reshape(-1, d, d)[:n]
        if d == 3:
            return sig.copy()
        out = np.zeros((n, 3, 3))
        out[:, :2, :2] = sig
        if self.sigma_33 is not None:
            out[:, 2, 2] = self.sigma_33.x.array[:n]
        return out

    @property
    def H(self):
        """H_n, or None without history and initial values (the State's)."""
        return self.state.H

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
        self.disc.dirichlet.set_time()

    def _step_forms(self):
        """J_n's data (loads, laws (4.1)-(4.2), history fields) and forms/step.py's forms."""
        case, disc = self.case, self.disc
        msh, ft, d = disc.mesh, disc.body.facet_tags, disc.dim
        c = case.contact
        ds = ufl.Measure("ds", domain=msh, subdomain_data=ft)
        self.ds_c = gamma3_measure(msh, ft, disc.gamma3_tags, case.numerics.quadrature,
                                   case.numerics.gauss_degree) if c.active else None
        # Parameters enter the forms as Constants: one compiled form serves every value.
        const = self.constants = _Constants(msh)
        E = const("E", self.E) if self.E is not None else None
        nu = const("nu", self.nu) if self.nu is not None else None
        # tau -> E tau in UFL (the initial H_0, the condensed solver's stiffness)
        self.elastic_operator = stress_operator(self.elasticity, disc.Q, E, nu)
        f0 = self.time_data.vector(case.loads.f0) if case.loads.f0 else None
        tractions = []
        for name, comps in case.loads.traction.items():
            vec = self.time_data.vector(comps)
            if vec is not None:
                tractions.append((vec, disc.tags[name]))
        n_facet = ufl.FacetNormal(msh)
        for name, p in case.loads.pressure.items():
            tractions.append((-self.time_data.scalar(p) * n_facet, disc.tags[name]))
        bulk = BulkData(E, nu, d, H=None if self.implicit else self.H, f0=f0,
                        tractions=tractions, ds=ds,
                        stress=self.sigma if self.implicit else None, tangent=self.C_alg,
                        C=None if E is not None else self.elastic_operator)
        if self.w is None:
            return build_step_forms(self.u, bulk, self._contact_data() if c.active else None)
        forms = build_step_forms(self.u, bulk, None)
        *self.pair_forms, terms = build_boundary_forms(self.w, self._pair_contact_data())
        forms.terms += terms
        return forms

    def contact_u(self) -> np.ndarray:
        """The displacement the Gamma3 terms act on, at the local Gamma3 nodes (owned and
        ghost): u (one body), or w = [u] - d nu (two bodies: the relative displacement less
        the initial distance; also stored in the Function ``w``); collective with pairs.

        Returns:
            (m, d) values in ``gamma3_local_nodes`` order.
        """
        d, nodes = self.disc.dim, self.disc.gamma3_local_nodes
        if self.w is None:
            return self.u.x.array.reshape(-1, d)[nodes]
        self.disc.pair_operators.jump(self.u.vector, self.w.vector)
        self.w.x.scatter_forward()
        return self.w.x.array.reshape(-1, d)[nodes]

    def contact_law(self, const=None, x=None, section=None) -> ContactLaw:
        """The contact laws of the run: the case's (app/model/contact_laws.py:
        ``contact_law``) with the parts given to the problem replaced (``replace_laws``); the
        forms, the condensed solver and the reports all read them here.

        Args:
            const: (name, value) -> the parameter (the forms' Constants); None: numbers.
            x: where a parameter of x, y, z is evaluated (a UFL SpatialCoordinate or the
                nodes' coordinates), or None.
            section: the set of laws (``Contact.sections``: a pair's own), or None: the
                case's contact section.

        Returns:
            The ContactLaw.

        Raises:
            CaseError: a replacement the case's contact section cannot take.
        """
        section = self.case.contact if section is None else section
        law = contact_law(section, self.case.numerics.delta, const, x)
        try:
            return replace_laws(law, self.contact_replacements)
        except ValueError as e:
            raise CaseError(f"{self.case.source}: {e}") from None

    def section_laws(self, const=None, x=None) -> list[ContactLaw]:
        """The contact laws of each set of laws of the run (``Contact.sections``: one, or
        one per pair where the pairs' laws differ), as ``contact_law`` builds them.

        Args:
            const: (name, value) -> the parameter (the forms' Constants; a pair's are
                named "pairs[i].<name>", delta is shared); None: numbers.
            x: where a parameter of x, y, z is evaluated, or None.

        Returns:
            The ContactLaws in the order of ``Contact.sections``.

        Raises:
            CaseError: a replacement the case's contact section cannot take.
        """
        sections = self.case.contact.sections
        if len(sections) == 1:
            return [self.contact_law(const, x)]
        out = []
        for i, section in enumerate(sections):
            named = None if const is None else (
                lambda name, value, i=i: _shared_delta(const, name, value) if name == "delta"
                else const(f"pairs[{i}].{name}", value))
            out.append(self.contact_law(named, x if varies_in_space(section) else None,
                                        section))
        return out

    def _contact_data(self) -> ContactData:
        """The Gamma3 part of J_n: the normal field and the laws' parameters."""
        c = self.case.contact
        law = self.contact_law(self.constants, ufl.SpatialCoordinate(self.disc.mesh)
                               if varies_in_space(c) else None)
        return ContactData(
            self.ds_c, self.disc.normal_ufl(), law=law,
            theta=self.theta.function if self.theta else None,
            xi=self.xi.function if self.xi else None)

    def _pair_contact_data(self) -> list[ContactData]:
        """The Gamma3 part of J_n of two bodies: one ContactData, or with laws per pair one
        per pair on its surface's facets (the factors xi, theta only where its laws have
        them)."""
        sections = self.case.contact.sections
        if len(sections) == 1:
            return [self._contact_data()]
        disc = self.disc
        c, ft, nu = self.case.numerics, disc.body.facet_tags, disc.normal_ufl()
        x = ufl.SpatialCoordinate(disc.mesh)
        out = []
        for pair, section, law in zip(self.case.contact.pairs, sections,
                                      self.section_laws(self.constants, x)):
            fr = section.friction
            out.append(ContactData(
                gamma3_measure(disc.mesh, ft, (disc.tags[pair.surface],), c.quadrature,
                               c.gauss_degree), nu, law=law,
                theta=self.theta.function if fr is not None and (
                    fr.slip is not None or fr.coulomb is not None) else None,
                xi=self.xi.function if section.memory is not None else None))
        return out

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
        return fem.Function(self.disc.Q)

    @cached_property
    def _eps_expr(self):
        return fem.Expression(eps(self.u), self.disc.Q.element.interpolation_points())

    @cached_property
    def boundary_layer(self) -> BoundaryLayer:
        """The nodal forces at the nodes of the Dirichlet groups, of Gamma3, of the pairs'
        targets and of the rigid caps (app/model/layer.py); built when first used
        (collective)."""
        refs = [g.name for g in self.disc.dirichlet.groups] \
            + list(self.case.boundaries.contact) + [q.target for q in self.case.contact.pairs] \
            + list(self.case.loads.rigid)      # two bodies: the targets; the rigid caps
        return BoundaryLayer(self, refs)

    @cached_property
    def load_vector(self) -> LoadVector | None:
        """f_n at the nodes (app/model/loadvector.py), or None without loads; built when
        first used (collective)."""
        return LoadVector(self.forms.loads, self.time_data) if self.forms.loads is not None \
            else None

    # ------------------------------------------------------------------ initial values
    def set_initial_values(self) -> None:
        """u = u0, H_0 = sigma0 - E eps(u0) (3.2), kappa = kappa0 (3.3) (cell averages) in
        the State.

        Raises:
            CaseError: if the initial values are not finite, kappa0 < 0 somewhere, or u0
                violates u = 0 on Gamma1 or u_nu <= g on Gamma3 (on every rank).
        """
        init, scalar, disc = self.case.initial, self.time_data.scalar, self.disc
        kappa = self.state.kappa
        if init.u0 is not None:
            vec = ufl.as_vector([scalar(c) for c in init.u0])
            self.u.interpolate(fem.Expression(vec, disc.V.element.interpolation_points()))
            self.u.x.scatter_forward()
            self._check_initial_u()
        if self.H is not None:
            H0 = -self.elastic_operator(eps(self.u))
            if init.sigma0 is not None:
                H0 = H0 + ufl.as_matrix([[scalar(c) for c in row]
                                         for row in init.sigma0])
            disc.cell_average(H0, self.H)
            disc.refuse(not np.isfinite(self.H.x.array).all(), "initial.sigma0",
                        "not a finite number in a cell of the mesh")
        if kappa is not None and self.materials:
            for g in self.materials.groups:
                if g.law is not None:
                    self._set_kappa0(g.material.viscoplastic.kappa0, g.rows, g.law.m,
                                     f"materials.{g.ref}.viscoplastic.kappa0")
        elif kappa is not None:
            vp = self.case.material.viscoplastic
            k0 = vp.kappa0 if vp is not None else 0.0     # a law given to an elastic case
            self._set_kappa0(k0, slice(None), self.state.m, "material.viscoplastic.kappa0")

    def _set_kappa0(self, k0, rows, m: int, key: str) -> None:
        """kappa = kappa0 (3.3) on the cells ``rows``, in each of the law's m components (a
        number, or the cell averages of an expression of x, y, z, refused if negative)."""
        if isinstance(k0, str):
            work = fem.Function(self.disc.Y)
            self.disc.cell_average(self.time_data.scalar(k0), work)
            k0 = work.x.array[rows][:, None]
            self.disc.refuse(not (k0 >= 0).all(), key,
                             "must be a finite number >= 0 everywhere")
        self.state.kappa_cells[rows, :m] = k0

    def _check_initial_u(self) -> None:
        """u0 at the mesh nodes: zero on Gamma1 (up to round-off of its largest value),
        u_nu <= g on Gamma3 (the case's validation checked sample points already)."""
        disc = self.disc
        uu = self.u.x.array.reshape(-1, disc.dim)
        disc.refuse(not np.isfinite(uu).all(), "initial.u0",
                    "not a finite number at a node of the mesh")
        scale = disc.reduce(float(np.abs(uu).max(initial=0.0)), "MAX")
        disc.refuse(np.abs(uu[disc.clamped_nodes]).max(initial=0.0) > 1e-12 * scale,
                    "initial.u0", "must vanish on Gamma1 (boundaries.clamped)")
        fr = disc.frames
        if fr is not None and fr.g is not None:
            u_nu = np.einsum("ij,ij->i", uu[fr.nodes], fr.normal)
            disc.refuse((fr.bounded & (u_nu > fr.g + 1e-12 * np.maximum(fr.g, scale))).any(),
                        "initial.u0", "violates u_nu <= g on Gamma3")

    def update_sigma(self) -> tuple[float, float] | None:
        """sigma_n = E eps(u_n) + H_n (3.2) and its von Mises norm, per cell.

        Returns:
            (||u_n||_V, ||sigma_n||_Q) where the compiled cell pass computed them on the way
            (the step record's norms without a second pass), else None.
        """
        sums = self.strain_operator.update_sigma(self.u, self.H, self.sigma, self.sigma_vm)
        if sums is None or self.full_stress is not None:
            self.update_vm()
        if sums is None:
            return None
        return float(np.sqrt(max(sums[0], 0.0))), float(np.sqrt(max(sums[1], 0.0)))

    def current_stress(self) -> None:
        """Make sigma the stress of the current u inside a step (Coulomb's fixed point reads
        the nodal forces between solves): E eps(u) + H_n (3.2); the implicit variant's
        residual hook has set it at the solver's last residual already."""
        if not self.implicit:
            self.update_sigma()

    def update_vm(self) -> None:
        """sigma_vm = ||sigma||_VM per cell, from sigma: the 3D norm; in 2D plane strain
        with sigma_33 (set here from sigma and kappa, app/model/fullstress.py)."""
        el = self.elasticity
        t = el.to_voigt(self.sigma.x.array)
        fs = self.full_stress
        if fs is None:
            self.sigma_vm.x.array[:] = el.von_mises(t)
        else:
            s33 = fs.sigma_33(t, self.state.kappa_cells)
            self.sigma_33.x.array[:] = s33
            self.sigma_vm.x.array[:] = fs.von_mises(t, s33)
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
            False if the update failed on some rank (the residual is then NaN on every
            rank, so that the assembly stays collective), else True.
        """
        if self.implicit_update is None:
            return True
        ok = self.implicit_update.trial(self, self.k)
        comm = self.disc.comm
        return ok if comm.size == 1 else comm.allreduce(ok, op=MPI.LAND)


def _shared_delta(const, name: str, value):
    """The one Constant delta of every pair's laws (the delta continuation of SNES VI
    changes it: app/solvers/snesvi.py)."""
    return const[name] if name in const else const(name, value)

