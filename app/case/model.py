"""The typed model of a case: one frozen dataclass per section, and the Case built from a
validated, default-filled mapping (``build_case``).

Adding a key to the case file: its entry in the schema (app/case/schema.py), its field here
(and its line in ``build_case``), and its rule in app/case/rules.py if it has one beyond the
schema's.  A built-in viscoplastic law's keys are none of these: its LawSpec declares them
(app/model/lawspec.py, in the law's module), and the schema, the rules and ``Viscoplastic``
read them from the registry app/model/lawregistry.py; a built-in contact law's keys (a
memory kernel, a slip law, a normal compliance, a friction bound, a variant of Coulomb's
bound) likewise by its ContactLawSpec (app/model/contactspec.py), read from
app/model/contactregistry.py into the tagged sections ``Memory``, ``Slip``, ``Compliance``,
``Friction`` and ``Coulomb``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from vpcontact.model.contactregistry import (
    BOUNDS,
    COULOMBS,
    KERNELS,
    NORMALS,
    SLIPS,
    builtin_keys,
    chosen,
)
from vpcontact.model.lawregistry import DEFAULT_LAW, LAWS, USER_LAW, key_owners

# solver.method's former names -> the names the Case holds
METHOD_NAMES = {"fast": "condensed"}


@dataclass(frozen=True)
class MeshSpec:
    """The ``mesh`` section: dimension; the built-in rectangle / box (sides, structured n or
    unstructured h, its builder ``engine``) or a gmsh file.

    For a ``file`` (an absolute path of a .msh or .geo), kind is "file" and L1, L2, L3, n,
    h, diagonal are None; ``size`` scales a .geo's characteristic lengths.
    """

    dim: int
    L1: float | None
    L2: float | None
    L3: float | None
    kind: str
    n: int | None
    h: float | None
    diagonal: str | None
    file: str | None = None
    size: float = 1.0
    engine: str = "gmsh"

    @property
    def builtin(self) -> bool:
        """The built-in rectangle / box (not a mesh.file)."""
        return self.file is None


@dataclass(frozen=True)
class Boundaries:
    """The ``boundaries`` section: the groups (names, or physical tags of a mesh.file) of
    Gamma1 (``clamped``, u = 0) and Gamma3 (``contact``)."""

    clamped: tuple
    contact: tuple


class _Constants:
    """A built-in law's constants read as attributes (``vp.lambda1``, ``slip.theta_inf``):
    a key of another law of its kind (``_kind_keys``: the viscoplastic laws' of
    app/model/lawregistry.py, a contact law's registry ``REGISTRY`` of
    app/model/contactregistry.py) reads as None."""

    REGISTRY: dict = {}

    def _kind_keys(self):
        """Returns: the keys of every law of the kind."""
        return builtin_keys(self.REGISTRY)

    def __getattr__(self, name: str):
        """A constant of the law by its key (None for a key of another law of its kind).

        Args:
            name: the key.

        Returns:
            Its value, or None.

        Raises:
            AttributeError: not a key of any law of the kind.
        """
        constants = self.__dict__.get("constants")
        if constants is not None and name in constants:
            return constants[name]
        if constants is not None and name in self._kind_keys():
            return None
        raise AttributeError(f"{type(self).__name__} has no attribute {name!r}")


@dataclass(frozen=True)
class Viscoplastic(_Constants):
    """``material.viscoplastic``: the law (a built-in law's name, app/model/lawregistry.py,
    or "python"), kappa0, the built-in law's ``constants`` ({key: float}: its keys of the
    case file, defaults filled, as its LawSpec declares them), the user's class and its
    params (law "python").  A constant reads as an attribute too (``vp.lambda1``); a key of
    another built-in law reads as None."""

    law: str
    kappa0: float | str
    constants: dict = field(default_factory=dict)
    cls: str | None = None              # law python: the class of --law-module
    params: dict | None = None          # law python: its constructor's keyword arguments

    def _kind_keys(self):
        """Returns: the keys of every built-in viscoplastic law."""
        return key_owners()


@dataclass(frozen=True)
class Orthotropic:
    """``material.elasticity.orthotropic``: the engineering constants E [E1, E2(, E3)], nu
    [nu12(, nu13, nu23)], G [G12(, G13, G23)] and the material axes (app/case/anisotropy.py)."""

    E: tuple
    nu: tuple
    G: tuple
    axes: tuple


@dataclass(frozen=True)
class Anisotropic:
    """``material.elasticity``: orthotropic constants or a Voigt matrix (rows, engineering
    strains), the other None."""

    orthotropic: Orthotropic | None = None
    voigt: tuple | None = None


@dataclass(frozen=True)
class Material:
    """The ``material`` section: E, nu (numbers, or expressions in x, y, z taken per cell;
    None with ``elasticity``), the viscoplastic law or None (elastic), the 2D model: "stress"
    (plane stress) or "strain" (plane strain), None in 3D; and the anisotropic
    ``elasticity`` instead of E, nu (None: isotropic)."""

    E: float | str | None
    nu: float | str | None
    viscoplastic: Viscoplastic | None
    plane: str | None = "stress"
    elasticity: Anisotropic | None = None


@dataclass(frozen=True)
class Slip(_Constants):
    """``contact.friction.slip``: its law's name in ``SLIPS`` (app/model/contactregistry.py:
    "weakening", theta(s) = theta_inf + (1 - theta_inf) exp(-s/s0); "table", [[s, theta],
    ...]) and its constants ({key: value}, as attributes too)."""

    REGISTRY = SLIPS
    law: str
    constants: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Compliance(_Constants):
    """``contact.normal_compliance``, a built-in law: its name in ``NORMALS``
    (app/model/contactregistry.py: "power", c_nu (r^+)^m with c_nu a number or an
    expression in x, y, z and m absent for (4.1); "table", [[r, p], ...]) and its constants
    ({key: value}, as attributes too)."""

    REGISTRY = NORMALS
    law: str
    constants: dict = field(default_factory=dict)


@dataclass(frozen=True)
class PythonLaw:
    """A contact law written by the user (``law: python``): the class of --law-module and
    its constructor's keyword arguments (app/model/lawmodule.py builds Class(**params))."""

    cls: str
    params: dict


