"""The cross-key rules of a case on the data as given (after the schema's, which checks
each key alone): the boundary groups (known sides of the built-in mesh, disjoint roles),
the loads' groups and vector lengths, expressions that parse with the names they may use,
tables that increase in time, the contact section (the gap's expression, the approach
direction; the built-in contact laws' keys and checks, from their registries
app/model/contactregistry.py).  Each rule is written once, here (a built-in law's own
in the law's module);
the values of the data at points of the body are checked in app/case/values.py."""
from __future__ import annotations

import math

from vpcontact.case import expressions
from vpcontact.case.anisotropy import check_material_elasticity
from vpcontact.case.materialrules import material_sections, section_errors
from vpcontact.case.model import Coulomb, case_name
from vpcontact.io.casekey import GROUP_MAPS
from vpcontact.io.errors import CaseError
from vpcontact.meshes.rectangle import SIDES
from vpcontact.model.contactregistry import (
    BOUNDS,
    COULOMBS,
    KERNELS,
    NORMALS,
    SLIPS,
    alternatives,
    builtin_keys,
    chosen,
    field_keys,
    recursive_kernels,
)
from vpcontact.model.lawregistry import DEFAULT_LAW, LAWS, USER_LAW, key_owners


def _check_components(items, path: str, dim: int, source: str, in_time: bool = True,
                      space_dim: int | None = None, free: bool = False):
    """Length = dim; expressions parse with the allowed names (t if ``in_time``, the
    coordinates of a body of dimension ``space_dim``, default dim); tables increase in t;
    with ``free``, None (a free component) is allowed but not everywhere."""
    names = ("t",) * in_time + ("x", "y", "z")[:space_dim or dim]
    if len(items) != dim:
        raise CaseError(f"{source}: {path}: expected {dim} components (the mesh dimension), "
                        f"got {len(items)}")
    if free and all(c is None for c in items):
        raise CaseError(f"{source}: {path}: every component is null (free); prescribe at "
                        "least one (a number, an expression or a table), or leave the group "
                        "out")
    for i, c in enumerate(items):
        _check_component(c, f"{path}[{i}]", names, source)


def _check_component(c, path: str, names: tuple, source: str) -> None:
    """An expression parses with ``names``; a table (only if t is a name) increases in t."""
    if isinstance(c, str):
        try:
            expressions.parse(c, names)
        except expressions.ExpressionError as exc:
            raise CaseError(f"{source}: {path}: {exc}") from None
    elif isinstance(c, dict) and "t" not in names:
        raise CaseError(f"{source}: {path}: a table in time is not an initial value "
                        f"(allowed: a number or an expression in {', '.join(names)})")
    elif isinstance(c, dict):
        ts = [row[0] for row in c["table"]]
        if any(b <= a for a, b in zip(ts, ts[1:])):
            raise CaseError(f"{source}: {path}.table: times must increase strictly")


def check_structure(data: dict, source: str) -> None:
    """The cross-key rules: boundary groups, vector lengths, expressions parse, contact and
    memory.

    Args:
        data: the default-filled, settled case mapping.
        source: the case file, for messages.

    Raises:
        CaseError: for the first rule the data breaks, naming the key.
    """
    dim = data["mesh"]["dim"]
    contact = data.get("contact", {})
    loads = data["loads"]
    _check_boundaries(data, source)
    _check_loads(data, source)
    if "f0" in loads:
        _check_components(loads["f0"], "loads.f0", dim, source)
    if contact and not any(k in contact for k in ("g", "normal_compliance", "friction", "memory",
                                                  "pairs")):
        raise CaseError(f"{source}: contact: give at least one of g, normal_compliance, "
                        "memory, friction (or pairs)")
    for path, section in material_sections(data):    # material, or each of materials
        with section_errors(path):
            _check_material(section, dim, source)
    _check_contact(contact, dim, source)
    for i, pair in enumerate(contact.get("pairs") or []):   # a pair's own laws
        laws = {k: pair[k] for k in ("normal_compliance", "memory", "friction") if k in pair}
        if laws:
            with section_errors(f"contact.pairs[{i}]", section="contact"):
                _check_contact({**laws, "pairs": True}, dim, source)
    init = data.get("initial", {})
    if "u0" in init:
        _check_components(init["u0"], "initial.u0", dim, source, in_time=False)
    if "sigma0" in init:
        rows = init["sigma0"]
        if len(rows) != dim or any(len(r) != dim for r in rows):
            raise CaseError(f"{source}: initial.sigma0: expected a {dim} x {dim} matrix")
        for i, r in enumerate(rows):
            _check_components(r, f"initial.sigma0[{i}]", dim, source, in_time=False)


