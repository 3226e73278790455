"""The registry of the built-in viscoplastic laws: ``LAWS``, name -> LawSpec (app/model/lawspec.py),
each declared once in its own module.  The case layer builds its schema of
``material.viscoplastic`` (``key_schemas``, ``law_description``, ``kappa0_description``), its
rules (``key_owners``, each spec's required keys and checks) and the Case's ``Viscoplastic``
from it, the run log its titles, the blow-up monitor kappa's growth (``kappa_growth``), the
model its law (``viscoplastic_law``).  A law written by the user (``law: python``,
app/model/lawmodule.py) keeps its own path: it has no spec.

Adding a built-in law: its class and its ``LawSpec`` in a module of its own (as
app/model/norton.py), and one entry in ``LAWS`` below.
"""
from __future__ import annotations

import math

from vpcontact.model.chaboche import SPEC as CHABOCHE
from vpcontact.model.laws import ViscoplasticLaw
from vpcontact.model.lawspec import LawSpec
from vpcontact.model.material import Elasticity
from vpcontact.model.norton import SPEC as NORTON
from vpcontact.model.viscoplastic import PERZYNA, POWER

# the built-in laws, in the order the schema lists them (perzyna first: the default)
LAWS: dict[str, LawSpec] = {s.name: s for s in (PERZYNA, POWER, NORTON, CHABOCHE)}
DEFAULT_LAW = "perzyna"
USER_LAW = "python"     # a class of --law-module (app/model/lawmodule.py), no spec


def key_owners() -> dict[str, tuple[str, ...]]:
    """The keys of the built-in laws and the laws that use each.

    Returns:
        {key: (law names, in the registry's order)}, the keys in order of first use.
    """
    owners: dict[str, tuple[str, ...]] = {}
    for name, spec in LAWS.items():
        for key in spec.keys:
            owners[key] = owners.get(key, ()) + (name,)
    return owners


def key_schemas() -> dict[str, dict]:
    """The schema of every built-in law's key, its description from each law's use.

    Returns:
        {key: schema}, in the order of ``key_owners``.

    Raises:
        ValueError: two laws give one key different schemas.
    """
    out = {}
    for key, names in key_owners().items():
        uses = [(name, LAWS[name].keys[key]) for name in names]
        schemas = {repr(use.schema) for _, use in uses}
        if len(schemas) > 1:
            raise ValueError(f"material.viscoplastic.{key}: the laws {', '.join(names)} "
                             "declare different schemas")
        out[key] = {**uses[0][1].schema, "description": _key_description(uses)}
    return out


def _key_description(uses: list) -> str:
    """'laws a and b (required there): what; law c (absent: 1): what' of one key, the laws
    that use it alike named together.

    Args:
        uses: [(law name, LawKey)] of the key.

    Returns:
        The description.
    """
    alike: dict[tuple[str, str], list[str]] = {}
    for name, use in uses:
        when = "required there" if use.required else f"absent: {use.default:g}"
        alike.setdefault((when, use.doc or use.what), []).append(name)
    return "; ".join(f"law{'s' * (len(names) > 1)} {' and '.join(names)} ({when}): {text}"
                     for (when, text), names in alike.items())


def law_description(user: str) -> str:
    """The schema's description of ``law``: each built-in law's summary, the plane strain
    rule, then the user's law.

    Args:
        user: the sentence of ``law: python``.

    Returns:
        The description.
    """
    carry = [s.name for s in LAWS.values() if s.carries_sigma33]
    keep = [s.name for s in LAWS.values() if not s.carries_sigma33]
    laws = "; ".join(f"{s.name}, {s.summary}" for s in LAWS.values())
    return (f"the viscoplastic law (absent: {DEFAULT_LAW}): {laws}; in 2D plane strain "
            f"{' and '.join(carry)} carry sigma_33 = nu (sigma_11 + sigma_22) - E eps_vp33 in "
            "the 3D norm, eps_vp33 one more internal variable (an isotropic E, kappa0 0), "
            f"{' and '.join(keep)} keep the paper's 2D norm there; {USER_LAW}, {user}")


def kappa0_description() -> str:
    """The schema's description of ``kappa0``: what it is for each built-in law.

    Returns:
        The description.
    """
    alike: dict[str, list[str]] = {}
    for spec in LAWS.values():
        alike.setdefault(spec.kappa0, []).append(spec.name)
    return ("initial internal state variable kappa0, a number or an expression in x, y, z: "
            + "; ".join(f"law{'s' * (len(names) > 1)} {' and '.join(names)}: {text}"
                        for text, names in alike.items()))


def viscoplastic_law(vp, elasticity: Elasticity, plane: str = "stress"
                     ) -> ViscoplasticLaw | None:
    """The case's viscoplastic law.

    Args:
        vp: the case's ``material.viscoplastic`` section (the Case's ``Viscoplastic``, or
            any object with the law's constants as attributes), or None: an elastic body;
            its ``law`` (absent: perzyna) names a spec of ``LAWS`` or a user's class
            (``python``: ``cls``, ``params``; app/model/lawmodule.py).
        elasticity: the elasticity E.
        plane: the 2D model, ``material.plane`` ("stress" or "strain"): Norton and
            Chaboche carry sigma_33 in plane strain (app/model/planestrain.py); Perzyna and
            PowerLaw keep the paper's 2D norm (sigma_33 = 0 in ||sigma||_VM) in both.

    Returns:
        The law, or None.
    """
    if vp is None:
        return None
    law = getattr(vp, "law", DEFAULT_LAW)
    if law == USER_LAW:                 # the class of --law-module (app/model/lawmodule.py)
        from vpcontact.model.lawmodule import python_law
        return python_law(vp, elasticity)
    return LAWS[law].build(vp, elasticity, plane)


def kappa_growth(vp, T: float, bound: float) -> float:
    """How far the largest component of kappa can move in [0, T] under stresses of von
    Mises norm at most ``bound`` (each spec's ``kappa_growth``).

    Args:
        vp: the Case's ``Viscoplastic``.
        T: the final time.
        bound: the bound of ||sigma||_VM.

    Returns:
        The growth; inf for a user's law (not known) or where it overflows.
    """
    spec = LAWS.get(vp.law)
    if spec is None:
        return math.inf
    try:
        return spec.kappa_growth(vp, T, bound)
    except OverflowError:
        return math.inf
