"""Where the stability sweep's variants act: every material section and every set of
contact laws of a case, and the variants of those laws that each one admits.

The material sections are ``material``, or each group of ``materials``; the contact
sections are ``contact`` and each entry of ``contact.pairs`` (a pair's own normal
compliance, memory, friction and gap g replace the contact section's for that pair, so a
variant changes every section that has the datum, scaled the same way).  A key of a
variant's changes is a dotted string for ``material`` and ``contact`` (``"contact.g"``) and
a tuple of path parts otherwise (``("materials", "upper", "E")``,
``("contact", "pairs", 0, "g")``: a group name may contain dots or be an integer tag).

Each ``*_plan`` returns the changes of its variants and the sections it cannot act on with
the precise reason ("materials.upper: chaboche's law has no viscosity lambda1"), which the
report lists; a group none of whose sections admits it is left out.
"""
from __future__ import annotations

from vpcontact.model.lawregistry import DEFAULT_LAW, LAWS, key_owners

# the viscoplastic laws with Perzyna's viscosity lambda1 (the stiff-viscosity variant)
LAMBDA1_LAWS = key_owners()["lambda1"]
# the friction keys that are not law (4.2)'s b, c1, c2, u1
OTHER_FRICTION = ("coulomb", "table", "law")


def key(prefix, rest: str):
    """The key of ``rest`` (a dotted path) under a section's prefix.

    Args:
        prefix: "material", "contact", or a tuple of path parts.
        rest: the dotted path inside the section ("" for the section itself).

    Returns:
        A dotted string under a string prefix, else a tuple of path parts.
    """
    if isinstance(prefix, str):
        return f"{prefix}.{rest}" if rest else prefix
    return tuple(prefix) + (tuple(rest.split(".")) if rest else ())


def path(k) -> list:
    """The path parts of a key (a dotted string or a tuple).

    Args:
        k: a key of Variant.changes.

    Returns:
        Its parts (strings, and integers for list entries).
    """
    return k.split(".") if isinstance(k, str) else list(k)


def material_sections(raw: dict) -> list[tuple[str, object, dict]]:
    """The material sections of a case.

    Args:
        raw: the case as a dict.

    Returns:
        (label, prefix, section) for ``material`` or each group of ``materials``.
    """
    if isinstance(raw.get("materials"), dict):
        return [(f"materials.{g}", ("materials", g), m)
                for g, m in raw["materials"].items() if isinstance(m, dict)]
    m = raw.get("material")
    return [("material", "material", m)] if isinstance(m, dict) else []


def contact_sections(raw: dict) -> list[tuple[str, object, dict]]:
    """The sets of contact laws of a case: the contact section and each pair.

    Args:
        raw: the case as a dict.

    Returns:
        (label, prefix, section) for ``contact`` and each ``contact.pairs[i]``.
    """
    c = raw.get("contact")
    if not isinstance(c, dict):
        return []
    pairs = c.get("pairs") if isinstance(c.get("pairs"), list) else []
    return [("contact", "contact", c)] + [
        (f"contact.pairs[{i}]", ("contact", "pairs", i), p)
        for i, p in enumerate(pairs) if isinstance(p, dict)]


def _law(m: dict) -> str | None:
    """The viscoplastic law's name of a material section (None: elastic)."""
    vp = m.get("viscoplastic")
    return None if not isinstance(vp, dict) else vp.get("law", DEFAULT_LAW)


def viscosity_plan(raw: dict) -> tuple[list, list[str]]:
    """The stiff-viscosity variant's sections: those whose law has lambda1.

    Args:
        raw: the case as a dict.

    Returns:
        (the prefixes of the sections to change, the reasons of the others).
    """
    on, why = [], []
    for label, prefix, m in material_sections(raw):
        law = _law(m)
        if law in LAMBDA1_LAWS:
            on.append(prefix)
        elif law is not None:
            why.append(f"{label}: {law}'s law has no viscosity lambda1")
    return on, why