def _check_material(material: dict, dim: int, source: str) -> None:
    """A material section: its elasticity (E and nu or material.elasticity, positive
    definite: app/case/anisotropy.py) and E, nu expressions, its viscoplastic law's keys,
    kappa0's expression."""
    try:
        check_material_elasticity(material, dim)
    except ValueError as e:
        raise CaseError(f"{source}: {e}") from None
    for key in ("E", "nu"):
        if isinstance(material.get(key), str):
            _check_component(material[key], f"material.{key}", ("x", "y", "z")[:dim], source)
    vp = material.get("viscoplastic")
    if vp:
        _check_law_keys(vp, source)
    if vp and dim == 2 and material.get("plane") == "strain":
        _check_plane_strain_law(material, vp, source)
    if vp and isinstance(vp["kappa0"], str):
        _check_components([vp["kappa0"]], "material.viscoplastic.kappa0", 1, source,
                          in_time=False, space_dim=dim)


def _check_plane_strain_law(material: dict, vp: dict, source: str) -> None:
    """The laws that carry sigma_33 in plane strain (their LawSpec's ``carries_sigma33``:
    norton, chaboche) need the 3D E, nu of an isotropic E (app/model/planestrain.py); then
    the law's own plane strain checks (norton: eps_vp33 in kappa starts at 0)."""
    law = vp.get("law", DEFAULT_LAW)
    spec = LAWS.get(law)
    if spec is None or not spec.carries_sigma33:
        return
    if "elasticity" in material:
        raise CaseError(f"{source}: material.elasticity: law {law} in plane strain "
                        "(material.plane: strain) needs an isotropic E (material.E, "
                        "material.nu) for its out-of-plane stress sigma_33")
    if spec.check_plane_strain is not None:
        spec.check_plane_strain(vp, source)


def _check_group(ref, path: str, builtin: bool, dim: int, source: str, named: bool) -> None:
    """A group of the built-in mesh is one of its sides (SIDES[dim]), given by name; a group
    of a mesh.file (a name or a tag) is checked against the file when it is loaded.
    ``named``: the path does not show the group (a list entry), so the message does."""
    if not builtin:
        return
    if not isinstance(ref, str):
        raise CaseError(f"{source}: {path}: the physical tag {ref} is for a mesh.file; the "
                        f"built-in mesh's groups are its sides, given by name (allowed: "
                        f"{', '.join(SIDES[dim])})")
    shown = f" ({ref!r})" if named else ""
    if ref not in SIDES[dim]:
        raise CaseError(f"{source}: {path}: no such side in {dim}D{shown} "
                        f"(allowed: {', '.join(SIDES[dim])})")


def _group_name(ref, builtin: bool) -> str:
    if builtin:
        return f"the {ref} side"
    return f"the group {ref!r}" if isinstance(ref, str) else f"the physical group {ref}"


