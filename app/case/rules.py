"""The cross-key rules of a case on the data as given (after the schema's, which checks
each key alone): the boundary groups (known sides of the built-in mesh, disjoint roles),
the loads' groups and vector lengths, expressions that parse with the names they may use,
tables that increase in time, the contact section (the gap's expression, the approach
direction, the friction law's sign, the memory kernel).  Each rule is written once, here;
the values of the data at points of the body are checked in app/case/values.py."""
from __future__ import annotations

import math

from vpcontact.case import expressions
from vpcontact.case.model import case_name
from vpcontact.case.reading import GROUP_MAPS
from vpcontact.io.errors import CaseError
from vpcontact.meshes.rectangle import SIDES


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
    if contact and not any(k in contact for k in ("g", "normal_compliance", "friction", "memory")):
        raise CaseError(f"{source}: contact: give at least one of g, normal_compliance, "
                        "memory, friction")
    vp = data["material"].get("viscoplastic")
    if vp:
        _check_law_keys(vp, source)
    if vp and isinstance(vp["kappa0"], str):
        _check_components([vp["kappa0"]], "material.viscoplastic.kappa0", 1, source,
                          in_time=False, space_dim=dim)
    _check_contact(contact, dim, source)
    init = data.get("initial", {})
    if "u0" in init:
        _check_components(init["u0"], "initial.u0", dim, source, in_time=False)
    if "sigma0" in init:
        rows = init["sigma0"]
        if len(rows) != dim or any(len(r) != dim for r in rows):
            raise CaseError(f"{source}: initial.sigma0: expected a {dim} x {dim} matrix")
        for i, r in enumerate(rows):
            _check_components(r, f"initial.sigma0[{i}]", dim, source, in_time=False)


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
    for kind in GROUP_MAPS:
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
    fr = contact.get("friction")
    if fr and fr["b"] - fr["c1"] * fr["u1"] < 0:
        raise CaseError(f"{source}: contact.friction: b - c1 u1 must be >= 0 (the friction "
                        f"force of law (4.2) may not change sign), got "
                        f"{fr['b'] - fr['c1'] * fr['u1']:g}")
    if contact.get("memory"):
        _check_memory(contact["memory"], source)


# the keys of material.viscoplastic that only one law uses
LAW_KEYS = {"n": "power", "s_ref": "power"}


def _check_law_keys(vp: dict, source: str) -> None:
    """material.viscoplastic: a key of another law (n, s_ref with perzyna) is refused; the
    power law needs s_ref (the schema has no defaults for n and s_ref, so a key present here
    was given)."""
    law = vp.get("law", "perzyna")
    for key, owner in LAW_KEYS.items():
        if key in vp and owner != law:
            raise CaseError(f"{source}: material.viscoplastic.{key}: not used with law "
                            f"{law} (only with law {owner})")
    if law == "power" and "s_ref" not in vp:
        raise CaseError(f"{source}: material.viscoplastic.s_ref: required with law power "
                        "(the stress scale of the overstress r = ||sigma - P sigma||_VM / "
                        "s_ref, in Pa)")


def _check_memory(mem: dict, source: str) -> None:
    need = {"power": ("alpha", "tau"), "table": ("table",)}.get(mem["kernel"], ())
    for key in need:
        if key not in mem:
            raise CaseError(f"{source}: contact.memory.{key}: required for the "
                            f"{mem['kernel']} kernel")
    if mem["sum"] == "recursion" and mem["kernel"] != "exponential":
        raise CaseError(f"{source}: contact.memory.sum: the recursion is exact only for the "
                        "exponential kernel (allowed here: auto, direct)")
    if mem["kernel"] == "table":
        ts = [row[0] for row in mem["table"]]
        if ts[0] != 0.0 or any(b <= a for a, b in zip(ts, ts[1:])) \
                or any(row[1] < 0 for row in mem["table"]):
            raise CaseError(f"{source}: contact.memory.table: times must start at 0 and "
                            "increase strictly; values must be >= 0")



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