def compliance_plan(raw: dict) -> tuple[list, list[str]]:
    """The near-Signorini c_nu variant's sections: those with normal_compliance.c_nu.

    Args:
        raw: the case as a dict.

    Returns:
        (the prefixes, the reasons of the sections with a compliance law but no c_nu).
    """
    on, why = [], []
    for label, prefix, c in contact_sections(raw):
        nc = c.get("normal_compliance")
        if isinstance(nc, dict) and "c_nu" in nc:
            on.append(prefix)
        elif isinstance(nc, dict):
            why.append(f"{label}.normal_compliance has no c_nu (a table or a user's law)")
    return on, why


def gap_plan(raw: dict) -> list[tuple[object, object]]:
    """The near-Signorini g variants' sections: those with a gap g.

    Args:
        raw: the case as a dict.

    Returns:
        (prefix, g) of each section with g (a number or an expression).
    """
    return [(prefix, c["g"]) for _, prefix, c in contact_sections(raw) if "g" in c]


def friction_plan(raw: dict) -> tuple[list, list, list[str]]:
    """The friction variants' sections: frictionless acts on every friction law; the
    variants of law (4.2) (b = 30, c1 = 300) on the sections with that law.

    Args:
        raw: the case as a dict.

    Returns:
        (the prefixes with friction, those with law (4.2), the reasons of the others).
    """
    every, law42, why = [], [], []
    for label, prefix, c in contact_sections(raw):
        fr = c.get("friction")
        if not isinstance(fr, dict):
            continue
        every.append(prefix)
        other = [k for k in OTHER_FRICTION if k in fr]
        if other:
            why.append(f"{label}.friction is {other[0]} friction, not law (4.2): no b, c1")
        else:
            law42.append(prefix)
    return every, law42, why


def elastic_plan(raw: dict) -> tuple[list, list[str]]:
    """The nu and E variants' sections: those with numbers E and nu.

    Args:
        raw: the case as a dict.

    Returns:
        (the prefixes, the reasons of the others: E or nu an expression, or an
        elasticity tensor).
    """
    on, why = [], []
    for label, prefix, m in material_sections(raw):
        if all(isinstance(m.get(k), (int, float)) and not isinstance(m.get(k), bool)
               for k in ("E", "nu")):
            on.append(prefix)
        else:
            why.append(f"{label}: E and nu are not both numbers")
    return on, why


def scaled_material(prefix, m: dict, factor: float) -> tuple[dict, str | None]:
    """The changes that multiply a material's stress-like data by ``factor`` so that u
    and the viscoplastic strain are unchanged, sigma scales: E and the law's keys its
    LawSpec's ``stress_scaling`` names (app/model/lawspec.py: Perzyna's and the power law's
    lambda1 and kappa0, the power law's s_ref; Norton's A by factor^-n; Chaboche's k, K, C,
    Q).

    Args:
        prefix: the section's prefix.
        m: the material section.
        factor: the scaling factor.

    Returns:
        (the changes, None), or ({}, why) where the law's data cannot be scaled.
    """
    law, vp = _law(m), m.get("viscoplastic")
    out = {key(prefix, "E"): ("scale", factor)} if "E" in m else {}
    if law is None:
        return out, None
    spec = LAWS.get(law)
    scales = spec.stress_scaling(vp, factor) if spec is not None and \
        spec.stress_scaling is not None else f"{law}'s law: its parameters' units are unknown"
    if isinstance(scales, str):
        return {}, scales
    out.update({key(prefix, f"viscoplastic.{k}"): ("scale", v) for k, v in scales.items()})
    return out, None


def scaled_contact(prefix, c: dict, factor: float) -> dict:
    """The changes that multiply a set of contact laws' stress-like data by ``factor``:
    c_nu, law (4.2)'s b, c1, c2 and the memory's b0 (Coulomb's mu is a pure number).

    Args:
        prefix: the section's prefix.
        c: the contact section or a pair.
        factor: the scaling factor.

    Returns:
        The changes.
    """
    keys = {"normal_compliance": ("c_nu",), "friction": ("b", "c1", "c2"), "memory": ("b0",)}
    return {key(prefix, f"{law}.{k}"): ("scale", factor)
            for law, names in keys.items() if isinstance(c.get(law), dict)
            for k in names if k in c[law]}