@dataclass(frozen=True)
class Coulomb(_Constants):
    """``contact.friction.coulomb``: its variant's name in ``COULOMBS``
    (app/model/contactregistry.py: "mu", the bound mu p_n, p_n the contact pressure;
    "static/kinetic", mu(s) p_n, mu(s) = mu_s - (mu_s - mu_k) min(s / slip_length, 1)) and
    its constants ({key: value}, as attributes too).  ``mu`` is the variant's coefficient
    (mu_s of the static/kinetic law)."""

    REGISTRY = COULOMBS
    law: str
    constants: dict = field(default_factory=dict)

    @property
    def mu(self) -> float:
        """The coefficient of the bound mu theta(s_n) p_n (the variant's ``CoulombLaw``)."""
        return COULOMBS[self.law].build(self.constants).mu

    @property
    def has_slip(self) -> bool:
        """The variant's bound has a slip dependence theta(s_n) (static/kinetic: mu(s) =
        mu_s theta(s)), so the accumulated slip s_n is a state."""
        return COULOMBS[self.law].build(self.constants).slip is not None

    @property
    def title(self) -> str:
        """The law in words (its spec's title with the constants): 'Coulomb friction mu p_n
        (mu = ..)' or 'Coulomb friction mu(s) p_n (mu_s = .., mu_k = .. over slip length
        ..)'."""
        return COULOMBS[self.law].title.format(**self.constants)


@dataclass(frozen=True)
class Friction(_Constants):
    """``contact.friction``: a built-in bound (``law``, its name in ``BOUNDS`` of
    app/model/contactregistry.py: "4.2", law (4.2) of b, c1, c2, u1; "table", the friction
    stress [[rho, tau], ...]; its ``constants`` as attributes too), or the user's law
    ``python``, or ``coulomb`` (then law is None and every constant reads as None); and
    the slip dependence or None."""

    REGISTRY = BOUNDS
    law: str | None
    constants: dict = field(default_factory=dict)
    slip: Slip | None = None
    python: PythonLaw | None = None
    coulomb: Coulomb | None = None


@dataclass(frozen=True)
class Memory(_Constants):
    """``contact.memory``: the memory kernel b(t) (``kernel``, its name in ``KERNELS`` of
    app/model/contactregistry.py, with its ``constants``, as attributes too) and how its
    sum is computed; b0 a number or an expression of x, y, z (b(t, x) = b0(x) times the
    kernel's shape)."""

    REGISTRY = KERNELS
    b0: float | str
    kernel: str
    constants: dict
    sum: str


