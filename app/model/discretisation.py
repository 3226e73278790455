"""The discretisation of a case: the mesh and its spaces, the named boundary groups, the
Dirichlet data, and the Gamma3 nodes with their weights, normals, frames and gaps.

V^h = continuous P1 vectors, Q^h = DG0 tensors (sigma, H_n), Y^h = DG0 scalars (kappa for
m = 1, sigma_vm).  Everything here is fixed for a run, and so is what is built from it
alone: the box bounds of U^h on the normal dofs of the Gamma3 nodes, the normal of the
forms, the pairs' linear maps.  The step problem (app/model/problem.py) holds it as
``disc`` and builds its forms on it, the State (app/model/state.py) its fields, the step
solvers and the derived quantities (app/post/quantities.py) read its groups and Gamma3
nodes.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import ufl
from dolfinx import cpp as dcpp
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact.case import Case, CaseError
from vpcontact.forms.contact import gamma3_measure
from vpcontact.meshes.bodycheck import interior_role
from vpcontact.model.dirichlet import build_dirichlet, check_rigid_motions
from vpcontact.model.frames import ContactFrames, build_frames, facet_normals, gap_values
from vpcontact.model.loads import TimeData
from vpcontact.model.pairs import PairOperators, node_labels, project_pairs
from vpcontact.model.rigidcap import build_caps


@dataclass
class Gamma3Nodes:
    """The locally owned Gamma3 nodes (not on Gamma1), with their weights."""

    nodes: np.ndarray    # local node (block) indices, owned, sorted by coordinates
    x: np.ndarray        # (m, d) coordinates
    weight: np.ndarray   # int_Gamma3 phi_i ds (the nodal rule's weight)



class Discretisation:
    """The spaces, boundary groups, Dirichlet data and Gamma3 nodes of a case on a mesh.

    Args:
        case: the validated case.
        body: the mesh with its facet tags and named boundary groups (meshes.RectangleMesh,
            BoxMesh or FileMesh).
        time_data: the loads' time constants (the prescribed displacements' data).

    Attributes:
        case, body: the case and the mesh with its groups (as given).
        mesh, comm, dim: the mesh, its communicator and dimension d.
        V, Q, Y: the spaces V^h (P1 vectors), Q^h (DG0 tensors), Y^h (DG0 scalars).
        tags: group reference -> facet tag; ``facets`` group reference -> facets.
        dirichlet: the Dirichlet data (Gamma1 and loads.displacement); ``bcs`` its conditions.
        caps: the rigid caps (app/model/rigidcap.py), or None.
        gamma3: the owned Gamma3 nodes and their weights, or None without contact.
        gamma3_local_nodes: the local (owned and ghost) Gamma3 nodes carrying contact.
        frames: the nodal normals, frames and gaps of Gamma3 (owned and ghost nodes), or None.
        pairs: the projection of the Gamma3 nodes onto their targets (two bodies,
            app/model/pairs.py), or None.

    Raises:
        CaseError: a group the mesh lacks, a role on the wrong group, no support.
    """

    def __init__(self, case: Case, body, time_data: TimeData):
        self.case, self.body, self.time_data = case, body, time_data
        msh = self.mesh = body.mesh
        self.comm = msh.comm
        self.dim = msh.topology.dim
        self.V = fem.VectorFunctionSpace(msh, ("CG", 1))
        self.Q = fem.TensorFunctionSpace(msh, ("DG", 0))
        self.Y = fem.FunctionSpace(msh, ("DG", 0))
        self._setup_boundaries()
        self.gamma3 = self.frames = self.pairs = None
        self.gamma3_local_nodes = None
        if case.contact.active:
            self.gamma3 = self._gamma3_nodes()
            if case.contact.pairs:      # two bodies: app/model/pairs.py
                nodes = self.gamma3_local_nodes
                self.pairs = project_pairs(self, nodes, self.facet_normals[nodes])
            self.frames = self._frames()

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
        pairs = case.contact.pairs        # two bodies: Gamma3 is the pairs' surfaces
        contact = [(p.surface, f"contact.pairs[{i}].surface") for i, p in enumerate(pairs)] \
            if pairs else [(r, "boundaries.contact") for r in b.contact]
        keys = [(r, "boundaries.clamped") for r in b.clamped] + contact + \
            [(r, f"loads.traction.{r}") for r in loads.traction] + \
            [(r, f"loads.pressure.{r}") for r in loads.pressure] + \
            [(r, f"loads.displacement.{r}") for r in loads.displacement] + \
            [(r, f"loads.rigid.{r}") for r in loads.rigid] + \
            [(p.target, f"contact.pairs[{i}].target") for i, p in enumerate(pairs)]
        self.tags = {ref: self.group_tag(ref, key) for ref, key in keys}
        for i, p in enumerate(pairs):
            if self.tags[p.surface] == self.tags[p.target]:
                raise CaseError(f"{case.source}: contact.pairs[{i}]: surface {p.surface!r} and "
                                f"target {p.target!r} are the same group (physical tag "
                                f"{self.tags[p.target]}); a pair is two surfaces facing "
                                "each other")
        self._check_roles()
        for ref, key in keys:                   # a role on an embedded curve: refused
            if (why := interior_role(self.body, key, ref, self.tags[ref])) is not None:
                raise CaseError(f"{case.source}: {why}")
        self.facets = {ref: ft.indices[ft.values == tag] for ref, tag in self.tags.items()}
        taken = [(r, "boundaries.clamped") for r in b.clamped] + \
            (contact if case.contact.active else []) + \
            [(p.target, f"contact.pairs[{i}].target") for i, p in enumerate(pairs)]
        self.caps = build_caps(self.V, self.facets, loads.rigid, case.source,
                               self._group_nodes(taken), self._group_nodes(
                                   [(r, f"loads.displacement.{r}") for r in loads.displacement]))
        self.dirichlet = build_dirichlet(self.V, self.facets, list(b.clamped),
                                         dict(loads.displacement), self.time_data,
                                         None if self.caps is None else self.caps.nodes)
        self.bcs = self.dirichlet.bcs
        foundation = np.concatenate([self.facets[r] for r in b.contact]) \
            if case.contact.active and not pairs else None
        self.held_by_contact = check_rigid_motions(
            self.V, self.dirichlet.fixed, case.source,
            [(self.facets[p.surface], self.facets[p.target]) for p in pairs], self.caps,
            foundation)
        self.clamped_nodes = self.dirichlet.clamped_nodes

    def _group_nodes(self, keys: list) -> dict:
        """Case key -> the local nodes of its group (for the caps' shared-node rule)."""
        fdim = self.dim - 1
        return {key: fem.locate_dofs_topological(self.V, fdim, self.facets[ref])
                for ref, key in keys} if self.case.loads.rigid else {}

    def _check_roles(self) -> None:
        """The rules validation applies to the groups' spellings (app/case/rules.py: no group
        twice in a role, clamped and contact disjoint, no load on a clamped group nor, in a
        case with contact, on Gamma3), applied to the groups themselves: a group's name and
        its physical tag are one group.

        Raises:
            CaseError: naming both spellings and the tag.
        """
        b, loads, source = self.case.boundaries, self.case.loads, self.case.source
        roles = [("boundaries.clamped", b.clamped), ("boundaries.contact", b.contact)] + \
            [(f"loads.{kind}", tuple(getattr(loads, kind)))
             for kind in ("traction", "pressure", "displacement", "rigid")]
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

    def gamma3_facet_coordinates(self) -> np.ndarray:
        """The vertex coordinates of this rank's Gamma3 facets (contact.xdmf's facet mesh).

        Returns:
            Shape (facets, vertices per facet, 3).
        """
        msh, fdim = self.mesh, self.dim - 1
        facets = np.unique(np.concatenate([self.facets[r] for r in self.case.boundaries.contact]
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
        facets = np.concatenate([self.facets[r] for r in self.case.boundaries.contact])
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
        raw = self.facet_normals[nodes] if self.pairs is None else self.pairs.normal
        frames = build_frames(self.V, nodes, raw, self.dirichlet.fixed[nodes], c.direction,
                              self.case.source)
        if self.pairs is not None:        # the bound w_nu = [u]_nu - d <= g of each pair
            frames.g = self.pairs.g.copy()
        elif c.g is not None:
            x = self.V.tabulate_dof_coordinates()[nodes, :self.dim]
            frames.g = gap_values(c.g, x, self.case.source, self.comm)
        return frames

    @cached_property
    def facet_normals(self) -> np.ndarray:
        """The area-weighted outward unit normals of Gamma3 at all local nodes."""
        return facet_normals(self.V, self.gamma3_exact_measure())

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
        return float(self.reduce(float(np.max(fr.g, initial=0.0)), "MAX"))

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

    def cell_volumes(self) -> np.ndarray:
        """The volumes |c| of the local cells (Y^h's dof order; assembled when first used).

        Returns:
            (owned cells,) volumes.
        """
        if not hasattr(self, "_vol"):
            w = ufl.TestFunction(self.Y)
            vec = fem.petsc.assemble_vector(fem.form(w * ufl.dx))
            self._vol = vec.array_r.copy()
            vec.destroy()
        return self._vol

    def cell_average(self, expr, f) -> None:
        """f = P_{Q^h} expr, the L2 projection onto DG0 (cell averages).

        Args:
            expr: a UFL expression of the shape of f's values.
            f: a DG0 Function (on Q^h or Y^h); its owned and ghost values are set.
        """
        w = ufl.TestFunction(f.function_space)
        vec = fem.petsc.assemble_vector(fem.form(ufl.inner(expr, w) * ufl.dx))
        bs = f.function_space.dofmap.index_map_bs
        owned = vec.array.size
        vol = np.repeat(self.cell_volumes()[:owned // bs], bs)
        f.x.array[:owned] = vec.array / vol
        f.x.scatter_forward()
        vec.destroy()

    def reduce(self, value: float, op) -> float:
        """``value`` reduced over the ranks; collective.

        Args:
            value: this rank's value.
            op: the MPI operation's name ("SUM", "MAX", ...).

        Returns:
            The reduced value.
        """
        if self.comm.size == 1:
            return value
        return self.comm.allreduce(value, op=getattr(MPI, op))

    def refuse(self, bad: bool, key: str, why: str) -> None:
        """Raise CaseError on every rank if ``bad`` on any (the exact check on the mesh).

        Args:
            bad: this rank's verdict.
            key: the case key at fault.
            why: the message.

        Raises:
            CaseError: on every rank, if ``bad`` on some rank.
        """
        if self.comm.allreduce(bool(bad), op=MPI.LOR):
            raise CaseError(f"{self.case.source}: {key}: {why}")

    # ------------------------------------------------------------------ Gamma3
    @cached_property
    def pair_node_labels(self) -> np.ndarray:
        """The local nodes' pair labels (1 surface, 2 target, 0 neither; app/model/pairs.py
        ``node_labels``), for checkpoints; collective when first used."""
        return node_labels(self)

    @cached_property
    def pair_operators(self) -> PairOperators:
        """The jump B, the normal coupling S and the offsets of the pairs (two bodies,
        app/model/pairs.py: ``PairOperators``); built when first used (collective)."""
        return PairOperators(self)

    def normal_ufl(self):
        """nu in the forms of J_n (3.4): a constant vector where every Gamma3 node has the
        same normal (a flat Gamma3 or a fixed direction), else the P1 field of the nodal
        normals (exact at the nodes, where the nodal rule evaluates the Gamma3 terms);
        collective.

        Returns:
            A UFL vector or a Function on V^h.
        """
        nu = self.frames.normal
        first = nu[0] if len(nu) else None
        firsts = [f for f in self.comm.allgather(first) if f is not None]
        ref = firsts[0] if firsts else np.zeros(self.dim)
        same = np.abs(nu - ref).max(initial=0.0) <= 1e-12 and all(
            np.abs(f - ref).max() <= 1e-12 for f in firsts)
        if self.comm.allreduce(bool(same), op=MPI.LAND):
            return ufl.as_vector([float(v) for v in ref])
        field = fem.Function(self.V, name="nu")
        arr = field.x.array.reshape(-1, self.dim)
        arr[:] = self.facet_normals
        arr[self.frames.nodes] = nu
        return field

    def bounds(self, like: PETSc.Vec) -> tuple[PETSc.Vec, PETSc.Vec]:
        """Box bounds of U^h (3.4): u_nu <= g at the Gamma3 nodes, in the nodal frames (the
        dof ``slot`` of node i is sign_i u_nu), +-inf elsewhere.

        Args:
            like: a vector of V^h (u's) whose layout the bounds take.

        Returns:
            (lower, upper) bound vectors like ``like`` (owned and ghost entries set).
        """
        lb, ub = like.duplicate(), like.duplicate()
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
