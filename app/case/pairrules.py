"""The rules of ``contact.pairs`` (two bodies of one mesh.file in contact), on the case as
given, before the schema's defaults are filled: the pairs' laws are lifted into the contact
section (one set of laws for every pair), the pairs' surfaces become Gamma3
(``boundaries.contact``), and what a pair cannot take is refused with the key named.

The result validates to the same case again (the studies validate ``case.raw`` with changed
keys): a case whose laws were lifted and whose boundaries.contact lists the surfaces is
accepted as it is.
"""
from __future__ import annotations

from vpcontact.case.reading import GROUP_MAPS
from vpcontact.io.errors import CaseError

# the contact laws a pair may carry (the contact section's own keys)
LAW_KEYS = ("normal_compliance", "memory", "friction")


def settle_pairs(data: dict, source: str) -> None:
    """Check and settle contact.pairs in place (nothing without pairs).

    Args:
        data: the case mapping after the schema check (changed in place).
        source: the case file, for messages.

    Raises:
        CaseError: pairs without a mesh.file, with contact.g or contact.direction, with a
            boundaries.contact other than the surfaces, a surface that is its own target or
            another pair's target or surface, a clamped or loaded pair group, different
            laws in different pairs.
    """
    contact = data.get("contact") or {}
    pairs = contact.get("pairs")
    if not pairs:
        return
    if "file" not in data["mesh"]:
        raise CaseError(f"{source}: contact.pairs: two bodies need a mesh.file holding both "
                        "(the built-in rectangle and box are one body)")
    for key in ("g", "direction"):
        if key in contact:
            raise CaseError(f"{source}: contact.{key}: not with contact.pairs (a pair's gap is "
                            "the distance measured on the mesh plus the pair's own g; its "
                            "normal is the target's)")
    if data.get("solver", {}).get("quadrature") == "gauss":
        raise CaseError(f"{source}: solver.quadrature: 'gauss' is not possible with "
                        "contact.pairs (the node-to-segment rule is nodal; allowed: vertex)")
    _lift_laws(contact, pairs, source)
    _check_groups(data, pairs, source)
    surfaces = [p["surface"] for p in pairs]
    bounds = data.setdefault("boundaries", {})
    given = bounds.get("contact")
    if given and list(given) != surfaces:
        raise CaseError(f"{source}: boundaries.contact: not with contact.pairs (Gamma3 is the "
                        f"pairs' surfaces, {surfaces}): leave it out")
    bounds["contact"] = surfaces


def _lift_laws(contact: dict, pairs: list, source: str) -> None:
    """A law given in the pairs moves to the contact section: the same in every pair, and
    not also given there."""
    for key in LAW_KEYS:
        given = [p[key] for p in pairs if key in p]
        if not given:
            continue
        if key in contact:
            raise CaseError(f"{source}: contact.pairs[*].{key}: also given in contact.{key}; "
                            "give it once (in the pairs or in the contact section)")
        if len(given) != len(pairs) or any(v != given[0] for v in given):
            raise CaseError(f"{source}: contact.pairs[*].{key}: the pairs have different "
                            f"{key} laws; one set of laws serves every pair: give the same "
                            f"{key} in each pair, or once in contact.{key}")
        contact[key] = given[0]
        for p in pairs:
            del p[key]


def _check_groups(data: dict, pairs: list, source: str) -> None:
    """Each surface differs from its target and from every other pair's groups; no pair
    group is clamped or loaded."""
    clamped = data.get("boundaries", {}).get("clamped", [])
    loaded = {ref for kind in GROUP_MAPS for ref in data["loads"].get(kind, {})}
    seen: dict = {}
    for i, p in enumerate(pairs):
        where = f"contact.pairs[{i}]"
        if p["surface"] == p["target"]:
            raise CaseError(f"{source}: {where}: surface and target are the same group "
                            f"{p['surface']!r} (a pair is two surfaces facing each other)")
        for role in ("surface", "target"):
            ref = p[role]
            if ref in seen and not (role == "target" and seen[ref] == "target"):
                raise CaseError(f"{source}: {where}.{role}: the group {ref!r} is already "
                                f"a {seen[ref]} of another pair (a surface is in one pair, "
                                "and never another pair's target)")
            seen[ref] = role
            if ref in clamped:
                raise CaseError(f"{source}: {where}.{role}: the group {ref!r} is in "
                                "boundaries.clamped (u = 0 there: it cannot be in contact)")
            if ref in loaded:
                raise CaseError(f"{source}: {where}.{role}: the group {ref!r} carries a load "
                                "(loads.traction, pressure or displacement): a contact "
                                "surface takes no load")