@dataclass(frozen=True)
class ContactPair:
    """One entry of ``contact.pairs``: the group ``surface`` whose nodes are projected onto
    the group ``target`` of another body, the extra gap g [m] of the bound
    u_nu <= d + g (d the measured initial distance) and the coupling rule ("mortar" or
    "node_to_segment", app/model/pairs.py); ``laws``: the pair's own contact laws (a
    Contact without g, direction and pairs) where the pairs' laws differ, else None (the
    contact section's laws serve every pair)."""

    surface: str | int
    target: str | int
    g: float = 0.0
    rule: str = "mortar"
    laws: Contact | None = None


@dataclass(frozen=True)
class Contact:
    """The ``contact`` section: gap g (a number, an expression in x, y, z, or None),
    the normal compliance ``normal`` (a built-in law's ``Compliance``, the user's
    ``PythonLaw``, or None), friction, memory, and the fixed unit approach direction (None:
    the outward normal of Gamma3), and the pairs of two bodies (``ContactPair``; empty: one
    body against the rigid foundation)."""

    g: float | str | None
    normal: Compliance | PythonLaw | None
    friction: Friction | None
    memory: Memory | None = None
    direction: tuple | None = None
    pairs: tuple = ()

    @property
    def c_nu(self) -> float | str | None:
        """The coefficient c_nu of the built-in compliance c_nu (r^+)^m, else None."""
        return self.normal.c_nu if isinstance(self.normal, Compliance) else None

    @property
    def compliance_python(self) -> PythonLaw | None:
        """The user's normal compliance (``law: python``), or None."""
        return self.normal if isinstance(self.normal, PythonLaw) else None

    @property
    def compliance(self) -> bool:
        """A normal compliance law is present (c_nu, a table or the user's law)."""
        return self.normal is not None

    @property
    def sections(self) -> tuple:
        """The sets of laws on Gamma3: (this section,) where one set serves all of Gamma3,
        else each pair's own (``ContactPair.laws``, in the pairs' order)."""
        if self.pairs and self.pairs[0].laws is not None:
            return tuple(p.laws for p in self.pairs)
        return (self,)

    @property
    def compliances(self) -> bool | tuple:
        """A normal compliance law is present: one bool, or with laws per pair one per pair
        (app/io/output.py: ``classify``)."""
        sections = self.sections
        return sections[0].compliance if len(sections) == 1 else \
            tuple(c.compliance for c in sections)

    @property
    def active(self) -> bool:
        """Any Gamma3 term present (or a pair of bodies: its bound u_nu <= d + g)."""
        return bool(self.pairs) or self.compliance or any(
            x is not None for x in (self.g, self.friction, self.memory))


@dataclass(frozen=True)
class Loads:
    """The ``loads`` section: body force f0; per group (a name or physical tag): tractions,
    normal pressures and prescribed displacements (components, None where free)."""

    f0: tuple | None
    traction: dict
    pressure: dict = field(default_factory=dict)
    displacement: dict = field(default_factory=dict)
    rigid: dict = field(default_factory=dict)


@dataclass(frozen=True)
class RigidCap:
    """One group of ``loads.rigid``: its d(d+1)/2 rigid amplitudes (2D: u_x, u_y, theta; 3D:
    u_x, u_y, u_z, theta_x, theta_y, theta_z), each loaded or prescribed.

    Attributes:
        load: per amplitude the force or moment component given (None: not given, 0).
        prescribed: per amplitude the displacement or rotation given (None: free).
        reference: the reference point X_ref, or None (the group's centroid).
    """

    load: tuple
    prescribed: tuple
    reference: tuple | None = None

    @classmethod
    def from_data(cls, data: dict, dim: int) -> RigidCap:
        """The cap of a case's ``loads.rigid.<group>`` mapping (checked by caprules).

        Args:
            data: force, moment, displacement, rotation, reference (each optional).
            dim: the mesh dimension.

        Returns:
            The RigidCap.
        """
        turns = 1 if dim == 2 else 3

        def amplitudes(move: str, turn: str) -> tuple:
            t = data.get(turn)
            return tuple(data.get(move) or [None] * dim) + \
                tuple(t if isinstance(t, list) else [t] * turns)

        ref = data.get("reference")
        return cls(amplitudes("force", "moment"), amplitudes("displacement", "rotation"),
                   tuple(ref) if ref is not None else None)


@dataclass(frozen=True)
class Initial:
    """The ``initial`` section: u0 and sigma0, or None (zero)."""

    u0: tuple | None
    sigma0: tuple | None


