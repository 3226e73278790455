"""The declaration of a built-in contact law: ``ContactLawSpec``, one per law, written in the
law's own module beside its class and collected by app/model/contactregistry.py (the
viscoplastic laws' ``LawSpec`` is app/model/lawspec.py).

Five kinds of contact law are chosen by the case file, each a registry of specs:

- the memory kernels b(t) of ``contact.memory`` (``KERNELS``), chosen by the key ``kernel``
  (app/model/memory_kernels.py);
- the slip dependence theta(s) of ``contact.friction.slip`` (``SLIPS``), chosen by the keys
  given (theta_inf, s0 or table; app/model/contact_laws.py, contact_tables.py);
- the normal compliance p(r) of ``contact.normal_compliance`` (``NORMALS``), chosen by the
  keys given (c_nu with m, or table);
- the friction bound psi'(rho) of ``contact.friction`` (``BOUNDS``), chosen by the keys given
  (b, c1, c2, u1, or table; a law written by the user keeps its own keys, app/case/rules.py);
- the variants of Coulomb's bound mu p_n of ``contact.friction.coulomb`` (``COULOMBS``),
  chosen by the keys given (mu, or mu_s, mu_k and slip_length; app/model/coulomb.py).

A spec holds what the rest of the code needs to know of a law besides its values: its keys
(``ContactKey``: the JSON schema of the value with its description, required or not), its
formula for the schema's description of the key that chooses it, its checks on the data as
given, its factory from the Case's constants and the stress levels its constants set (the
blow-up bound of app/post/divergence.py).  The case layer (schema, rules, model), the reports
and the blow-up monitor loop over the registries; nothing here imports numpy or the model.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

from vpcontact.io.errors import CaseError
from vpcontact.model.lawspec import NONNEGATIVE, NUMBER, POSITIVE  # noqa: F401 (re-exported)

# the JSON schema of a contact law's expression or table (app/case/schema.py's fragments);
# a constant's are the viscoplastic laws' (app/model/lawspec.py)
EXPRESSION = {"type": "string", "minLength": 1, "maxLength": 500}
TABLE = {"type": "array", "minItems": 1, "maxItems": 100000,
         "items": {"type": "array", "items": NUMBER, "minItems": 2, "maxItems": 2}}


@dataclass(frozen=True)
class ContactKey:
    """One constant of a contact law, a key of its section.

    Attributes:
        schema: the JSON schema of its value with its description (the case-file reference).
        required: the law needs the key (else it is optional).
        only: where the key is given with another law of its kind, the refusal's reason
            (e.g. "only with c_nu (a table gives p(r) itself)"); "" for a key the rules do
            not refuse there.
        field: what the value is where it may be an expression in x, y, z, a field >= 0 on
            Gamma3 (e.g. "the compliance coefficient": its expression is checked to parse
            and, at the data's sample points, to be >= 0), or "": a number or table only.
    """

    schema: dict
    required: bool = True
    only: str = ""
    field: str = ""


class Drawing(NamedTuple):
    """How the figure of the case's laws (Fig. 2, app/post/linefigures.py) draws a friction
    bound psi'(rho).

    Attributes:
        upto: the largest slip rho drawn [m].
        label: the curve's label.
        stick: the bound at zero slip, drawn as the stick interval [0, stick].
        stick_label: its label.
        mark: (slip, name) marked on the slip axis, or None.
    """

    upto: float
    label: str
    stick: float
    stick_label: str
    mark: tuple | None = None


@dataclass(frozen=True)
class ContactLawSpec:
    """The declaration of one built-in contact law (see the module docstring).

    Attributes:
        name: the law's name: the value of the key that chooses it (a memory kernel's
            ``kernel``), or the name the Case's section carries (a law chosen by its keys).
        formula: the law in a few words, for the schema's description of the key that
            chooses it (e.g. "b0 exp(-beta t)").
        keys: its keys, in the schema's order.
        build: (constants, ...) -> the law object: constants is {key: value} of the keys
            given (the Case's section ``constants``); a kind's further arguments are its
            registry's (app/model/contactregistry.py).
        check: (given, path, source) -> None, raising CaseError: the rules beyond the schema
            on the section as given (default-filled), path its key (e.g.
            "contact.friction.slip"), or None.
        levels: (constants) -> [stress levels] its constants set, for the blow-up bound
            (app/post/divergence.py; a kind's further arguments as ``build``), or None.
        recursive: a memory kernel with the exact O(1) recursion of its sum.
        title: its name in the run log's active terms, or "" (the kind's); a Coulomb
            variant's is a format string of its constants (e.g. "mu = {mu:g}").
        drawing: (constants) -> the ``Drawing`` of a friction bound in Fig. 2, or None.
    """

    name: str
    formula: str
    keys: dict[str, ContactKey]
    build: Callable
    check: Callable | None = None
    levels: Callable | None = None
    recursive: bool = False
    title: str = ""
    drawing: Callable | None = None

    def required(self) -> tuple[str, ...]:
        """Returns: the keys the law needs, in the order of ``keys``."""
        return tuple(k for k, key in self.keys.items() if key.required)

    def constants(self, section: dict) -> dict:
        """The law's constants from its validated section.

        Args:
            section: the section (its required keys present).

        Returns:
            {key: value} of the keys given: a number as float, an expression (str) as it
            is, a table as a tuple of float pairs.
        """
        return {k: _value(section[k]) for k in self.keys if k in section}


def _value(v):
    """A constant of a section: a number as float, an expression as it is, a table
    [[a, b], ...] as a tuple of float pairs."""
    if isinstance(v, str):
        return v
    if isinstance(v, (list, tuple)):
        return tuple((float(a), float(b)) for a, b in v)
    return float(v)


def table_points(rows, path: str, source: str) -> tuple[list, list]:
    """The abscissae of a law's table start at 0 and increase strictly.

    Args:
        rows: the table [[x, y], ...].
        path: its key, for the message.
        source: the case file, for the message.

    Returns:
        (xs, ys), the table's columns.

    Raises:
        CaseError: the first column does not start at 0 or does not increase strictly.
    """
    xs, ys = [r[0] for r in rows], [r[1] for r in rows]
    if xs[0] != 0.0 or any(b <= a for a, b in zip(xs, xs[1:])):
        raise CaseError(f"{source}: {path}: the first column must start at 0 and increase "
                        "strictly")
    return xs, ys


def table_values(table) -> list[float]:
    """The absolute values of a table's second column (a law's stress levels).

    Args:
        table: the table ((a, b), ...).

    Returns:
        [|b|, ...].
    """
    return [abs(float(b)) for _, b in table]
