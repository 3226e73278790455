"""A body of several materials (the case's ``materials``: one per physical group of cells of a
mesh.file): each group's cells, its elasticity E and its viscoplastic law (G, Gk) of
(1.2)-(1.3), and the history update (3.2)-(3.3) of the whole body from the groups' laws.

The cells of a group are the rows of the DG0 fields (sigma, H, kappa; owned and ghost cells,
so that every local cell has its material and the ghosts are updated like the owned cells
without communication).  Each group's law is built with the group's own (homogeneous)
elasticity and updates only its rows: the rows are gathered, the law's update (Perzyna's
compiled one where it can be) runs on them, and the results are scattered back; a group
without a law keeps H_n = H_{n-1} and its kappa at 0.

Laws with different numbers m of internal variables may be mixed: kappa has m = the largest
over the groups, and a group's law reads and writes the first m_g components of its rows
(the others stay 0 there).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from vpcontact.case import Case, CaseError
from vpcontact.case.materialrules import renamed
from vpcontact.forms.elasticity import plane_strain_moduli
from vpcontact.model.lawregistry import viscoplastic_law
from vpcontact.model.material import CellElasticity, Elasticity
from vpcontact.model.stiffness import case_elasticity, global_bounds


@dataclass
class MaterialGroup:
    """One material of the body and its cells.

    Attributes:
        ref: the group as the case names it (a name, or a physical tag).
        tag: its physical tag.
        rows: the local rows (owned and ghost cells) of the DG0 fields in the group.
        material: the case's Material of the group.
        elasticity: E in the group (plane strain taken into the plane-stress moduli).
        law: the group's viscoplastic law, or None (an elastic group).
    """

    ref: object
    tag: int
    rows: np.ndarray
    material: object
    elasticity: object
    law: object = None


def material_elasticity(material, dim: int, Q, path: str, source: str):
    """The elasticity of one material: the general one of app/model/stiffness.py (E(x),
    orthotropic, voigt), else isotropic with numbers (plane strain by the moduli of
    forms.elasticity.plane_strain_moduli); collective.

    Args:
        material: the case's Material.
        dim: the space dimension.
        Q: the DG0 tensor space.
        path: the material's key path (e.g. "materials.steel"), for messages.
        source: the case file, for messages.

    Returns:
        An Elasticity, MatrixElasticity or CellElasticity (over every row).

    Raises:
        CaseError: for elasticity data outside H(E).
    """
    try:
        general = case_elasticity(material, dim, Q)
    except ValueError as e:
        raise CaseError(renamed(f"{source}: {e}", path)) from None
    if general is not None:
        return general
    E, nu = (plane_strain_moduli(material.E, material.nu)
             if dim == 2 and material.plane == "strain" else (material.E, material.nu))
    return Elasticity(E, nu, dim)


def cell_rows(body, Q) -> tuple[np.ndarray, np.ndarray]:
    """The physical tag of every local cell, by row of the DG0 fields.

    Args:
        body: the FileMesh (its ``cell_tags``).
        Q: a DG0 space (its dofmap orders the rows).

    Returns:
        (rows, tags): the rows of the tagged local cells and their tags; a local cell
        without a tag has no row here.
    """
    ct = body.cell_tags
    dofs = Q.dofmap.list.array            # one DG0 block per cell: the cell's row
    return dofs[ct.indices], np.asarray(ct.values)


def _tag_of(ref, body, tags: list, source: str) -> int:
    """The physical tag of a group of cells named by the case (a name or a tag)."""
    names = getattr(body, "cell_groups", {})
    if isinstance(ref, str) and ref in names:
        return names[ref]
    if isinstance(ref, int) and ref in tags:
        return ref
    dims = {**getattr(body, "other_groups", {}),
            **dict.fromkeys(getattr(body, "groups", {}), body.dim - 1)}
    hint = f"; {ref!r} is a group of dimension {dims[ref]}" if ref in dims else ""
    raise CaseError(f"{source}: materials.{ref}: no physical group of cells {ref!r} in the "
                    f"mesh (names: {', '.join(sorted(names)) or 'none'}; numbers: "
                    f"{', '.join(map(str, tags)) or 'none'}){hint}")


@dataclass
class BodyMaterials:
    """The materials of a body: its groups, E per cell and the law of the whole body.

    Attributes:
        groups: the MaterialGroups, in the case's order.
        elasticity: the CellElasticity of the body (each group's E on its rows).
        law: the GroupLaws, or None where no group has a viscoplastic law.
    """

    groups: list
    elasticity: CellElasticity
    law: object = None

    def cell_counts(self, n_owned: int, comm) -> list[tuple[object, int, int]]:
        """The number of cells of each group (all ranks); collective.

        Args:
            n_owned: the number of owned rows (the others are ghosts).
            comm: the mesh's communicator.

        Returns:
            [(group, physical tag, cells)] in the case's order.
        """
        return [(g.ref, g.tag, int(comm.allreduce(int((g.rows < n_owned).sum()))))
                for g in self.groups]

    def describe(self) -> dict:
        """The groups' elasticities (summary.json's "laws", ``check``).

        Returns:
            {"name": "materials: <group> (<E>), ...", "constants": {}, "groups": {group:
            {"E", "nu", "plane"} (isotropic with numbers) or the elasticity's kind}}.
        """
        groups = {}
        for g in self.groups:
            m = g.material
            groups[str(g.ref)] = {"E": m.E, "nu": m.nu, "plane": m.plane} \
                if isinstance(g.elasticity, Elasticity) else {"kind": type(g.elasticity).__name__}
        text = ", ".join(f"{ref} ({', '.join(f'{k} = {v}' for k, v in d.items())})"
                         for ref, d in groups.items())
        return {"name": f"materials: {text}", "constants": {}, "groups": groups}


def body_materials(case: Case, body, Q) -> BodyMaterials:
    """The groups of ``case.materials`` on the mesh, E per cell, the body's law; collective.

    Args:
        case: the validated case (with ``materials``).
        body: the FileMesh.
        Q: the DG0 tensor space (the rows).

    Returns:
        The BodyMaterials.

    Raises:
        CaseError: as ``material_groups``.
    """
    groups = material_groups(case, body, Q)
    n = len(Q.dofmap.list.array)
    pieces = CellElasticity.from_pieces(n, [(g.rows, g.elasticity) for g in groups],
                                        Q.mesh.topology.dim)
    el = CellElasticity(pieces.mats, pieces.index, pieces.dim,
                        global_bounds(pieces, Q.mesh.comm))
    laws = any(g.law is not None for g in groups)
    return BodyMaterials(groups, el, GroupLaws(groups, el) if laws else None)


def material_groups(case: Case, body, Q) -> list[MaterialGroup]:
    """The groups of ``case.materials`` on the mesh; collective.

    Args:
        case: the validated case (with ``materials``).
        body: the FileMesh.
        Q: a DG0 space (the rows).

    Returns:
        The MaterialGroups, in the case's order.

    Raises:
        CaseError: on every rank, for a group the mesh does not have, a group given twice
            (its name and its tag), or cells of the body in no group of ``materials``.
    """
    rows, tags = cell_rows(body, Q)
    comm, source, dim = Q.mesh.comm, case.source, Q.mesh.topology.dim
    body_tags = sorted(set().union(*comm.allgather({int(t) for t in tags})))
    groups, seen = [], {}
    for ref, material in case.materials.items():
        tag = _tag_of(ref, body, body_tags, source)
        if tag in seen:
            raise CaseError(f"{source}: materials: {seen[tag]!r} and {ref!r} are the same "
                            f"group (physical tag {tag}); give it once")
        seen[tag] = ref
        el = material_elasticity(material, dim, Q, f"materials.{ref}", source)
        groups.append(MaterialGroup(ref, tag, np.sort(rows[tags == tag]), material, el,
                                    viscoplastic_law(material.viscoplastic, el,
                                                     material.plane)))
    n_owned = Q.dofmap.index_map.size_local
    n_local = n_owned + Q.dofmap.index_map.num_ghosts
    covered = np.zeros(n_local, dtype=bool)
    for g in groups:
        covered[g.rows] = True
    missing = int(comm.allreduce(int((~covered[:n_owned]).sum())))
    ghosts = comm.allreduce(bool((~covered[n_owned:]).any()), op=MPI.LOR)
    if missing or ghosts:
        left = sorted(set(body_tags) - set(seen))
        raise CaseError(f"{source}: materials: {missing} cell(s) of the body are in no group "
                        f"of materials (physical groups of cells without a material: "
                        f"{', '.join(map(str, left)) or 'none'}); give every group of the "
                        "body a material")
    return groups


class GroupLaws:
    """The viscoplastic law of a body of several materials: each group's law on its cells.

    It gives what a run asks of a ViscoplasticLaw (app/model/laws.py): ``m``, ``explicit()``
    (the update (3.2)-(3.3) by group), ``implicit()`` (the backward-Euler local solve by
    group), ``rates`` on all rows, the constants of the stability indicator (the largest of
    the groups': the explicit update is stable where every group's is) and ``describe()``.

    Args:
        groups: the MaterialGroups (those without a law are elastic).
        elasticity: E of the whole body (per cell).
    """

    name = "materials"

    def __init__(self, groups: list[MaterialGroup], elasticity):
        self.groups = groups
        self.flowing = [g for g in groups if g.law is not None]
        self.elasticity = elasticity
        self.m = max(g.law.m for g in self.flowing)
        self.uses_eps = any(getattr(g.law, "uses_eps", False) for g in self.flowing)

    def _largest(self, method: str) -> float | None:
        """The largest of the groups' ``method()``, None if one of them does not know."""
        values = [getattr(g.law, method)() for g in self.flowing]
        return None if any(v is None for v in values) else max(values)

    def relaxation_rate(self) -> float | None:
        """Returns: the largest r_max of the groups' laws (None if one does not know it)."""
        return self._largest("relaxation_rate")

    def lipschitz_constant(self) -> float | None:
        """Returns: the largest L_G of the groups' laws (None if one does not know it)."""
        return self._largest("lipschitz_constant")

    @property
    def hardens(self) -> bool:
        """Returns: whether every group's law hardens (ViscoplasticLaw.hardens)."""
        return all(getattr(g.law, "hardens", False) for g in self.flowing)

    def rate_at_stress(self, S: float) -> float | None:
        """The largest of the groups' laws' rates at the stress scale S.

        Args:
            S: the stress scale [Pa].

        Returns:
            r(S) [1/s], None if one group's law does not know it.
        """
        values = [getattr(g.law, "rate_at_stress", lambda _: None)(S) for g in self.flowing]
        return None if any(v is None for v in values) else max(values)

    def constants(self) -> dict:
        """Returns: {} (the groups' constants are in ``describe()``)."""
        return {}

    def describe(self) -> dict:
        """The groups' laws (summary.json's "laws", ``check``).

        Returns:
            {"name": "materials", "m", "constants": {}, "lipschitz_constant", "groups":
            {group: the law's describe() or None (elastic)}}.
        """
        laws = ", ".join(f"{g.ref} {g.law.name if g.law is not None else 'elastic'}"
                         for g in self.groups)
        return {"name": f"{self.name}: {laws}", "m": self.m, "constants": {},
                "lipschitz_constant": self.lipschitz_constant(),
                "groups": {str(g.ref): g.law.describe() if g.law is not None else None
                           for g in self.groups}}

    def rates(self, t: np.ndarray, kappa: np.ndarray, *eps) -> tuple[np.ndarray, np.ndarray]:
        """G and Gk of each group's law on its rows (0 in the elastic groups).

        The rows are the cells the body's elasticity has selected (``rows``; all local
        cells unless a caller selected some, e.g. one cell repeated for a difference
        quotient: app/post/diagnostics.estimated_rate).

        Args:
            t: rows (n, mt) of sigma in t-coordinates, one per selected cell.
            kappa: (n, m) internal variables.
            eps: the strain rows, for a law that ``uses_eps``.

        Returns:
            (G rows (n, mt), Gk (n, m)).

        Raises:
            ValueError: if the rows are not the selected cells.
        """
        cells = getattr(self.elasticity, "selected", None)
        cells = np.arange(len(t)) if cells is None else cells
        if len(cells) != len(t):
            raise ValueError(f"materials: {len(t)} rows for {len(cells)} selected cells")
        G, Gk = np.zeros_like(t), np.zeros_like(kappa)
        for g in self.flowing:
            mine, mg = np.isin(cells, g.rows), g.law.m
            if not mine.any():
                continue
            extra = (eps[0][mine],) if eps and getattr(g.law, "uses_eps", False) else ()
            with g.elasticity.rows(cells[mine]):
                G[mine], Gk[mine, :mg] = g.law.rates(
                    t[mine], np.ascontiguousarray(kappa[mine, :mg]), *extra)
        return G, Gk

    def explicit(self) -> GroupExplicitUpdate:
        """Returns: the explicit update (3.2)-(3.3) by group."""
        return GroupExplicitUpdate(self.flowing)

    def implicit(self, rtol: float = 1e-12, max_iter: int = 60) -> GroupBackwardEuler:
        """The backward-Euler local solve by group.

        Args:
            rtol: tolerance of the scaled local residual.
            max_iter: local Newton iterations allowed.

        Returns:
            A GroupBackwardEuler.
        """
        return GroupBackwardEuler(self.groups, self.m, rtol, max_iter)


class GroupExplicitUpdate:
    """H_n = H_{n-1} + k_n G(sigma_{n-1}, kappa_{n-1}), kappa likewise (3.2)-(3.3), each
    group's law on its rows (gathered, updated by the law's own update, scattered back).

    Args:
        groups: the MaterialGroups with a law.
    """

    def __init__(self, groups: list[MaterialGroup]):
        self.parts = [(g.rows, g.law.m, g.law.explicit(), g.elasticity) for g in groups]

    def __call__(self, sigma: np.ndarray, H: np.ndarray, kappa: np.ndarray, k: float) -> None:
        """One explicit step of the history terms; nothing is written if a group's fails.

        Args:
            sigma: sigma_{n-1} per cell, flat (ncells * d * d).
            H: H_{n-1} per cell, same layout; becomes H_n.
            kappa: kappa_{n-1}, (ncells, m); becomes kappa_n.
            k: the step k_n.

        Raises:
            RuntimeError: a group's update failed (the state is unchanged).
        """
        n = kappa.shape[0]
        s_rows, h_rows = sigma.reshape(n, -1), H.reshape(n, -1)
        done = []
        for rows, mg, update, el in self.parts:
            h = np.ascontiguousarray(h_rows[rows])
            kap = np.ascontiguousarray(kappa[rows, :mg])
            with el.rows(rows):       # E per cell in the group: its rows (else nothing)
                update(np.ascontiguousarray(s_rows[rows]).reshape(-1), h.reshape(-1), kap, k)
            done.append((rows, mg, h, kap))
        for rows, mg, h, kap in done:
            h_rows[rows] = h
            kappa[rows, :mg] = kap


class GroupBackwardEuler:
    """The implicit variant's local solve (app/model/implicit.py) by group: each group's
    law's BackwardEuler on its rows; an elastic group keeps the trial stress and E as its
    tangent.

    Args:
        groups: the MaterialGroups.
        m: kappa's number of components.
        rtol: tolerance of the scaled local residual.
        max_iter: local Newton iterations allowed.
    """

    def __init__(self, groups: list[MaterialGroup], m: int, rtol: float, max_iter: int):
        self.m = m
        self.parts = [(g.rows, g.elasticity, g.law,
                       g.law.implicit(rtol, max_iter) if g.law is not None else None)
                      for g in groups]

    def solve(self, s_tr: np.ndarray, kappa_prev: np.ndarray, k: float, eps=None):
        """Solve the local system per cell, group by group.

        Args:
            s_tr: (n, mt) trial stresses E eps(u_n) + H_{n-1} in t-coordinates.
            kappa_prev: (n, m) kappa_{n-1}.
            k: the time step k_n.
            eps: (n, mt) the trial strain, for a law that ``uses_eps`` (else None).

        Returns:
            (sigma_n (n, mt), kappa_n (n, m), C_alg (n, mt, mt)).

        Raises:
            LocalFailure: a group's local Newton iteration did not converge.
        """
        n, mt = s_tr.shape
        sigma, kappa = s_tr.copy(), kappa_prev.copy()
        C = np.empty((n, mt, mt))
        for rows, el, law, local in self.parts:
            if local is None:
                with el.rows(rows):
                    C[rows] = el.Cmat
                continue
            mg = law.m
            extra = (eps[rows],) if eps is not None and getattr(law, "uses_eps", False) \
                else ()
            with el.rows(rows):
                sigma[rows], kappa[rows, :mg], C[rows] = local.solve(
                    s_tr[rows], np.ascontiguousarray(kappa_prev[rows, :mg]), k, *extra)
        return sigma, kappa, C