@dataclass(frozen=True)
class TimeGrid:
    """The ``time`` section: the time points t_0..t_N, the history scheme, adaptivity."""

    times: tuple
    uniform: bool
    scheme: str = "explicit"
    adaptive: dict | None = None

    @property
    def T(self) -> float:
        """The final time t_N."""
        return self.times[-1]

    @property
    def N(self) -> int:
        """The number of steps."""
        return len(self.times) - 1


@dataclass(frozen=True)
class Numerics:
    """The ``solver`` section: step solver ("snes_vi", "condensed" or "auto"; a case file's
    "fast" is read as "condensed"), delta, Gamma3 quadrature, SNES VI's linear solver."""

    method: str
    delta: float
    quadrature: str
    gauss_degree: int
    linear: str = "auto"


@dataclass(frozen=True)
class OutputSpec:
    """The ``output`` section: field output and checkpoint intervals (steps)."""

    every: int
    checkpoint_every: int | None = None


@dataclass(frozen=True)
class Case:
    """A validated case: its sections as separate objects, and the raw mapping."""

    name: str
    source: str
    mesh: MeshSpec
    material: Material | None      # None with materials
    contact: Contact
    loads: Loads
    initial: Initial
    time: TimeGrid
    numerics: Numerics
    petsc: dict
    output: OutputSpec
    raw: dict = field(repr=False)
    data_stress: float = 0.0     # the stress scale of loads and initial data (validation)
    boundaries: Boundaries = Boundaries(("left",), ("bottom",))
    # the PETSc defaults (DEFAULT_PETSC scaled to the case) under petsc: rescale_for_length
    # replaces those of them that were not given
    petsc_defaults: dict = field(default_factory=dict, repr=False)
    # materials: physical group of cells (name or tag) -> Material, or None (material)
    materials: dict | None = None
    # where the laws settled from the pairs into the contact section were written:
    # contact.<law> -> contact.pairs[i].<law> (app/case/pairrules.py, for messages)
    laws_written: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def dim(self) -> int:
        """The space dimension."""
        return self.mesh.dim

    @property
    def all_materials(self) -> tuple:
        """The Materials of the body: (material,) or those of materials, in the given order."""
        return (self.material,) if self.materials is None else tuple(self.materials.values())

    def active_terms(self) -> list[str]:
        """The model's terms this case has, for the run log.

        Returns:
            Their names.
        """
        first = self.all_materials[0]
        kind = _elasticity_kind(first)
        terms = [f"plane-{first.plane} {kind}elasticity" if self.dim == 2
                 else f"{kind or 'isotropic '}elasticity (3D)"]
        if self.materials is not None:
            terms.append(f"{len(self.materials)} materials (groups "
                         f"{', '.join(map(str, self.materials))})")
        laws = [m.viscoplastic for m in self.all_materials if m.viscoplastic]
        if laws:
            name = ", ".join(dict.fromkeys(_law_title(vp) for vp in laws))
            terms.append(f"{name} viscoplastic history H_n, kappa_n"
                         + (" (implicit, right end point)" if self.time.scheme == "implicit"
                            else " (explicit, as in the paper)"))
        laws = list(dict.fromkeys(t for c in self.contact.sections for t in _law_terms(c)))
        normal = [t for t in laws if t.startswith("normal compliance")]
        terms += normal
        if self.contact.pairs:
            terms.append(f"{len(self.contact.pairs)} contact pair(s) of two bodies "
                         "([u]_nu <= d + g; " + ", ".join(dict.fromkeys(
                             p.rule.replace("_", "-") for p in self.contact.pairs)) + ")")
            if len(self.contact.sections) > 1:
                terms.append("laws per pair")
        if self.contact.g is not None:
            terms.append("unilateral constraint u_nu <= g")
        return terms + [t for t in laws if t not in normal]

    def omitted_terms(self) -> list[str]:
        """The model's terms this case leaves out (nothing is allocated or computed for them).

        Returns:
            Their names.
        """
        out = []
        if not any(m.viscoplastic for m in self.all_materials):
            out.append("viscoplastic history (elastic body)")
        sections = self.contact.sections
        if not any(c.compliance for c in sections):
            out.append("normal compliance")
        if self.contact.g is None and not self.contact.pairs:
            out.append("unilateral constraint")
        if all(c.memory is None for c in sections):
            out.append("memory term")
        if all(c.friction is None for c in sections):
            out.append("friction")
        elif all(c.friction is None or c.friction.slip is None for c in sections):
            out.append("slip dependence")
        return out


