"""The rules of ``contact.pairs`` (two bodies of one mesh.file in contact), on the case as
given, before the schema's defaults are filled: the pairs' laws are settled (``settle_laws``:
a law of the contact section serves every pair that does not give its own; one set of laws
for all pairs moves to the contact section, different laws stay in the pairs, each pair with
all of its laws), the pairs' surfaces become Gamma3 (``boundaries.contact``), and what a
pair cannot take is refused with the key named.

The result validates to the same case again (the studies validate ``case.raw`` with changed
keys): a case whose laws were settled and whose boundaries.contact lists the surfaces is
accepted as it is.
"""
from __future__ import annotations

import re

from vpcontact.case.schema import SCHEMA
from vpcontact.case.schemacheck import fill_defaults
from vpcontact.io.casekey import GROUP_MAPS
from vpcontact.io.errors import CaseError
from vpcontact.model.contactregistry import KERNELS, builtin_keys

# the contact laws a pair may carry (the contact section's own keys)
LAW_KEYS = ("normal_compliance", "memory", "friction")
# the memory kernel's keys that pairs with different laws share (b0 may differ: the
# Gamma3 history sums b0(x_i) u_nu^+ with one kernel shape, app/model/gamma3.py): kernel,
# every kernel's keys (app/model/contactregistry.py), sum
MEMORY_SHAPE = ("kernel", *builtin_keys(KERNELS), "sum")


def settle_pairs(data: dict, source: str) -> dict:
    """Check and settle contact.pairs in place (nothing without pairs).

    Args:
        data: the case mapping after the schema check (changed in place).
        source: the case file, for messages.

    Returns:
        Where the laws moved to the contact section were written: ``contact.<law>`` ->
        ``contact.pairs[i].<law>`` (see ``settle_laws``; for ``as_written``).

    Raises:
        CaseError: pairs without a mesh.file, with contact.g, with a
            boundaries.contact other than the surfaces, a surface that is its own target or
            another pair's target or surface, a clamped or loaded pair group, pairs with
            different laws of which one is written in Python.
    """
    contact = data.get("contact") or {}
    pairs = contact.get("pairs")
    if not pairs:
        return {}
    if "file" not in data["mesh"]:
        raise CaseError(f"{source}: contact.pairs: two bodies need a mesh.file holding both "
                        "(the built-in rectangle and box are one body)")
    if "g" in contact:
        raise CaseError(f"{source}: contact.g: not with contact.pairs (a pair's gap is the "
                        "distance measured on the mesh plus the pair's own g: "
                        "contact.pairs[i].g)")
    if data.get("solver", {}).get("quadrature") == "gauss":
        raise CaseError(f"{source}: solver.quadrature: 'gauss' is not possible with "
                        "contact.pairs (the node-to-segment rule is nodal; allowed: vertex)")
    moved = settle_laws(contact, pairs, source)
    _check_groups(data, pairs, source)
    surfaces = [p["surface"] for p in pairs]
    bounds = data.setdefault("boundaries", {})
    given = bounds.get("contact")
    if given and list(given) != surfaces:
        raise CaseError(f"{source}: boundaries.contact: not with contact.pairs (Gamma3 is the "
                        f"pairs' surfaces, {surfaces}): leave it out")
    bounds["contact"] = surfaces
    return moved


def settle_laws(contact: dict, pairs: list, source: str) -> dict:
    """Each pair's laws: its own keys, else the contact section's.  The same in every pair:
    given once in the contact section (the pairs carry none); else each pair carries all of
    its laws and the contact section none (``ContactPair.laws``).

    Args:
        contact: the contact section (changed in place).
        pairs: its pairs (changed in place).
        source: the case file, for messages.

    Returns:
        The laws that moved from a pair to the contact section (the same in every pair):
        ``contact.<law>`` -> ``contact.pairs[i].<law>``, the first pair's key where it gives
        the law itself (a law of the contact section stays under its own key).

    Raises:
        CaseError: a law written in Python (``law: python``) in pairs whose laws differ.
    """
    defaults = {key: contact.pop(key) for key in LAW_KEYS if key in contact}
    laws = [{key: p.get(key, defaults.get(key)) for key in LAW_KEYS
             if key in p or key in defaults} for p in pairs]
    written = [{key for key in LAW_KEYS if key in p} for p in pairs]
    for p in pairs:
        for key in LAW_KEYS:
            p.pop(key, None)
    if all(law == laws[0] for law in laws):
        contact.update(laws[0])
        return {f"contact.{key}": f"contact.pairs[0].{key}" for key in laws[0]
                if key in written[0]}
    for i, (p, law) in enumerate(zip(pairs, laws)):
        for key, value in law.items():
            if isinstance(value, dict) and value.get("law") == "python":
                raise CaseError(f"{source}: contact.pairs[{i}].{key}: law: python serves "
                                "every pair or none: the pairs' laws differ here, so give "
                                f"the law once in contact.{key} and the same in every pair")
        p.update(law)
    return {}


def as_written(message: str, moved: dict) -> str:
    """A message of the rules (which name a law settled into the contact section
    ``contact.<law>``) with the key paths where the case gives the law
    (``contact.pairs[i].<law>...``), so that its line can be found (reading.with_lines).

    Args:
        message: a CaseError message.
        moved: ``contact.<law>`` -> where it was written (``settle_pairs``).

    Returns:
        The message with those key paths replaced.
    """
    for short, written in moved.items():
        message = re.sub(r"(?<![\w.\[\]])" + re.escape(short) + r"(?!\w)", written, message)
    return message


def fill_pair_defaults(data: dict, source: str) -> None:
    """The schema's defaults in the laws of pairs with different laws (``settle_laws``),
    and their memory kernels of one shape.

    Args:
        data: the case mapping with its defaults filled (changed in place).
        source: the case file, for messages.

    Raises:
        CaseError: two pairs whose memory kernels differ in more than b0.
    """
    schema = SCHEMA["properties"]["contact"]["properties"]["pairs"]["items"]
    pairs = (data.get("contact") or {}).get("pairs") or []
    shapes = {}
    for i, p in enumerate(pairs):
        fill_defaults(p, schema)
        if "memory" in p:
            shapes[i] = {k: p["memory"].get(k) for k in MEMORY_SHAPE}
    first = next(iter(shapes.items()), None)
    for i, shape in shapes.items():
        key = next((k for k in MEMORY_SHAPE if shape[k] != first[1][k]), None)
        if key is not None:
            raise CaseError(f"{source}: contact.pairs[{i}].memory.{key}: "
                            f"{shape[key]!r}, but contact.pairs[{first[0]}].memory.{key}: "
                            f"{first[1][key]!r}: the pairs' memory terms share the kernel "
                            f"({', '.join(MEMORY_SHAPE)}); b0 may differ")


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
                                "(loads.traction, pressure, displacement or rigid): a contact "
                                "surface takes no load")
