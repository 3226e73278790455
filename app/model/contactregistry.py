"""The registries of the built-in contact laws, name -> ContactLawSpec
(app/model/contactspec.py), each declared once in the module that implements it:

- ``KERNELS``: the memory kernels of ``contact.memory``, chosen by its key ``kernel``
  (app/model/memory_kernels.py);
- ``SLIPS``: the slip dependence of ``contact.friction.slip`` (app/model/contact_laws.py);
- ``NORMALS``: the normal compliance of ``contact.normal_compliance``
  (app/model/contact_laws.py, contact_tables.py);
- ``BOUNDS``: the friction bound of ``contact.friction`` (the same modules);
- ``COULOMBS``: the variants of Coulomb's bound mu p_n of ``contact.friction.coulomb``
  (mu; mu_s, mu_k, slip_length; app/model/coulomb.py).

A law of the last four is chosen by the keys given (``chosen``): the first law (the kind's
default) whose required keys are given, exactly one law's.  The case layer builds its schema
of these sections (``key_schemas``, ``kernel_keys``), its rules (each spec's keys, required
keys and checks, ``alternatives``) and the Case's tagged sections from them, the blow-up
monitor their stress levels, the model its laws (``contact_law``, ``friction_law``,
``slip_law``, ``memory_kernel``, ``coulomb_law`` below, as ``viscoplastic_law`` of
app/model/lawregistry.py).  A law written by the user (``law: python``,
app/model/lawmodule.py) keeps its own path.

Adding a built-in contact law: its class and its ``ContactLawSpec`` in a module of its own
(or beside its kind's laws), and one entry in its registry below.
"""
from __future__ import annotations

from vpcontact.model.contact_laws import (
    COMPLIANCE,
    COULOMB_PSI,
    FRICTION,
    SLIP_TABLE,
    SLIP_WEAKENING,
    ContactLaw,
    PiecewiseLinearFriction,
    PythonLawSlot,
    RegularisedNorm,
    RegularisedPositivePart,
)
from vpcontact.model.contact_tables import COMPLIANCE_TABLE, FRICTION_TABLE
from vpcontact.model.contactspec import ContactLawSpec
from vpcontact.model.coulomb import CONSTANT_MU, STATIC_KINETIC, CoulombLaw
from vpcontact.model.laws import ScalarLaw
from vpcontact.model.memory_kernels import EXPONENTIAL, POWER, TABLE_KERNEL, MemoryKernel

# each kind's laws in the schema's order, its default first
KERNELS: dict[str, ContactLawSpec] = {s.name: s for s in (EXPONENTIAL, POWER, TABLE_KERNEL)}
SLIPS: dict[str, ContactLawSpec] = {s.name: s for s in (SLIP_WEAKENING, SLIP_TABLE)}
NORMALS: dict[str, ContactLawSpec] = {s.name: s for s in (COMPLIANCE, COMPLIANCE_TABLE)}
BOUNDS: dict[str, ContactLawSpec] = {s.name: s for s in (FRICTION, FRICTION_TABLE)}
COULOMBS: dict[str, ContactLawSpec] = {s.name: s for s in (CONSTANT_MU, STATIC_KINETIC)}
DEFAULT_KERNEL = "exponential"


def key_schemas(registry: dict[str, ContactLawSpec]) -> dict[str, dict]:
    """The schema of every key of one kind's laws.

    Args:
        registry: KERNELS, SLIPS, NORMALS, BOUNDS or COULOMBS.

    Returns:
        {key: schema}, the laws' keys in the registry's order.

    Raises:
        ValueError: two laws of the kind declare one key.
    """
    out: dict[str, dict] = {}
    for spec in registry.values():
        for key, use in spec.keys.items():
            if key in out:
                raise ValueError(f"the key {key} is declared by two laws of one kind")
            out[key] = use.schema
    return out


def kernel_keys() -> dict[str, dict]:
    """The schema of ``contact.memory``'s kernel keys: the default kernel's keys, ``kernel``
    (the kernels' names and formulas), then the other kernels' keys.

    Returns:
        {key: schema}.
    """
    keys = key_schemas(KERNELS)
    first = list(KERNELS[DEFAULT_KERNEL].keys)
    formulas = [s.formula for s in KERNELS.values()]
    text = ", ".join(formulas[:-1]) + (", or " if len(formulas) > 1 else "") + formulas[-1]
    kernel = {"enum": list(KERNELS), "default": DEFAULT_KERNEL, "description": f"b(t) = {text}"}
    return {**{k: keys[k] for k in first}, "kernel": kernel,
            **{k: v for k, v in keys.items() if k not in first}}


def recursive_kernels() -> list[str]:
    """Returns: the names of the kernels whose sum has the exact O(1) recursion."""
    return [name for name, spec in KERNELS.items() if spec.recursive]


def chosen(registry: dict[str, ContactLawSpec], given: dict) -> ContactLawSpec:
    """The law a section chooses by its keys: the first whose required keys are given, else
    the kind's default (the first).

    Args:
        registry: SLIPS, NORMALS, BOUNDS or COULOMBS.
        given: the section.

    Returns:
        The spec.
    """
    specs = list(registry.values())
    return next((s for s in specs if any(k in given for k in s.required())), specs[0])


def alternatives(registry: dict[str, ContactLawSpec], last: str = ", ") -> str:
    """The laws' required keys as a choice, e.g. "b, c1, c2, u1, or table".

    Args:
        registry: SLIPS, NORMALS, BOUNDS or COULOMBS.
        last: what joins the last two keys of a law (", "; " and ": "mu, or mu_s, mu_k and
            slip_length").

    Returns:
        The text.
    """
    return ", or ".join(_listed(s.required(), last) for s in registry.values())