def _check_boundaries(data: dict, source: str) -> None:
    """boundaries.clamped and .contact: known groups (built-in mesh), no repeats, disjoint;
    a case with a contact section has a contact boundary."""
    builtin, dim = "file" not in data["mesh"], data["mesh"]["dim"]
    bounds = data["boundaries"]
    for role in ("clamped", "contact"):
        seen = []
        for i, ref in enumerate(bounds[role]):
            _check_group(ref, f"boundaries.{role}[{i}]", builtin, dim, source, named=True)
            if ref in seen:
                raise CaseError(f"{source}: boundaries.{role}[{i}]: {ref!r} is listed twice")
            seen.append(ref)
    both = [ref for ref in bounds["contact"] if ref in bounds["clamped"]]
    if both:
        raise CaseError(f"{source}: boundaries.contact: {_group_name(both[0], builtin)} is also "
                        "in boundaries.clamped (a group is either clamped, Gamma1, or in "
                        "contact, Gamma3)")
    if data.get("contact") and not bounds["contact"]:
        need = "required with mesh.file" if not builtin else "empty"
        raise CaseError(f"{source}: boundaries.contact: {need} in a case with a contact "
                        "section (name the groups of Gamma3, the contact boundary)")


def _check_loads(data: dict, source: str) -> None:
    """loads.traction, .pressure and .displacement: known groups (built-in mesh), neither
    clamped nor (in a case with a contact section) in contact; their components."""
    builtin, dim = "file" not in data["mesh"], data["mesh"]["dim"]
    bounds, loads = data["boundaries"], data["loads"]
    has_contact = bool(data.get("contact"))
    names = ("t", "x", "y", "z")[:dim + 1]
    for kind in GROUP_MAPS[:3]:            # loads.rigid: app/case/caprules.py
        for ref, value in loads.get(kind, {}).items():
            path = f"loads.{kind}.{ref}"
            _check_group(ref, path, builtin, dim, source, named=False)
            if ref in bounds["clamped"]:
                raise CaseError(f"{source}: {path}: {_group_name(ref, builtin)} is clamped "
                                f"(boundaries.clamped: u = 0 there); a {kind} there is not "
                                "allowed")
            if has_contact and ref in bounds["contact"]:
                raise CaseError(f"{source}: {path}: {_group_name(ref, builtin)} is Gamma3 "
                                f"(contact); a {kind} there is only allowed in a case without "
                                "a contact section")
            if kind == "pressure":
                _check_component(value, path, names, source)
            else:
                _check_components(value, path, dim, source, free=kind == "displacement")


def _check_contact(contact: dict, dim: int, source: str) -> None:
    """The gap's expression (x, y, z only), the approach direction (dim components, not
    zero), the friction law's sign and the memory kernel."""
    g = contact.get("g")
    if isinstance(g, str):
        try:
            used = expressions.names(expressions.parse(g))
        except expressions.ExpressionError:
            used = set()
        if "t" in used:
            raise CaseError(f"{source}: contact.g: the initial gap does not depend on time "
                            f"(allowed: an expression in {', '.join('xyz'[:dim])}, without t)")
        _check_component(g, "contact.g", tuple("xyz"[:dim]), source)
    d = contact.get("direction")
    if d is not None and len(d) != dim:
        raise CaseError(f"{source}: contact.direction: expected {dim} components (the mesh "
                        f"dimension), got {len(d)}")
    if d is not None and not math.hypot(*d) > 0:
        raise CaseError(f"{source}: contact.direction: the zero vector is no direction "
                        "(allowed: a vector of length > 0)")
    _check_compliance(contact.get("normal_compliance"), dim, source)
    fr = contact.get("friction")
    if fr:
        _check_friction(fr, source)
    if fr and "coulomb" in fr and not {"normal_compliance", "g", "pairs"} & set(contact):
        raise CaseError(f"{source}: contact.friction.coulomb: needs a contact pressure p_n: "
                        "give contact.normal_compliance or contact.g (a pair's bound is "
                        "always there)")
    if contact.get("memory"):
        _check_memory(contact["memory"], source)
    if isinstance((contact.get("memory") or {}).get("b0"), str):
        _check_component(contact["memory"]["b0"], "contact.memory.b0", tuple("xyz"[:dim]),
                         source)