def _law_terms(c: Contact) -> list[str]:
    """The names of the contact laws of one set of laws (Contact.sections)."""
    terms = []
    if c.compliance:
        user = c.compliance_python
        terms.append("normal compliance" if user is None else
                     f"normal compliance (the user's law {user.cls}, --law-module)")
    if c.memory is not None:
        terms.append(f"memory term xi_n ({c.memory.kernel} kernel)")
    if c.friction is not None:
        fr = c.friction
        terms.append(f"friction (the user's law {fr.python.cls}, --law-module)"
                     if fr.python is not None else
                     fr.coulomb.title if fr.coulomb is not None else BOUNDS[fr.law].title)
        if fr.slip is not None:
            terms.append("slip-dependent friction theta(s_n)")
    return terms


def case_name(data: dict, source: str) -> str:
    """The case's name.

    Args:
        data: the case mapping.
        source: the case file.

    Returns:
        ``name``, or the file name without its extension (app/case/rules.py's check_name
        refuses one that cannot name an output directory).
    """
    return data.get("name") or Path(source).stem


def build_case(data: dict, source: str, time_grid: TimeGrid, petsc: dict) -> Case:
    """The :class:`Case` of a validated, default-filled case mapping.

    Args:
        data: the mapping, validated and with its defaults filled and settled.
        source: the case file, for messages (and the default name).
        time_grid: the time grid of the ``time`` section.
        petsc: the PETSc options in force (app/solvers/options.py).

    Returns:
        The Case (its data_stress and petsc_defaults are set by validation).
    """
    mesh, contact, loads = data["mesh"], data.get("contact", {}), data["loads"]
    init = data.get("initial", {})
    name = case_name(data, source)
    method = METHOD_NAMES.get(data["solver"]["method"], data["solver"]["method"])
    return Case(
        name=name,
        source=source,
        mesh=_mesh_spec(mesh),
        material=_material(data["material"]) if "material" in data else None,
        materials={group: _material(m) for group, m in data["materials"].items()}
        if "materials" in data else None,
        contact=_contact(contact),
        loads=Loads(tuple(loads["f0"]) if "f0" in loads else None,
                    {k: tuple(v) for k, v in loads.get("traction", {}).items()},
                    dict(loads.get("pressure", {})),
                    {k: tuple(v) for k, v in loads.get("displacement", {}).items()},
                    {k: RigidCap.from_data(v, mesh["dim"])
                     for k, v in loads.get("rigid", {}).items()}),
        boundaries=Boundaries(tuple(data["boundaries"]["clamped"]),
                              tuple(data["boundaries"]["contact"])),
        initial=Initial(tuple(init["u0"]) if "u0" in init else None,
                        tuple(map(tuple, init["sigma0"])) if "sigma0" in init else None),
        time=time_grid,
        numerics=Numerics(**{**data["solver"], "method": method}),
        petsc=petsc,
        output=OutputSpec(**data["output"]),
        raw=data,
    )


def _contact(contact: dict) -> Contact:
    """The Contact of a contact section (or of a pair's own laws: no g, direction, pairs)."""
    fr, mem = contact.get("friction"), contact.get("memory")
    g, d = contact.get("g"), contact.get("direction")
    pairs = contact.get("pairs", ())
    laws = ("normal_compliance", "memory", "friction")
    own = any(key in p for p in pairs for key in laws)
    return Contact(
        g if isinstance(g, str) else float(g) if g is not None else None,
        _compliance(contact.get("normal_compliance")),
        _friction(fr) if fr else None,
        _memory(mem) if mem else None,
        tuple(float(x) / math.hypot(*d) for x in d) if d is not None else None,
        tuple(ContactPair(p["surface"], p["target"], float(p.get("g", 0.0)),
                          p.get("rule", "mortar"),
                          _contact({k: p[k] for k in laws if k in p}) if own else None)
              for p in pairs))


def _memory(mem: dict) -> Memory:
    """The Memory of contact.memory: b0, its kernel's constants (``KERNELS``), the sum."""
    b0 = mem["b0"] if isinstance(mem["b0"], str) else float(mem["b0"])
    return Memory(b0, mem["kernel"], KERNELS[mem["kernel"]].constants(mem), mem["sum"])


def _compliance(nc: dict | None) -> Compliance | PythonLaw | None:
    """The law of contact.normal_compliance: a built-in law of ``NORMALS`` chosen by its
    keys, the user's law, or None (absent)."""
    if not nc:
        return None
    if nc.get("law") == "python":
        return _python_law(nc)
    spec = chosen(NORMALS, nc)
    return Compliance(spec.name, spec.constants(nc))