def _listed(keys: tuple[str, ...], last: str) -> str:
    """Keys as a list, ``last`` joining the last two."""
    return last.join(filter(None, (", ".join(keys[:-1]), keys[-1])))


def field_keys(registry: dict[str, ContactLawSpec]) -> dict[str, str]:
    """The keys of one kind's laws that may be fields of x, y, z (``ContactKey.field``).

    Args:
        registry: KERNELS, SLIPS, NORMALS, BOUNDS or COULOMBS.

    Returns:
        {key: what it is}, in the registry's order.
    """
    return {k: use.field for spec in registry.values() for k, use in spec.keys.items()
            if use.field}


def builtin_keys(registry: dict[str, ContactLawSpec]) -> tuple[str, ...]:
    """Every key of one kind's laws.

    Args:
        registry: KERNELS, SLIPS, NORMALS, BOUNDS or COULOMBS.

    Returns:
        The keys, in the registry's order.
    """
    return tuple(key_schemas(registry))


def memory_kernel(kind: str, b0: float, beta: float = 0.0, alpha: float = 1.0,
                  tau: float = 1.0, table=None) -> MemoryKernel:
    """The memory kernel of a name (the registry's ``KERNELS``, app/model/contactregistry.py).

    Args:
        kind: a kernel's name, e.g. "exponential", "power" or "table".
        b0: the factor b0.
        beta: the exponential kernel's rate.
        alpha: the power law's exponent.
        tau: the power law's time scale.
        table: (t, b) points of the table kernel.

    Returns:
        The kernel.

    Raises:
        ValueError: an unknown ``kind``.
    """
    if kind not in KERNELS:
        raise ValueError(f"unknown kernel {kind!r}")
    given = {"beta": beta, "alpha": alpha, "tau": tau, "table": table}
    return KERNELS[kind].build({k: given[k] for k in KERNELS[kind].keys}, b0)


def coulomb_law(coulomb) -> CoulombLaw:
    """Coulomb's bound mu theta(s_n) p_n of a case's ``contact.friction.coulomb`` (its variant
    in the registry ``COULOMBS``, app/model/coulomb.py).

    Args:
        coulomb: the Coulomb (its variant's name and constants).

    Returns:
        The CoulombLaw: mu and the slip dependence theta(s) or None.
    """
    return COULOMBS[coulomb.law].build(coulomb.constants)


def slip_law(slip):
    """theta(s) of a case's ``contact.friction.slip`` (its law in the registry ``SLIPS`` of
    app/model/contactregistry.py).

    Args:
        slip: the Slip (its law's name and constants).

    Returns:
        The law's theta(s): a SlipWeakening, a TableSlip, ...
    """
    return SLIPS[slip.law].build(slip.constants)


def contact_law(contact, delta, const=None, x=None) -> ContactLaw:
    """The laws of a case's contact section.

    Args:
        contact: the case's ``contact`` section (c_nu or a compliance table, friction,
            memory).
        delta: the regularisation width (``solver.delta``).
        const: (name, value) -> the parameter in the laws (the forms' dolfinx Constants);
            None: the numbers themselves.
        x: where a parameter given as an expression of x, y, z (c_nu(x)) is evaluated: a
            UFL SpatialCoordinate (the forms) or the nodes' coordinates (n, d) (numpy);
            needed only by such a parameter (``varies_in_space``).

    Returns:
        The ContactLaw.
    """
    param = const if const is not None else (lambda name, value: value)
    fr = contact.friction
    friction = friction_law(fr, param)
    normal = _normal_law(contact, param, x)
    d = param("delta", delta) if fr is not None or contact.memory is not None else None
    return ContactLaw(
        normal=normal,
        memory=None if contact.memory is None else RegularisedPositivePart(d),
        friction=friction, norm=None if fr is None else RegularisedNorm(d))


def friction_law(fr, const=None) -> ScalarLaw | None:
    """The friction potential psi of a case's ``contact.friction``.

    Args:
        fr: the Friction (a bound of ``BOUNDS``, app/model/contactregistry.py: b, c1, c2, u1
            of (4.2), a table, ...; Coulomb's; the user's law), or None.
        const: (name, value) -> the parameter in the law (the forms' Constants); None: the
            numbers themselves.

    Returns:
        The bound's law (a PiecewiseLinearFriction, a TableFriction, ...),
        PiecewiseLinearFriction psi(rho) = rho for Coulomb, or the PythonLawSlot of the
        user's law; None without friction.
    """
    param = const if const is not None else (lambda name, value: value)
    if fr is None:
        return None
    if getattr(fr, "python", None) is not None:
        return PythonLawSlot("contact.friction", fr.python)
    if getattr(fr, "coulomb", None) is not None:    # psi(rho) = rho, its factor mu p_n
        return PiecewiseLinearFriction(*(param(k, v) for k, v in COULOMB_PSI.items()))
    return BOUNDS[fr.law].build(fr.constants, param)


def _normal_law(contact, param, x):
    """The normal compliance of a contact section (None: none): its law of ``NORMALS``
    (app/model/contactregistry.py: (4.1) for a number c_nu without m, else c_nu(x) (r^+)^m,
    the table's law, ...), or the user's law's place."""
    normal = contact.normal
    if normal is None:
        return None
    if getattr(contact, "compliance_python", None) is not None:
        return PythonLawSlot("contact.normal_compliance", contact.compliance_python)
    return NORMALS[normal.law].build(normal.constants, param, x)
