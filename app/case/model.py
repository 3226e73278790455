"""The typed model of a case: one frozen dataclass per section, and the Case built from a
validated, default-filled mapping (``build_case``).

Adding a key to the case file: its entry in the schema (app/case/schema.py), its field here
(and its line in ``build_case``), and its rule in app/case/rules.py if it has one beyond the
schema's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

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


@dataclass(frozen=True)
class Viscoplastic:
    """``material.viscoplastic``: the law ("perzyna" or "power"), lambda1, lambda2, kappa0,
    and the power law's exponent n and stress scale s_ref (None with perzyna)."""

    lambda1: float
    lambda2: float
    kappa0: float | str
    law: str = "perzyna"
    n: float | None = None
    s_ref: float | None = None


@dataclass(frozen=True)
class Material:
    """The ``material`` section: E, nu, the viscoplastic law or None (elastic), and the 2D
    model: "stress" (plane stress) or "strain" (plane strain); None in 3D."""

    E: float
    nu: float
    viscoplastic: Viscoplastic | None
    plane: str | None = "stress"


@dataclass(frozen=True)
class Slip:
    """``contact.friction.slip``: theta(s) = theta_inf + (1 - theta_inf) exp(-s/s0)."""

    theta_inf: float
    s0: float


@dataclass(frozen=True)
class Friction:
    """``contact.friction``: the parameters of law (4.2) and the slip dependence or None."""

    b: float
    c1: float
    c2: float
    u1: float
    slip: Slip | None = None


@dataclass(frozen=True)
class Memory:
    """``contact.memory``: the memory kernel b(t) and how its sum is computed."""

    b0: float
    beta: float
    kernel: str
    alpha: float | None
    tau: float | None
    table: tuple | None
    sum: str


@dataclass(frozen=True)
class Contact:
    """The ``contact`` section: gap g (a number, an expression in x, y, z, or None),
    normal compliance c_nu (4.1), friction, memory, and the fixed unit approach direction
    (None: the outward normal of Gamma3)."""

    g: float | str | None
    c_nu: float | None
    friction: Friction | None
    memory: Memory | None = None
    direction: tuple | None = None

    @property
    def active(self) -> bool:
        """Any Gamma3 term present."""
        return any(x is not None for x in (self.g, self.c_nu, self.friction, self.memory))


@dataclass(frozen=True)
class Loads:
    """The ``loads`` section: body force f0; per group (a name or physical tag): tractions,
    normal pressures and prescribed displacements (components, None where free)."""

    f0: tuple | None
    traction: dict
    pressure: dict = field(default_factory=dict)
    displacement: dict = field(default_factory=dict)


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
    material: Material
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

    @property
    def dim(self) -> int:
        """The space dimension."""
        return self.mesh.dim

    def active_terms(self) -> list[str]:
        """The model's terms this case has, for the run log.

        Returns:
            Their names.
        """
        terms = [f"plane-{self.material.plane} elasticity" if self.dim == 2
                 else "isotropic elasticity (3D)"]
        if self.material.viscoplastic:
            vp = self.material.viscoplastic
            name = "Perzyna" if vp.law == "perzyna" else \
                f"power-law Perzyna (n = {vp.n:g}, s_ref = {vp.s_ref:g})"
            terms.append(f"{name} viscoplastic history H_n, kappa_n"
                         + (" (implicit, right end point)" if self.time.scheme == "implicit"
                            else " (explicit, as in the paper)"))
        if self.contact.c_nu is not None:
            terms.append("normal compliance")
        if self.contact.g is not None:
            terms.append("unilateral constraint u_nu <= g")
        if self.contact.memory is not None:
            terms.append(f"memory term xi_n ({self.contact.memory.kernel} kernel)")
        if self.contact.friction is not None:
            terms.append("nonmonotone friction (4.2)")
            if self.contact.friction.slip is not None:
                terms.append("slip-dependent friction theta(s_n)")
        return terms

    def omitted_terms(self) -> list[str]:
        """The model's terms this case leaves out (nothing is allocated or computed for them).

        Returns:
            Their names.
        """
        out = []
        if not self.material.viscoplastic:
            out.append("viscoplastic history (elastic body)")
        if self.contact.c_nu is None:
            out.append("normal compliance")
        if self.contact.g is None:
            out.append("unilateral constraint")
        if self.contact.memory is None:
            out.append("memory term")
        if self.contact.friction is None:
            out.append("friction")
        elif self.contact.friction.slip is None:
            out.append("slip dependence")
        return out


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
    init, vp = data.get("initial", {}), data["material"].get("viscoplastic")
    fr, mem = contact.get("friction"), contact.get("memory")
    slip = fr.get("slip") if fr else None
    name = case_name(data, source)
    method = METHOD_NAMES.get(data["solver"]["method"], data["solver"]["method"])
    g, d = contact.get("g"), contact.get("direction")
    return Case(
        name=name,
        source=source,
        mesh=_mesh_spec(mesh),
        material=Material(float(data["material"]["E"]), float(data["material"]["nu"]),
                          _viscoplastic(vp) if vp else None,
                          data["material"].get("plane")),
        contact=Contact(
            g if isinstance(g, str) else float(g) if g is not None else None,
            float(contact["normal_compliance"]["c_nu"]) if "normal_compliance" in contact
            else None,
            Friction(*(float(fr[k]) for k in ("b", "c1", "c2", "u1")),
                     Slip(float(slip["theta_inf"]), float(slip["s0"])) if slip else None)
            if fr else None,
            Memory(float(mem["b0"]), float(mem["beta"]), mem["kernel"], mem.get("alpha"),
                   mem.get("tau"), tuple(map(tuple, mem["table"])) if "table" in mem else None,
                   mem["sum"]) if mem else None,
            tuple(float(x) / math.hypot(*d) for x in d) if d is not None else None),
        loads=Loads(tuple(loads["f0"]) if "f0" in loads else None,
                    {k: tuple(v) for k, v in loads.get("traction", {}).items()},
                    dict(loads.get("pressure", {})),
                    {k: tuple(v) for k, v in loads.get("displacement", {}).items()}),
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


def _viscoplastic(vp: dict) -> Viscoplastic:
    """The Viscoplastic of the material.viscoplastic section (law absent: perzyna; the power
    law's n absent: 1)."""
    law = vp.get("law", "perzyna")
    power = law == "power"
    return Viscoplastic(float(vp["lambda1"]), float(vp["lambda2"]),
                        vp["kappa0"] if isinstance(vp["kappa0"], str) else float(vp["kappa0"]),
                        law, float(vp.get("n", 1.0)) if power else None,
                        float(vp["s_ref"]) if power else None)


def _mesh_spec(mesh: dict) -> MeshSpec:
    """The MeshSpec of the default-filled (and settled) mesh section."""
    if "file" in mesh:
        return MeshSpec(mesh["dim"], None, None, None, "file", None, None, None,
                        file=mesh["file"], size=float(mesh.get("size", 1.0)))
    return MeshSpec(mesh["dim"], float(mesh["L1"]), float(mesh["L2"]), float(mesh["L3"]),
                    mesh["kind"], int(mesh["n"]) if mesh["kind"] == "structured" else None,
                    float(mesh["h"]) if mesh["kind"] == "unstructured" else None,
                    mesh["diagonal"], engine=mesh["engine"])

