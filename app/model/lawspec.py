"""The declaration of a built-in viscoplastic law: ``LawSpec``, one per law, written in the
law's own module beside its class (app/model/viscoplastic.py: perzyna, power;
app/model/norton.py; app/model/chaboche.py) and collected by app/model/lawregistry.py.

A spec holds everything the rest of the code needs to know of a law besides its rates
(1.2)-(1.3): the keys of ``material.viscoplastic`` it uses (``LawKey``: the schema of the
value, what it is, its unit, a default where it has one, else required), its title for the
run log, what kappa0 means for it, the unit of kappa, its extra checks on the case's data,
the growth of kappa under a stress bound (the blow-up bound of app/post/divergence.py) and
the factory of the law object.  The case layer (schema, rules, model), the reports and the
blow-up monitor loop over the registry; nothing here imports numpy or the model.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

# the JSON schema of a law's constant (app/case/schema.py's fragments)
NUMBER = {"type": "number"}
POSITIVE = {"type": "number", "exclusiveMinimum": 0}
NONNEGATIVE = {"type": "number", "minimum": 0}
EXPONENT = {"type": "number", "minimum": 1}


@dataclass(frozen=True)
class LawKey:
    """One constant of a law, a key of ``material.viscoplastic``.

    Attributes:
        schema: the JSON schema of its value (type and range).
        what: what it is, in words (the message of a missing key; the schema's description
            without ``doc``).
        unit: its unit ("-": dimensionless), for the reports.
        default: the value where the key is absent, or None: the key is required.
        doc: its description in the case-file reference, or "" (then ``what``).
    """

    schema: dict
    what: str
    unit: str
    default: float | None = None
    doc: str = ""

    @property
    def required(self) -> bool:
        """Returns: the key has no default (the law requires it)."""
        return self.default is None


@dataclass(frozen=True)
class LawSpec:
    """The declaration of one built-in viscoplastic law (see the module docstring).

    Attributes:
        name: the law's name in the case file (``material.viscoplastic.law``).
        title: its name in the run log's active terms (e.g. "Norton").
        summary: the law in one sentence, for the schema's description of ``law``.
        kappa0: what kappa0 means for the law, for the schema's description of ``kappa0``.
        kappa_unit: the unit of kappa (its largest component) for the figures.
        keys: its constants, in the order of the class's constructor (and of ``constants()``).
        build: (vp, elasticity, plane) -> the law: vp has the constants as attributes (the
            Case's ``Viscoplastic``), plane is ``material.plane``.
        kappa_growth: (vp, T, S) -> how far the largest component of kappa can move in
            [0, T] under stresses of von Mises norm at most S (may raise OverflowError).
        shown: the keys the title shows with their values.
        check: (vp, source) -> None, raising CaseError: the rules beyond the schema on the
            section as given (default-filled), or None.
        check_plane_strain: the same in 2D plane strain, or None.
        carries_sigma33: in plane strain the law carries sigma_33 with the 3D E, nu of an
            isotropic E (app/model/planestrain.py).
        stress_scaling: (vp, factor) -> {key: multiplier} of the section's keys that make
            sigma scale by ``factor`` with u and the viscoplastic strain unchanged (E scaled
            too; the stability sweep's scaled variants, app/studies/variantsections.py), or
            the reason (a str) the data cannot be scaled; None: not known.
    """

    name: str
    title: str
    summary: str
    kappa0: str
    kappa_unit: str
    keys: dict[str, LawKey]
    build: Callable
    kappa_growth: Callable
    shown: tuple = ()
    check: Callable | None = None
    check_plane_strain: Callable | None = None
    carries_sigma33: bool = False
    stress_scaling: Callable | None = None

    def required(self) -> dict[str, str]:
        """The keys the law requires, with what they are.

        Returns:
            {key: what}, in the order of ``keys``.
        """
        return {k: key.what for k, key in self.keys.items() if key.required}

    def constants(self, section: dict) -> dict[str, float]:
        """The law's constants from a validated ``material.viscoplastic`` section.

        Args:
            section: the section (its required keys present).

        Returns:
            {key: float}, a default where the key is absent.
        """
        return {k: float(section.get(k, key.default)) for k, key in self.keys.items()}

    def with_units(self, values: dict) -> dict[str, tuple]:
        """The constants with their units, as ``ViscoplasticLaw.constants`` gives them.

        Args:
            values: {key: value} of the law's keys.

        Returns:
            {key: (value, unit)}, in the order of ``keys``.
        """
        return {k: (values[k], key.unit) for k, key in self.keys.items()}

    def constants_of(self, law) -> dict[str, tuple]:
        """A law object's constants with their units (``ViscoplasticLaw.constants``).

        Args:
            law: the law (its constants as attributes of the keys' names).

        Returns:
            {key: (value, unit)}, in the order of ``keys``.
        """
        return self.with_units({k: getattr(law, k) for k in self.keys})

    def title_of(self, vp) -> str:
        """The law's title with the values of its ``shown`` keys.

        Args:
            vp: the law's constants as attributes (the Case's ``Viscoplastic``).

        Returns:
            e.g. "Norton (A = 0.001, n = 3)", or the bare title.
        """
        if not self.shown:
            return self.title
        return f"{self.title} ({', '.join(f'{k} = {getattr(vp, k):g}' for k in self.shown)})"