def _one_law(given: dict, path: str, registry: dict, source: str, last: str = ", ") -> None:
    """The keys of exactly one built-in law of a kind (app/model/contactregistry.py: the
    first whose required keys are given, else the kind's default), all its required keys,
    no other law's optional key; then the law's own checks (its ContactLawSpec's
    ``check``).  ``last`` joins the last two keys of a law in the messages' choice
    (``alternatives``)."""
    choice = alternatives(registry, last)
    have = [(spec, [k for k in spec.required() if k in given]) for spec in registry.values()]
    have = [(spec, keys) for spec, keys in have if keys]
    if len(have) > 1:
        (_, first), (_, second) = have[:2]
        raise CaseError(f"{source}: {path}.{second[0]}: not with {', '.join(first)} (give "
                        f"{choice}; {'not both' if len(registry) == 2 else 'only one'})")
    spec = chosen(registry, given)
    missing = [k for k in spec.required() if k not in given]
    if missing:
        raise CaseError(f"{source}: {path}.{missing[0]}: required (give {choice})")
    for other in registry.values():
        for key, use in other.keys.items():
            if other is not spec and key in given and key not in spec.keys:
                raise CaseError(f"{source}: {path}.{key}: {use.only or f'only with {other.name}'}")
    if spec.check is not None:
        spec.check(given, path, source)


def _python_contact_law(given: dict, path: str, source: str) -> bool:
    """A contact law written by the user (``law: python``): class required, the built-in
    laws' keys refused; class and params only with law python.  Returns: law python."""
    if given.get("law") != "python":
        for key in ("class", "params"):
            if key in given:
                raise CaseError(f"{source}: {path}.{key}: only with law: python (a law "
                                "written by the user)")
        return False
    builtin = [k for k in builtin_keys(BUILTIN_CONTACT_LAWS[path]) if k in given]
    if builtin:
        raise CaseError(f"{source}: {path}.{builtin[0]}: not with law: python (the user's "
                        f"class gives the law; remove {', '.join(builtin)})")
    if "class" not in given:
        raise CaseError(f"{source}: {path}.class: required with law python (the name of the "
                        "law's class in the module of --law-module FILE.py)")
    return True


# the built-in laws of a section that law: python replaces
BUILTIN_CONTACT_LAWS = {"contact.normal_compliance": NORMALS, "contact.friction": BOUNDS}


def _check_compliance(nc: dict | None, dim: int, source: str) -> None:
    """contact.normal_compliance: the keys of one built-in law (``NORMALS``: c_nu with m, a
    table nondecreasing from [0, 0], ...), an expression in x, y, z; or a law written by
    the user."""
    path = "contact.normal_compliance"
    if nc is None or _python_contact_law(nc, path, source):
        return
    _one_law(nc, path, NORMALS, source)
    for key in field_keys(NORMALS):          # c_nu(x), ...: an expression in x, y, z
        if isinstance(nc.get(key), str):
            _check_component(nc[key], f"{path}.{key}", tuple("xyz"[:dim]), source)


def _check_friction(fr: dict, source: str) -> None:
    """contact.friction: the keys of one built-in bound (``BOUNDS``: b, c1, c2, u1 with
    b - c1 u1 >= 0, or a table with tau(0) > 0, tau >= 0, last slope >= 0, ...); or
    Coulomb's; or a law written by the user; its slip: one slip law's keys (``SLIPS``:
    theta_inf, s0, or a table in [0, 1], ...)."""
    if "coulomb" in fr:
        _check_coulomb(fr, source)
    elif not _python_contact_law(fr, "contact.friction", source):
        _one_law(fr, "contact.friction", BOUNDS, source)
    slip = fr.get("slip")
    if slip is not None:
        _one_law(slip, "contact.friction.slip", SLIPS, source)


