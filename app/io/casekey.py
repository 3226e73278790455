"""The normalised case a checkpoint belongs to: the sections of ``case_fingerprint``
(app/io/checkpoint.py: mesh, material(s), contact, loads, initial values, boundaries; not
the solver, PETSc or output settings) with every equivalent spelling made one, so that a
restart of the same case written another way is accepted and a real change still refused:

- the defaults the case model fills (app/case/model.py) written out: a pair's ``rule``
  (mortar) and ``g`` (0), a viscoplastic law's ``law`` (perzyna), a mesh.file's ``size``
  (1); an empty section or a key set to null is the section or key left out;
- numbers as floats (``E: 1000`` is ``E: 1000.0``; no key's meaning depends on the
  difference);
- groups by their physical tags: a boundary list, a load's group, a pair's surface and
  target (facet groups) and a ``materials`` key (cell groups) named by a name or by its tag
  are the same group.  The names' tags are the mesh's, stored in the checkpoint
  (``group_map``) when it is written: the mesh.file digest in the fingerprint makes the
  restart's mesh the same, so its names have the same tags.
"""
from __future__ import annotations

import copy

SECTIONS = ("mesh", "material", "contact", "loads", "initial", "boundaries")
# the maps of loads keyed by boundary group: a name, or (YAML's integer keys) a physical tag
GROUP_MAPS = ("traction", "pressure", "displacement", "rigid")


def group_map(body) -> dict:
    """The physical names of a body's groups and their tags, for ``normalised_sections``.

    Args:
        body: the mesh's body (app/simulation.build_mesh): ``groups`` (facets) and, for a
            mesh.file, ``cell_groups``.

    Returns:
        {"facets": {name: tag}, "cells": {name: tag}}, JSON-storable.
    """
    return {"facets": {str(k): int(v) for k, v in getattr(body, "groups", {}).items()},
            "cells": {str(k): int(v) for k, v in getattr(body, "cell_groups", {}).items()}}


def normalised_sections(case, groups: dict) -> dict:
    """The case's fingerprinted sections, normalised (see the module's docstring).

    Args:
        case: the validated Case (``case.raw``: its sections with the schema's defaults).
        groups: ``group_map`` of the mesh the checkpoint was written on.

    Returns:
        {section: data} of the sections present (an absent or empty section left out).
    """
    data = {k: copy.deepcopy(case.raw[k]) for k in SECTIONS if case.raw.get(k) is not None}
    if "materials" in case.raw:
        data["materials"] = copy.deepcopy(case.raw["materials"])
    _fill_model_defaults(data, case)
    _resolve_groups(data, groups.get("facets", {}), groups.get("cells", {}))
    return _plain(data)


def _fill_model_defaults(data: dict, case) -> None:
    """The defaults app/case/model.py fills rather than the schema (case.raw lacks them)."""
    for p, pair in zip((data.get("contact") or {}).get("pairs") or [], case.contact.pairs):
        p["rule"], p["g"] = pair.rule, pair.g
    materials = [data.get("material")] + list((data.get("materials") or {}).values())
    for m in materials:
        if isinstance(m, dict) and isinstance(m.get("viscoplastic"), dict):
            m["viscoplastic"].setdefault("law", "perzyna")
    if case.mesh.file is not None:     # the files' content is in the fingerprint, not
        data["mesh"]["size"] = case.mesh.size      # their names
        data["mesh"].pop("file", None)


def _resolve_groups(data: dict, facets: dict, cells: dict) -> None:
    """Group names replaced by their tags where the mesh has them."""
    def tag(ref, names):
        return names.get(ref, ref) if isinstance(ref, str) else ref

    bounds = data.get("boundaries") or {}
    for key, refs in bounds.items():
        if isinstance(refs, list):
            bounds[key] = [tag(r, facets) for r in refs]
    loads = data.get("loads") or {}
    for kind in GROUP_MAPS:
        if isinstance(loads.get(kind), dict):
            loads[kind] = {tag(r, facets): v for r, v in loads[kind].items()}
    for p in (data.get("contact") or {}).get("pairs") or []:
        for role in ("surface", "target"):
            p[role] = tag(p[role], facets)
    if isinstance(data.get("materials"), dict):
        data["materials"] = {tag(r, cells): v for r, v in data["materials"].items()}


def _plain(x):
    """Numbers as floats (bools kept), empty sections and null keys left out."""
    if isinstance(x, dict):
        out = {k: _plain(v) for k, v in x.items() if v is not None}
        return {k: v for k, v in out.items() if v != {}}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, int) and not isinstance(x, bool):
        return float(x)
    return x
