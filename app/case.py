"""Reading, overriding and validating case files (YAML, safe loader, JSON schema).

A validated case is split into plain dataclasses: physical data, numerical settings,
PETSc options and output settings are separate objects (STYLE.md).
"""
from __future__ import annotations

import copy
import re
import difflib
from dataclasses import dataclass, field
from pathlib import Path

import jsonschema
import yaml

from .schema import DEFAULT_PETSC, SCHEMA


class CaseLoader(yaml.SafeLoader):
    """yaml.SafeLoader that also reads 1e-4 / 5E+3 as floats (YAML 1.1 wants a dot)."""


CaseLoader.yaml_implicit_resolvers = {k: list(v) for k, v in
                                      yaml.SafeLoader.yaml_implicit_resolvers.items()}
CaseLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                    |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                    |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                    |[-+]?\.(?:inf|Inf|INF)
                    |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))


def safe_load(text: str):
    """Parse YAML with :class:`CaseLoader` (safe: plain data only, no Python objects)."""
    return yaml.load(text, Loader=CaseLoader)


class CaseError(ValueError):
    """An invalid case: the message names the file, the key path and what is allowed."""


# ----------------------------------------------------------------------------- loading
def _fill_defaults(schema: dict, data: dict) -> None:
    """Insert schema defaults for missing keys of the present (sub)sections."""
    for key, sub in schema.get("properties", {}).items():
        if key not in data and "default" in sub:
            data[key] = copy.deepcopy(sub["default"])
        if isinstance(data.get(key), dict) and sub.get("type") == "object":
            _fill_defaults(sub, data[key])


def _key_path(err: jsonschema.ValidationError) -> str:
    return ".".join(str(p) for p in err.absolute_path) or "(top level)"