def _check_coulomb(fr: dict, source: str) -> None:
    """contact.friction.coulomb: not with another friction law's keys; the keys of exactly
    one variant (``COULOMBS``: mu >= 0, or mu_s >= mu_k >= 0 and slip_length > 0), its own
    checks; a variant with a slip dependence (mu_s, mu_k) not with slip."""
    other = [k for k in (*builtin_keys(BOUNDS), "law", "class", "params") if k in fr]
    if other:
        raise CaseError(f"{source}: contact.friction.{other[0]}: not with coulomb (the "
                        f"Coulomb law mu p_n is the friction law; remove {', '.join(other)})")
    c = fr["coulomb"]
    _one_law(c, "contact.friction.coulomb", COULOMBS, source, last=" and ")
    spec = chosen(COULOMBS, c)
    if "slip" in fr and Coulomb(spec.name, spec.constants(c)).has_slip:
        raise CaseError(f"{source}: contact.friction.slip: not with coulomb mu_s, mu_k (the "
                        "static/kinetic pair is the slip dependence; give one of them)")


# the keys of material.viscoplastic that only some laws use, and the keys each law requires
# with what they are (the schema has no defaults for them): from each law's LawSpec
# (app/model/lawregistry.py); law python: the class of --law-module and its constructor's
# keyword arguments
LAW_KEYS = {**key_owners(), "class": (USER_LAW,), "params": (USER_LAW,)}
LAW_REQUIRED = {**{name: spec.required() for name, spec in LAWS.items()},
                USER_LAW: {"class": "the name of the law's class in the module of "
                                    "--law-module FILE.py"}}


def _check_law_keys(vp: dict, source: str) -> None:
    """material.viscoplastic: a key of another law (n, s_ref with perzyna, lambda1 with
    norton, ...) is refused; each law's own keys are required (the schema has no defaults for
    them, so a key present here was given); then the law's own checks (its LawSpec's
    ``check``: chaboche starts from X = R = p = 0, so its kappa0 may only be 0, ...)."""
    law = vp.get("law", DEFAULT_LAW)
    for key, owners in LAW_KEYS.items():
        if key in vp and law not in owners:
            raise CaseError(f"{source}: material.viscoplastic.{key}: not used with law "
                            f"{law} (only with law{'s' * (len(owners) > 1)} "
                            f"{', '.join(owners)})")
    for key, what in LAW_REQUIRED[law].items():
        if key not in vp:
            raise CaseError(f"{source}: material.viscoplastic.{key}: required with law {law} "
                            f"({what})")
    spec = LAWS.get(law)
    if spec is not None and spec.check is not None:
        spec.check(vp, source)


def _check_memory(mem: dict, source: str) -> None:
    """contact.memory: the required keys of its kernel (``KERNELS``), the recursion only for
    a recursive kernel, the kernel's own checks."""
    spec = KERNELS[mem["kernel"]]
    for key in spec.required():
        if key not in mem:
            raise CaseError(f"{source}: contact.memory.{key}: required for the "
                            f"{mem['kernel']} kernel")
    if mem["sum"] == "recursion" and not spec.recursive:
        raise CaseError(f"{source}: contact.memory.sum: the recursion is exact only for the "
                        f"{' and '.join(recursive_kernels())} kernel (allowed here: auto, "
                        "direct)")
    if spec.check is not None:
        spec.check(mem, "contact.memory", source)


def check_name(data: dict, source: str) -> None:
    """The case's name (given, or the file name's) can name an output directory.

    Args:
        data: the case mapping.
        source: the case file.

    Raises:
        CaseError: for the file name of a case without ``name`` that gives "", "." or "..".
    """
    name = case_name(data, source)
    if name in ("", ".", ".."):
        raise CaseError(f"{source}: name: the file name gives the case name {name!r}, which "
                        "cannot name an output directory; set name (allowed: letters, digits, "
                        "'_', '.' and '-', starting with a letter or digit)")
