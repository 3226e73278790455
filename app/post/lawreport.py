"""The laws and materials of a case, as the model's objects describe them: the elasticity E
(H(E)), the viscoplastic law (G, Gk) with its m and constants (H(G)), the contact laws on
Gamma3: normal compliance p, memory kernel b, friction j_tau and its slip dependence theta
(H(p), H(b), H(j_tau)).

Every law describes itself (``name`` and ``constants()``: name -> (value, unit), the
protocols of app/model/laws.py; memory kernels and the slip law likewise), so a new law is
listed without a change here.  ``law_report`` gathers them into summary.json's "laws";
``law_lines`` prints them for ``check``.
"""
from __future__ import annotations


def _value(v):
    """A constant for JSON: a number as float, anything else (an expression) as text."""
    try:
        return float(v)
    except (TypeError, ValueError):
        return str(v)


def _entry(obj) -> dict | None:
    """{"name", "constants": {name: [value, unit]}} of a law, or None."""
    if obj is None:
        return None
    consts = obj.constants() if hasattr(obj, "constants") else {}
    return {"name": getattr(obj, "name", type(obj).__name__),
            "constants": {k: [_value(v), u] for k, (v, u) in consts.items()}}


def _elasticity(problem) -> dict:
    """The elasticity's description: its own ``constants()`` where it has them, else the
    case's isotropic E, nu (plane stress or strain in 2D)."""
    el, mat = problem.elasticity, problem.case.material
    if getattr(problem, "materials", None):      # one per group (app/model/materials.py)
        return problem.materials.describe()
    if hasattr(el, "constants"):
        return _entry(el)
    kind = f"isotropic, plane {mat.plane}" if problem.disc.dim == 2 else "isotropic (3D)"
    return {"name": kind, "constants": {"E": [_value(mat.E), "N/m^2"],
                                        "nu": [_value(mat.nu), "-"]}}


def law_report(problem, gamma3_history=None) -> dict:
    """The laws of a case (summary.json's "laws").

    Args:
        problem: the ContactProblem (its elasticity, viscoplastic law, contact laws,
            case).
        gamma3_history: the Gamma3History (memory kernel, slip law), or None.

    Returns:
        {"elasticity": {name, constants}, "viscoplastic": the law's ``describe()`` or None,
        "contact": {"normal", "memory", "friction", "slip", "memory_kernel"}: each
        {name, constants} or None, and "g" the gap of u_nu <= g or None} ("contact" None
        without a contact section).
    """
    case, law = problem.case, problem.law
    out = {"elasticity": _elasticity(problem),
           "viscoplastic": None if law is None else law.describe(), "contact": None}
    if law is not None and out["viscoplastic"] is not None:
        vp = case.material.viscoplastic if case.material is not None else None
        kappa0 = getattr(vp, "kappa0", None) if vp is not None else None
        if kappa0 is not None:
            out["viscoplastic"]["kappa0"] = _value(kappa0)
    if not case.contact.active:
        return out
    sections = case.contact.sections
    laws = problem.section_laws()       # the case's, with the API's replacements
    if len(sections) == 1:
        out["contact"] = _contact_entry(problem, sections[0], laws[0], gamma3_history)
        out["contact"]["g"] = None if case.contact.g is None else _value(case.contact.g)
    else:                               # laws per pair
        out["contact"] = {"g": None, "pairs": [_contact_entry(problem, c, law, None)
                                               for c, law in zip(sections, laws)]}
    return out


def _contact_entry(problem, section, laws, h) -> dict:
    """{"normal", "memory", "friction", "memory_kernel", "slip"} of one set of contact
    laws; the kernel and theta(s) are the Gamma3 history's ``h`` (None: the section's)."""
    from vpcontact.model.contactregistry import coulomb_law
    from vpcontact.model.gamma3 import section_kernel, section_slip
    mk = section.memory
    kernel = h.memory.kernel if h is not None and h.memory else \
        section_kernel(mk) if h is None and mk is not None else None
    slip = h.slip.law if h is not None and h.slip else \
        section_slip(section.friction) if h is None else None
    out = {"normal": _entry(laws.normal), "memory": _entry(laws.memory),
           "friction": _entry(laws.friction), "memory_kernel": _entry(kernel),
           "slip": _entry(slip)}
    fr = section.friction
    if getattr(fr, "coulomb", None) is not None and \
            "friction" not in problem.contact_replacements:
        out["friction"] = _entry(coulomb_law(fr.coulomb))    # its variant's own words
    return out


def _constants_text(entry: dict) -> str:
    """'name: k = v unit, ...' of one entry."""
    consts = ", ".join(f"{k} = {v:g}" + ("" if u in ("-", "") else f" {u}")
                       if isinstance(v, float)
                       else f"{k} = {v}" + ("" if u in ("-", "") else f" [{u}]")
                       for k, (v, u) in entry["constants"].items())
    return entry["name"] + (f": {consts}" if consts else "")


def _law_text(vp: dict) -> str:
    """A viscoplastic law's line: name, constants, m, kappa0, L_G."""
    lip = vp.get("lipschitz_constant")
    k0 = vp.get("kappa0")
    return (f"{_constants_text(vp)} (m = {vp['m']})"
            + ("" if k0 is None else f"; kappa0 = {k0:g}" if isinstance(k0, float)
               else f"; kappa0 = {k0}")
            + (f"; L_G = {lip:.4g} 1/s" if lip is not None else "; L_G: not stated by the law"))


def law_lines(report: dict, diagnostics=None) -> list[str]:
    """The report's lines for ``check``.

    Args:
        report: ``law_report``'s dict.
        diagnostics: the Diagnostics (m_E, L_G, m_j), or None.

    Returns:
        One line for the elasticity, one for the viscoplastic law, one per contact law.
    """
    d = diagnostics
    lines = ["elasticity: " + _constants_text(report["elasticity"])
             + (f"; m_E = {d.m_E:.4g} N/m^2 (smallest eigenvalue of E)" if d else "")]
    vp = report["viscoplastic"]
    if vp is None:
        lines.append("viscoplastic law: none (elastic body)")
    else:
        groups = vp.get("groups") or {"": vp}
        lines += [f"viscoplastic law{f' ({g})' if g else ''}: " + (
            _law_text(law) if law is not None else "none (elastic)")
            for g, law in groups.items()]
    contact = report["contact"]
    if contact is None:
        lines.append("contact laws: none (no contact section)")
        return lines
    pairs = contact.get("pairs")
    for where, entry in ([("contact", contact)] if pairs is None else
                         [(f"contact pair {i}", e) for i, e in enumerate(pairs)]):
        for key in ("normal", "memory", "memory_kernel", "friction", "slip"):
            if entry.get(key) is not None:
                text = _constants_text(entry[key])
                if key == "friction" and d is not None:
                    text += f"; m_j = {d.m_j:g} N/m^3" if d.m_j is not None else \
                        "; m_j: not stated by the law (no (2.6) margin)"
                lines.append(f"{where}: {text}")
        if pairs is not None and not any(entry.get(k) for k in ("normal", "friction")):
            lines.append(f"{where}: hard contact [u]_nu <= d + g, frictionless")
    g = contact.get("g")
    if g is not None:
        lines.append("contact: unilateral constraint u_nu <= g, g = "
                     + (f"{g:g} m" if isinstance(g, float) else f"{g} [m]"))
    return lines