def _explain(err: jsonschema.ValidationError) -> str:
    path = _key_path(err)
    if err.validator == "additionalProperties":
        allowed = sorted(err.schema.get("properties", {}))
        extra = sorted(set(err.instance) - set(allowed))
        msgs = []
        for key in extra:
            where = f"{path}.{key}" if path != "(top level)" else key
            close = difflib.get_close_matches(key, allowed, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            msgs.append(f"{where}: unknown key{hint} (allowed: {', '.join(allowed)})")
        return "; ".join(msgs)
    if err.validator == "required":
        return f"{path}: {err.message}"
    if err.validator == "enum":
        return f"{path}: {err.instance!r} is not allowed (allowed: " \
               f"{', '.join(map(str, err.validator_value))})"
    return f"{path}: {err.message}"


def _set_path(data: dict, dotted: str, value) -> None:
    keys = dotted.split(".")
    node = data
    for key in keys[:-1]:
        if not isinstance(node.get(key, {}), dict):
            raise CaseError(f"--set {dotted}: '{key}' is not a section")
        node = node.setdefault(key, {})
    node[keys[-1]] = value


def parse_override(text: str) -> tuple[str, object]:
    """'section.key=value' -> (path, value), the value read as YAML (numbers, lists, ...)."""
    if "=" not in text:
        raise CaseError(f"--set {text!r}: expected section.key=value")
    key, raw = text.split("=", 1)
    if not key or any(not part for part in key.split(".")):
        raise CaseError(f"--set {text!r}: expected section.key=value")
    try:
        value = safe_load(raw) if raw.strip() else None
    except yaml.YAMLError as exc:
        raise CaseError(f"--set {key}: cannot read value {raw!r}: {exc}") from None
    return key, value


def load_raw(path: str | Path, overrides: list[str] = ()) -> dict:
    """Read the YAML case with a safe loader and apply ``--set`` overrides."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise CaseError(f"{path}: cannot read case file: {exc.strerror}") from None
    try:
        data = safe_load(text)
    except yaml.YAMLError as exc:
        raise CaseError(f"{path}: not valid YAML: {exc}") from None
    if not isinstance(data, dict):
        raise CaseError(f"{path}: a case file must be a YAML mapping of sections, "
                        f"got {type(data).__name__}")
    for item in overrides:
        key, value = parse_override(item)
        _set_path(data, key, value)
    return data


# ----------------------------------------------------------------------------- the case
@dataclass(frozen=True)
class MeshSpec:
    L1: float
    L2: float
    kind: str
    n: int | None
    h: float | None
    diagonal: str


@dataclass(frozen=True)
class Viscoplastic:
    lambda1: float
    lambda2: float
    kappa0: float


@dataclass(frozen=True)
class Material:
    E: float
    nu: float
    viscoplastic: Viscoplastic | None


@dataclass(frozen=True)
class Friction:
    b: float
    c1: float
    c2: float
    u1: float


@dataclass(frozen=True)
class Contact:
    g: float | None
    c_nu: float | None
    friction: Friction | None

    @property
    def active(self) -> bool:
        return self.g is not None or self.c_nu is not None or self.friction is not None


@dataclass(frozen=True)
class Loads:
    f0: tuple
    traction: dict


@dataclass(frozen=True)
class TimeGrid:
    T: float
    N: int

    @property
    def times(self) -> list[float]:
        """t_0 = 0 < t_1 < ... < t_N = T (uniform)."""
        return [self.T * n / self.N for n in range(self.N + 1)]


@dataclass(frozen=True)
class Numerics:
    method: str
    delta: float
    quadrature: str
    gauss_degree: int


@dataclass(frozen=True)
class OutputSpec:
    every: int


@dataclass(frozen=True)
class Case:
    name: str
    source: str
    mesh: MeshSpec
    material: Material
    contact: Contact
    loads: Loads
    time: TimeGrid
    numerics: Numerics
    petsc: dict
    output: OutputSpec
    raw: dict = field(repr=False)

    def active_terms(self) -> list[str]:
        terms = ["plane-stress elasticity"]
        if self.material.viscoplastic:
            terms.append("Perzyna viscoplastic history H_n, kappa_n")
        if self.contact.c_nu is not None:
            terms.append("normal compliance")
        if self.contact.g is not None:
            terms.append("unilateral constraint u_nu <= g")
        if self.contact.friction is not None:
            terms.append("nonmonotone friction (4.2)")
        return terms


def validate(data: dict, source: str = "<case>") -> Case:
    """Validate a raw case dictionary against the schema; return a :class:`Case`."""
    data = copy.deepcopy(data)
    validator = jsonschema.Draft7Validator(SCHEMA)
    errors = sorted(validator.iter_errors(data), key=lambda e: list(e.absolute_path))
    if errors:
        raise CaseError(f"{source}: invalid case:\n  " + "\n  ".join(_explain(e) for e in errors))
    _fill_defaults(SCHEMA, data)
    mesh = data["mesh"]
    if mesh["kind"] == "unstructured" and "h" not in mesh:
        raise CaseError(f"{source}: mesh.h: required when mesh.kind is 'unstructured'")
    contact = data.get("contact", {})
    traction = data["loads"].get("traction", {})
    if contact and "bottom" in traction:
        raise CaseError(f"{source}: loads.traction.bottom: the bottom side is Gamma3 (contact); "
                        "a traction there is only allowed in a case without a contact section")
    if contact and not any(k in contact for k in ("g", "normal_compliance", "friction")):
        raise CaseError(f"{source}: contact: give at least one of g, normal_compliance, friction")
    vp = data["material"].get("viscoplastic")
    fr = contact.get("friction")
    if fr and fr["b"] - fr["c1"] * fr["u1"] < 0:
        raise CaseError(f"{source}: contact.friction: b - c1 u1 must be >= 0 (the friction "
                        f"force of law (4.2) may not change sign), got "
                        f"{fr['b'] - fr['c1'] * fr['u1']:g}")
    petsc = {**DEFAULT_PETSC, **data.get("petsc", {})}
    return Case(
        name=data.get("name") or Path(source).stem,
        source=source,
        mesh=MeshSpec(float(mesh["L1"]), float(mesh["L2"]), mesh["kind"],
                      int(mesh["n"]) if mesh["kind"] == "structured" else None,
                      float(mesh["h"]) if mesh["kind"] == "unstructured" else None,
                      mesh["diagonal"]),
        material=Material(float(data["material"]["E"]), float(data["material"]["nu"]),
                          Viscoplastic(float(vp["lambda1"]), float(vp["lambda2"]),
                                       float(vp["kappa0"])) if vp else None),
        contact=Contact(float(contact["g"]) if "g" in contact else None,
                        float(contact["normal_compliance"]["c_nu"])
                        if "normal_compliance" in contact else None,
                        Friction(*(float(fr[k]) for k in ("b", "c1", "c2", "u1"))) if fr else None),
        loads=Loads(tuple(float(x) for x in data["loads"]["f0"]),
                    {k: tuple(float(x) for x in v) for k, v in traction.items()}),
        time=TimeGrid(float(data["time"]["T"]), int(data["time"]["N"])),
        numerics=Numerics(**data["solver"]),
        petsc=petsc,
        output=OutputSpec(**data["output"]),
        raw=data,
    )


def load_case(path: str | Path, overrides: list[str] = ()) -> Case:
    """Read, override and validate a case file.  Raises :class:`CaseError`."""
    return validate(load_raw(path, overrides), str(path))