def _python_law(section: dict) -> PythonLaw | None:
    """The PythonLaw of a contact law section with ``law: python``, else None."""
    if section.get("law") != "python":
        return None
    return PythonLaw(section["class"],
                     {k: float(v) for k, v in section.get("params", {}).items()})


def _friction(fr: dict) -> Friction:
    """The Friction of contact.friction: a bound of ``BOUNDS`` chosen by its keys, the
    user's law or Coulomb's; its slip law of ``SLIPS``."""
    slip = fr.get("slip")
    s = None
    if slip:
        spec = chosen(SLIPS, slip)
        s = Slip(spec.name, spec.constants(slip))
    if "coulomb" in fr or fr.get("law") == "python":
        return Friction(None, {}, s, _python_law(fr),
                        _coulomb(fr["coulomb"]) if "coulomb" in fr else None)
    bound = chosen(BOUNDS, fr)
    return Friction(bound.name, bound.constants(fr), s)


def _coulomb(c: dict) -> Coulomb:
    """The Coulomb of contact.friction.coulomb: its variant of ``COULOMBS`` chosen by its
    keys (mu, or mu_s, mu_k and slip_length)."""
    spec = chosen(COULOMBS, c)
    return Coulomb(spec.name, spec.constants(c))


def _material(material: dict) -> Material:
    """The Material of a material section (``material`` or an entry of ``materials``)."""
    vp = material.get("viscoplastic")
    return Material(_modulus(material.get("E")), _modulus(material.get("nu")),
                    _viscoplastic(vp) if vp else None, material.get("plane"),
                    _anisotropic(material.get("elasticity")))


def _elasticity_kind(material: Material) -> str:
    """The elasticity's kind for the list of terms ("" for the paper's isotropic numbers)."""
    spec = material.elasticity
    if spec is not None:
        return "orthotropic " if spec.orthotropic is not None else "anisotropic (Voigt) "
    if isinstance(material.E, str) or isinstance(material.nu, str):
        return "isotropic per-cell (E(x), nu(x)) "
    return ""


def _modulus(value) -> float | str | None:
    """E or nu: a number as float, an expression string, or None (absent)."""
    return value if value is None or isinstance(value, str) else float(value)


def _anisotropic(spec: dict | None) -> Anisotropic | None:
    """The Anisotropic of a material.elasticity section (lists as tuples), or None."""
    if spec is None:
        return None
    o = spec.get("orthotropic")
    return Anisotropic(
        Orthotropic(tuple(map(float, o["E"])), tuple(map(float, o["nu"])),
                    tuple(map(float, o["G"])), _rows(o["axes"])) if o is not None else None,
        _rows(spec["voigt"]) if "voigt" in spec else None)


def _rows(matrix) -> tuple:
    """A list of lists of numbers as a tuple of tuples of floats."""
    return tuple(tuple(map(float, r)) for r in matrix)


def _viscoplastic(vp: dict) -> Viscoplastic:
    """The Viscoplastic of the material.viscoplastic section (law absent: perzyna; a
    constant absent: its LawSpec's default)."""
    law = vp.get("law", DEFAULT_LAW)
    kappa0 = vp["kappa0"] if isinstance(vp["kappa0"], str) else float(vp["kappa0"])
    if law == USER_LAW:
        return Viscoplastic(law, kappa0, cls=vp["class"],
                            params={k: float(v) for k, v in vp.get("params", {}).items()})
    return Viscoplastic(law, kappa0, LAWS[law].constants(vp))


def _law_title(vp: Viscoplastic) -> str:
    """The law's name and constants for the run log's active terms."""
    if vp.law == USER_LAW:
        return f"the user's law {vp.cls} (--law-module)"
    return LAWS[vp.law].title_of(vp)


def _mesh_spec(mesh: dict) -> MeshSpec:
    """The MeshSpec of the default-filled (and settled) mesh section."""
    if "file" in mesh:
        return MeshSpec(mesh["dim"], None, None, None, "file", None, None, None,
                        file=mesh["file"], size=float(mesh.get("size", 1.0)))
    return MeshSpec(mesh["dim"], float(mesh["L1"]), float(mesh["L2"]), float(mesh["L3"]),
                    mesh["kind"], int(mesh["n"]) if mesh["kind"] == "structured" else None,
                    float(mesh["h"]) if mesh["kind"] == "unstructured" else None,
                    mesh["diagonal"], engine=mesh["engine"])

