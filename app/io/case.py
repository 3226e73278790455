"""Reading, overriding and validating case files (YAML, safe loader, JSON schema).

A validated case is split into plain dataclasses: physical data, numerical settings,
PETSc options and output settings are separate objects.
"""
from __future__ import annotations

import copy
import dataclasses
import difflib
import math
import os
import re
import stat
from dataclasses import dataclass, field
from pathlib import Path

import jsonschema
import yaml

from vpcontact.io.errors import CaseError
from vpcontact.io.petscopts import PetscOptions, check_petsc_options
from vpcontact.io.schema import DEFAULT_PETSC, SCHEMA
from vpcontact.meshes.rectangle import SIDES

MAX_INT_DIGITS = 30


class CaseLoader(yaml.SafeLoader):
    """yaml.SafeLoader that also reads 1e-4 / 5E+3 as floats (YAML 1.1 wants a dot) and
    rejects duplicate keys (PyYAML would silently keep the last one)."""

    def construct_mapping(self, node, deep=False):
        """A mapping, refused if a key repeats.

        Args:
            node: the YAML mapping node.
            deep: construct the values recursively.

        Returns:
            The dict.

        Raises:
            yaml.constructor.ConstructorError: for a duplicate key (naming both lines).
        """
        seen = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            if isinstance(key, (str, int, float, bool)) and key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r} (first on line {seen[key]})",
                    key_node.start_mark)
            if isinstance(key, (str, int, float, bool)):
                seen[key] = key_node.start_mark.line + 1
        return super().construct_mapping(node, deep)

    def construct_yaml_int(self, node):
        """An integer of at most MAX_INT_DIGITS digits (Python refuses to convert very long
        ones, and none is a sensible value here).

        Args:
            node: the YAML scalar node.

        Returns:
            The int.

        Raises:
            yaml.constructor.ConstructorError: for more than MAX_INT_DIGITS digits.
        """
        if len(re.sub(r"[^0-9a-fA-F]", "", node.value)) > MAX_INT_DIGITS:
            raise yaml.constructor.ConstructorError(
                None, None, f"integer with more than {MAX_INT_DIGITS} digits", node.start_mark)
        return super().construct_yaml_int(node)


CaseLoader.add_constructor("tag:yaml.org,2002:int", CaseLoader.construct_yaml_int)
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
    """Parse YAML with :class:`CaseLoader` (safe: plain data only, no Python objects).

    Args:
        text: the YAML text.

    Returns:
        The parsed data.

    Raises:
        yaml.YAMLError: for text that is not valid YAML or has a duplicate key.
    """
    return yaml.load(text, Loader=CaseLoader)


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
            shown = key if re.fullmatch(r"\w+", str(key)) else repr(key)
            where = f"{path}.{shown}" if path != "(top level)" else shown
            close = difflib.get_close_matches(str(key), allowed, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            msgs.append(f"{where}: unknown key{hint} (allowed: {', '.join(allowed)})")
        return "; ".join(msgs)
    if err.validator == "required":
        return f"{path}: {err.message}"
    if err.validator == "pattern" and path == "name":
        return f"{path}: {err.instance!r} cannot name an output directory (allowed: " \
               "letters, digits, '_', '.' and '-', starting with a letter or digit)"
    if err.validator == "enum":
        return f"{path}: {err.instance!r} is not allowed (allowed: " \
               f"{', '.join(map(str, err.validator_value))})"
    if err.validator == "oneOf":      # the reason of the one alternative of the right type
        typed = [e for e in err.context if e.validator != "type" and not e.relative_path]
        if len(typed) == 1:
            return f"{path}: {typed[0].message}"
    return f"{path}: {err.message}"


def _set_path(data: dict, dotted: str, value) -> None:
    keys = dotted.split(".")
    node = data
    for key in keys[:-1]:
        if not isinstance(node.get(key, {}), dict):
            raise CaseError(f"--set {dotted}: '{key}' is not a section")
        node = node.setdefault(key, {})
    last = keys[-1]
    if keys[:-1] in (["loads", kind] for kind in GROUP_MAPS) and \
            re.fullmatch(rf"[0-9]{{1,{MAX_INT_DIGITS}}}", last):
        last = int(last)                  # a physical tag, as YAML reads the key 3:
    node[last] = value


def parse_override(text: str) -> tuple[str, object]:
    """Read one ``--set`` override.

    Args:
        text: 'section.key=value'.

    Returns:
        (dotted key path, value), the value read as YAML (numbers, lists, ...).

    Raises:
        CaseError: if the text is not of that form or the value is not YAML.
    """
    if "=" not in text:
        raise CaseError(f"--set {text!r}: expected section.key=value")
    key, raw = text.split("=", 1)
    if not key or any(not part for part in key.split(".")):
        raise CaseError(f"--set {text!r}: expected section.key=value")
    try:
        value = safe_load(raw) if raw.strip() else None
    except yaml.YAMLError as exc:
        raise CaseError(f"--set {key}: cannot read value {raw!r}: "
                        f"{_yaml_error(exc, raw)}") from None
    except RecursionError:
        raise CaseError(f"--set {key}: cannot read value: nested too deeply") from None
    return key, value


class RawCase(dict):
    """The parsed case mapping; ``lines`` maps dotted key paths to their 1-based YAML line."""

    lines: dict = {}


def key_lines(text: str) -> dict[str, int]:
    """Where the keys of a YAML text are.

    Args:
        text: the YAML text.

    Returns:
        Dotted key path -> 1-based line of the key (as far as the parser can tell).
    """
    out: dict[str, int] = {}
    seen: set[int] = set()

    def walk(node, path):
        if id(node) in seen:                  # an alias: its lines are those of the anchor
            return
        seen.add(id(node))
        if isinstance(node, yaml.MappingNode):
            for k, v in node.value:
                if isinstance(k, yaml.ScalarNode):
                    p = f"{path}.{k.value}" if path else str(k.value)
                    out.setdefault(p, k.start_mark.line + 1)
                    walk(v, p)
        elif isinstance(node, yaml.SequenceNode):
            for i, v in enumerate(node.value):
                p = f"{path}[{i}]"
                out.setdefault(p, v.start_mark.line + 1)
                walk(v, p)
    try:
        walk(yaml.compose(text, Loader=CaseLoader), "")
    except yaml.YAMLError:
        pass
    return out


_PATH = re.compile(r"[A-Za-z_]\w*(?:\.\w+|\[\d+\])*")


def with_lines(message: str, lines: dict) -> str:
    """Add '(line N)' after the first key path of each message line that the YAML text has.

    Args:
        message: a CaseError message.
        lines: key path -> line (``key_lines``).

    Returns:
        The message with the lines.
    """
    if not lines:
        return message

    def parent(path: str) -> str:
        return re.sub(r"(\.\w+|\[\d+\])$", "", path)

    def add(m):
        path = m.group(0)
        while path and path not in lines:       # the deepest key present in the file
            shorter = parent(path)
            path = shorter if shorter != path else ""
        return f"{m.group(0)} (line {lines[path]})" if path else m.group(0)
    # a key path is followed by ': ' where our messages name it
    return re.sub(r"(?<![\w.\[\]])" + _PATH.pattern + r"(?=: )", add, message)


def _yaml_error(exc: yaml.YAMLError, text: str = "") -> str:
    """PyYAML's error on one line: the problem and where (line and column in ``text``)."""
    if isinstance(exc, yaml.reader.ReaderError):      # a character YAML does not allow
        line = text.count("\n", 0, exc.position) + 1
        column = exc.position - (text.rfind("\n", 0, exc.position) + 1) + 1
        return f"unacceptable character #x{exc.character:04x} (line {line}, column {column})"
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
    context = getattr(exc, "context", None)
    return " ".join(f"{problem}{where}{f', {context}' if context else ''}".split())


MAX_VERTICES = 1e8           # a mesh larger than this is refused before any computation
MAX_CASE_SIZE = 2_000_000   # numbers, strings and containers after alias expansion
MAX_FILE_BYTES = 50_000_000
# magnitude of a nonzero number of the case (outside PETSc options): products and squares
# of a few data values stay within double precision
MIN_MAGNITUDE, MAX_MAGNITUDE = 1e-100, 1e100
MAX_STEPS = 1_000_000       # time steps (as time.N allows)
MIN_LENGTH, MAX_LENGTH = 1e-30, 1e30   # a side length outside this range is degenerate [m]
MAX_ASPECT = 1e6            # largest ratio of two side lengths
REFERENCE_FORCE = 8.0       # the paper's nodal force scale (N/m, 2D), where snes_atol holds
# the maps of loads keyed by boundary group: a name, or (YAML's integer keys) a physical tag
GROUP_MAPS = ("traction", "pressure", "displacement")
MESH_SUFFIXES = (".msh", ".geo")
# the built-in mesh's keys, not used with mesh.file
BUILTIN_MESH_KEYS = ("L1", "L2", "L3", "kind", "n", "h", "diagonal", "engine")
DEFAULT_BOUNDARIES = {"clamped": ["left"], "contact": ["bottom"]}     # built-in meshes


def _is_tag(key) -> bool:
    """A physical group's tag: an integer >= 0 (not a bool)."""
    return isinstance(key, int) and not isinstance(key, bool) and key >= 0


def _check_data(data, path: str, source, budget: list) -> None:
    """Reject non-finite numbers and oversized data (YAML alias bombs), naming the key."""
    budget[0] -= 1
    if budget[0] < 0:
        raise CaseError(f"{source}: {path or '(top level)'}: the case is too large (more than "
                        f"{MAX_CASE_SIZE} values after expanding YAML aliases)")
    if isinstance(data, float) and not math.isfinite(data):
        raise CaseError(f"{source}: {path or '(top level)'}: {data} is not a finite number")
    if isinstance(data, (int, float)) and not isinstance(data, bool) and data != 0 \
            and not path.startswith("petsc.") \
            and not MIN_MAGNITUDE <= abs(data) <= MAX_MAGNITUDE:
        shown = f"{data:g}" if isinstance(data, float) or data.bit_length() < 300 else \
            f"an integer of {data.bit_length()} bits"
        raise CaseError(f"{source}: {path}: {shown} is out of range (allowed: 0 or "
                        f"magnitudes from {MIN_MAGNITUDE:g} to {MAX_MAGNITUDE:g})")
    if isinstance(data, dict):
        groups = path in tuple(f"loads.{m}" for m in GROUP_MAPS)
        for key, value in data.items():
            if groups and not isinstance(key, str) and not _is_tag(key):
                raise CaseError(f"{source}: {path}: the key {key!r} is not a group (a name, or "
                                "a physical tag: an integer >= 0)")
            if not isinstance(key, str) and not groups:
                raise CaseError(f"{source}: {path or '(top level)'}: the key {key!r} is not a "
                                "name (keys are strings such as 'mesh' or 'E')")
            _check_data(value, f"{path}.{key}" if path else str(key), source, budget)
    elif isinstance(data, list):
        for i, value in enumerate(data):
            _check_data(value, f"{path}[{i}]", source, budget)


def read_text(path: Path) -> str:
    """The case file's text.

    A device, FIFO or directory is refused before it is opened: reading one may never end.

    Args:
        path: the case file.

    Returns:
        The text of a regular file of at most MAX_FILE_BYTES bytes of UTF-8.

    Raises:
        CaseError: for anything else, or a file that cannot be read.
    """
    try:
        if not stat.S_ISREG(path.stat().st_mode):
            raise CaseError(f"{path}: not a regular file (a case file must be a YAML text "
                            "file, not a directory, device or pipe)")
        with open(path, "rb") as fh:
            raw = fh.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise CaseError(f"{path}: cannot read case file: {exc.strerror}") from None
    if len(raw) > MAX_FILE_BYTES:
        raise CaseError(f"{path}: the case file is larger than {MAX_FILE_BYTES} bytes")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CaseError(f"{path}: not a YAML text file (not UTF-8 at byte {exc.start})") \
            from None


def load_raw(path: str | Path, overrides: list[str] = ()) -> dict:
    """Read the YAML case with a safe loader and apply ``--set`` overrides.

    Args:
        path: the case file.
        overrides: 'section.key=value' strings.

    Returns:
        The RawCase (with the lines of its keys), not yet validated.

    Raises:
        CaseError: if the file cannot be read, is not a YAML mapping, or holds non-finite,
            out-of-range or too much data.
    """
    path = Path(path)
    text = read_text(path)
    try:
        data = safe_load(text)
    except yaml.YAMLError as exc:
        raise CaseError(f"{path}: not valid YAML: {_yaml_error(exc, text)}") from None
    except RecursionError:
        raise CaseError(f"{path}: not valid YAML: nested too deeply") from None
    if not isinstance(data, dict):
        raise CaseError(f"{path}: a case file must be a YAML mapping of sections, "
                        f"got {type(data).__name__}")
    data = RawCase(data)
    data.lines = key_lines(text)
    for item in overrides:
        key, value = parse_override(item)
        _set_path(data, key, value)
        data.lines.pop(key, None)              # the value comes from --set, not the file
    try:
        _check_data(data, "", path, [MAX_CASE_SIZE])
    except RecursionError:
        raise CaseError(f"{path}: the case is nested too deeply") from None
    except CaseError as exc:
        raise CaseError(with_lines(str(exc), data.lines)) from None
    return data


# ----------------------------------------------------------------------------- the case
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
    """``material.viscoplastic``: the Perzyna law's lambda1, lambda2 and kappa0."""

    lambda1: float
    lambda2: float
    kappa0: float | str


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
    """The ``solver`` section: step solver, delta, Gamma3 quadrature, SNES VI's linear
    solver."""

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
            terms.append("Perzyna viscoplastic history H_n, kappa_n"
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
    from vpcontact.io import expressions

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


def _time_grid(t: dict, source: str) -> TimeGrid:
    if "times" in t:
        extra = [k for k in ("N", "k", "grading") if k in t]
        if extra:
            raise CaseError(f"{source}: time.{extra[0]}: not allowed together with time.times")
        ts = [float(x) for x in t["times"]]
        if ts[0] != 0.0 or any(b <= a for a, b in zip(ts, ts[1:])):
            raise CaseError(f"{source}: time.times: must start at 0 and increase strictly")
        if "T" in t and abs(t["T"] - ts[-1]) > 1e-12 * ts[-1]:
            raise CaseError(f"{source}: time.T: {t['T']} differs from the last of time.times "
                            f"({ts[-1]})")
        k = [b - a for a, b in zip(ts, ts[1:])]
        return TimeGrid(tuple(ts), max(k) - min(k) <= 1e-12 * ts[-1])
    if "T" not in t:
        raise CaseError(f"{source}: time.T: required (or give time.times)")
    T = float(t["T"])
    if ("N" in t) == ("k" in t):
        raise CaseError(f"{source}: time: give exactly one of time.N and time.k")
    if "k" in t:
        if "grading" in t:
            raise CaseError(f"{source}: time.grading: needs time.N, not time.k")
        steps = T / t["k"]
        if not steps <= MAX_STEPS + 0.5:
            raise CaseError(f"{source}: time.k: {t['k']} gives {steps:.3g} steps of T = {T:g} "
                            f"(limit {MAX_STEPS})")
        N = round(steps)
        if N < 1 or abs(N * t["k"] - T) > 1e-9 * T:
            raise CaseError(f"{source}: time.k: {t['k']} does not divide T = {T} into whole steps")
        return TimeGrid(tuple(T * n / N for n in range(N + 1)), True)
    N = int(t["N"])
    r = float(t.get("grading", 1.0))
    if r == 1.0:
        return TimeGrid(tuple(T * n / N for n in range(N + 1)), True)
    try:
        k1 = T * (1.0 - r) / (1.0 - r**N)
        ts = [0.0] + [k1 * (1.0 - r**n) / (1.0 - r) for n in range(1, N + 1)]
    except (OverflowError, ZeroDivisionError):
        ts = [0.0, math.nan, T]
    ts[-1] = T
    if not all(math.isfinite(x) for x in ts) or any(b <= a for a, b in zip(ts, ts[1:])):
        raise CaseError(f"{source}: time.grading: {r} with N = {N} gives steps that underflow "
                        "or overflow")
    return TimeGrid(tuple(ts), False)


def _check_adaptive(a: dict | None, times: tuple, source: str) -> None:
    """k_min <= first step, k_min <= k_max (the stepper could not take a single step);
    T / k_max within MAX_STEPS (the stepper takes at least that many steps)."""
    if a is None:
        return
    k0 = times[1] - times[0]
    k_min, k_max = a.get("k_min"), a.get("k_max", times[-1])
    if not times[-1] / k_max <= MAX_STEPS + 0.5:
        raise CaseError(f"{source}: time.adaptive.k_max: {k_max:g} gives at least "
                        f"{times[-1] / k_max:.3g} steps of T = {times[-1]:g} (limit {MAX_STEPS})")
    if k_min is not None and k_min > k_max:
        raise CaseError(f"{source}: time.adaptive.k_min: {k_min:g} is larger than "
                        f"time.adaptive.k_max = {k_max:g} (allowed: k_min <= k_max)")
    if k_min is not None and k_min > k0:
        raise CaseError(f"{source}: time.adaptive.k_min: {k_min:g} is larger than the first "
                        f"step of the time grid, {k0:g}, where adaptive steps start "
                        "(allowed: k_min <= first step)")


def validate(data: dict, source: str = "<case>") -> Case:
    """Validate a raw case dictionary against the schema.

    Args:
        data: the case mapping (a RawCase from load_raw, or a dict built in code).
        source: the file name for messages.

    Returns:
        The Case.

    Raises:
        CaseError: one line naming the file, the key path and (for a file read by
            load_raw) its line.
    """
    try:
        return _validate(data, source)
    except CaseError as exc:          # one line, with the YAML lines of the keys named
        text = str(exc).replace("\r", "\\r").replace("\n", "\\n")
        raise CaseError(with_lines(text, getattr(data, "lines", {}))) from None
    except RecursionError:
        raise CaseError(f"{source}: the case is nested too deeply") from None


def _validate(data: dict, source: str) -> Case:
    _check_data(data, "", source, [MAX_CASE_SIZE])      # dicts built in code, not by load_raw
    data = copy.deepcopy(dict(data))
    validator = jsonschema.Draft7Validator(SCHEMA)
    errors = sorted(validator.iter_errors(_schema_view(data, source)),
                    key=lambda e: list(e.absolute_path))
    if errors:       # one line: the first error, then the others
        msgs = [_explain(e) for e in errors]
        more = f" (also: {'; '.join(msgs[1:])})" if len(msgs) > 1 else ""
        raise CaseError(f"{source}: {msgs[0]}{more}")
    dim_given = "dim" in data["mesh"]
    mesh_file = _check_given(data, source)
    _fill_defaults(SCHEMA, data)
    _settle_defaults(data, mesh_file)
    if mesh_file is None:
        _check_mesh(data["mesh"], source)
    try:
        _check_structure(data, source)
    except CaseError:       # vectors of the other dimension: is mesh.dim the cause?
        if mesh_file is not None and dim_given:
            _check_file_dimension(data["mesh"]["dim"], mesh_file, source)
        raise
    time_grid = dataclasses.replace(_time_grid(data["time"], source),
                                    scheme=data["time"]["scheme"],
                                    adaptive=data["time"].get("adaptive"))
    _check_adaptive(time_grid.adaptive, time_grid.times, source)
    stress = _check_values(data, time_grid, source)
    defaults = {**DEFAULT_PETSC, **scaled_petsc_defaults(data, stress)}
    limits = petsc_limits(data, stress)
    check_petsc_options(data.get("petsc", {}), source, base=defaults, limits=limits)
    petsc = PetscOptions({**defaults, **data.get("petsc", {})}, limits)
    case = dataclasses.replace(_build(data, source, time_grid, petsc), data_stress=stress,
                               petsc_defaults=defaults)
    ok, why = fast_eligible(case)
    if case.numerics.method == "fast" and not ok:
        raise CaseError(f"{source}: solver.method: 'fast' is not possible here: {why} "
                        "(allowed: snes_vi, auto)")
    return case


def _schema_view(data: dict, source: str) -> dict:
    """The case with the keys of the group maps of loads as strings, for jsonschema (which
    names object keys by strings; YAML reads a physical tag as an integer key)."""
    loads = data.get("loads")
    if not isinstance(loads, dict):
        return data
    view = {**data, "loads": dict(loads)}
    for kind in GROUP_MAPS:
        groups = loads.get(kind)
        if not isinstance(groups, dict) or all(isinstance(k, str) for k in groups):
            continue
        both = [k for k in groups if not isinstance(k, str) and str(k) in groups]
        if both:
            raise CaseError(f"{source}: loads.{kind}.{both[0]}: given twice, as the tag "
                            f"{both[0]} and as the name '{both[0]}' (give one)")
        view["loads"][kind] = {str(k): v for k, v in groups.items()}
    return view


def _check_given(data: dict, source: str) -> Path | None:
    """The keys the user gave (before defaults are filled) that do not apply: the built-in
    mesh's keys with mesh.file, mesh.size without a .geo, material.plane in 3D; mesh.dim of
    a mesh.file: taken from the file when not given, else refused if the file contradicts it
    (a .msh 4 file is read at once; a .geo only when the case's vectors disagree with
    mesh.dim: meshing it tells the rest).

    Returns:
        The mesh file's absolute path, or None for the built-in mesh.
    """
    mesh = data["mesh"]
    path = None
    if "file" not in mesh and "size" in mesh:
        raise CaseError(f"{source}: mesh.size: only with a .geo mesh.file (the built-in "
                        "mesh's cells are set by mesh.n or mesh.h)")
    if "file" in mesh:
        given = [k for k in BUILTIN_MESH_KEYS if k in mesh]
        if given:
            raise CaseError(f"{source}: mesh.{given[0]}: not used with mesh.file (the "
                            f"built-in mesh's keys {', '.join(BUILTIN_MESH_KEYS)} are not "
                            "used with a gmsh file)")
        path = _mesh_path(mesh["file"], source)
        if "size" in mesh and path.suffix.lower() != ".geo":
            raise CaseError(f"{source}: mesh.size: only with a .geo mesh.file (a .msh is "
                            "meshed already)")
        if "dim" in mesh:
            _check_file_dimension(mesh["dim"], path, source, cheap=True)
        else:
            mesh["dim"] = _file_dimension(path, source)
    if mesh.get("dim", 2) == 3 and "plane" in data["material"]:
        raise CaseError(f"{source}: material.plane: not used in 3D (plane stress and plane "
                        "strain are the 2D models; a 3D body is a solid)")
    return path


def _file_dimension(path: Path, source: str, cheap: bool = False) -> int | None:
    """The dimension of the mesh file (meshes/fileinfo.py; None if ``cheap`` and gmsh would
    be needed)."""
    from vpcontact.meshes.fileinfo import FileInfoError, file_dimension
    try:
        return file_dimension(path, cheap)
    except FileInfoError as exc:
        raise CaseError(f"{source}: mesh.file: {exc}") from None


def _check_file_dimension(dim: int, path: Path, source: str, cheap: bool = False) -> None:
    """Refuse a mesh.dim that contradicts the mesh file (``cheap``: only if the file tells
    its dimension without gmsh); a file whose dimension cannot be told is left to the
    mesh's loading, which says what is wrong with it."""
    from vpcontact.meshes.fileinfo import FileInfoError, file_dimension
    try:
        found = file_dimension(path, cheap)
    except FileInfoError:
        return
    if found is not None and found != dim:
        what = "tetrahedra, a solid" if found == 3 else "triangles in a plane"
        raise CaseError(f"{source}: mesh.dim: {dim} contradicts mesh.file {path.name}, which "
                        f"is {found}D ({what}); give {found} or leave the key out (the file's "
                        "dimension is taken)")


def _mesh_path(file: str, source: str) -> Path:
    """mesh.file relative to the case file's directory: a .msh or .geo regular file."""
    if Path(file).suffix.lower() not in MESH_SUFFIXES:
        raise CaseError(f"{source}: mesh.file: {file!r} is not a gmsh mesh or geometry file "
                        f"(allowed: a file ending in {' or '.join(MESH_SUFFIXES)})")
    path = Path(os.path.abspath(Path(source).parent / file))   # an absolute file stays
    try:
        found = path.is_file() and os.access(path, os.R_OK)
        exists = found or path.exists()
    except (OSError, ValueError):        # e.g. a NUL character or a name too long
        found = exists = False
    if not found:
        why = "not a readable regular file" if exists else "no such file"
        raise CaseError(f"{source}: mesh.file: {file!r}: {why} (looked for {path}; a relative "
                        "path is relative to the case file's directory)")
    return path


def _settle_defaults(data: dict, mesh_file: Path | None) -> None:
    """After _fill_defaults: drop the defaults that do not apply (the built-in mesh's keys
    and mesh.engine with mesh.file, mesh.size without a .geo, material.plane in 3D), make
    mesh.file absolute, fill boundaries (built-in mesh: clamped [left], contact [bottom];
    mesh.file: []) and write physical tags as integers.  The result validates to the same
    case again (the studies validate case.raw with changed keys)."""
    mesh = data["mesh"]
    if mesh_file is not None:
        for key in BUILTIN_MESH_KEYS:
            mesh.pop(key, None)
        mesh["file"] = str(mesh_file)
    if mesh_file is None or mesh_file.suffix.lower() != ".geo":
        mesh.pop("size", None)
    if mesh["dim"] == 3:
        data["material"].pop("plane", None)
    bounds = data.setdefault("boundaries", {})
    for role, default in DEFAULT_BOUNDARIES.items():
        refs = bounds.get(role, default if mesh_file is None else [])
        bounds[role] = [r if isinstance(r, str) else int(r) for r in refs]


def _check_mesh(mesh: dict, source: str) -> None:
    """Mesh size within MAX_VERTICES; lengths neither degenerate nor too flat."""
    dim = mesh["dim"]
    if mesh["kind"] == "unstructured" and "h" not in mesh:
        raise CaseError(f"{source}: mesh.h: required when mesh.kind is 'unstructured'")
    lengths = [mesh["L1"], mesh["L2"], mesh["L3"]][:dim]
    for i, L in enumerate(lengths):
        if not MIN_LENGTH <= L <= MAX_LENGTH:
            raise CaseError(f"{source}: mesh.L{i + 1}: {L:g} m is a degenerate length "
                            f"(allowed: {MIN_LENGTH:g} to {MAX_LENGTH:g})")
    if max(lengths) > MAX_ASPECT * min(lengths):
        i = lengths.index(min(lengths))
        raise CaseError(f"{source}: mesh.L{i + 1}: {lengths[i]:g} m is too thin next to "
                        f"{max(lengths):g} m (allowed: side ratios up to {MAX_ASPECT:g})")
    if mesh["kind"] == "structured":
        vertices, key = float(mesh["n"] + 1) ** dim, "mesh.n"
    else:
        vertices, key = math.prod(L / mesh["h"] + 1 for L in lengths), "mesh.h"
    if vertices > MAX_VERTICES:
        raise CaseError(f"{source}: {key}: the mesh would have about {vertices:.3g} vertices "
                        f"(limit {MAX_VERTICES:.0e}); use a coarser mesh")


def _check_structure(data: dict, source: str) -> None:
    """Cross-key rules: boundary groups, vector lengths, expressions parse, contact and
    memory."""
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
    from vpcontact.io import expressions

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


def _check_values(data: dict, time_grid: TimeGrid, source: str,
                  length: float | None = None, samples=None) -> float:
    """The data values at sample points of the body and times (app/io/datacheck.py): finite,
    initial values in the model's set.  Returns the stress scale of the data (loads,
    sigma0 and the stress E |u| / L of the initial and prescribed displacements).

    The body of a mesh.file is unknown here: only what does not depend on the position is
    sampled (the mesh's nodes are checked when it is loaded), and L is 1.  The geometric
    checks of u0 (zero on Gamma1, u_nu <= g on Gamma3) need the built-in mesh with the
    default boundaries; g >= 0 is sampled on the built-in mesh's contact sides.  ``length``:
    the body's size L (default: body_length(data)); ``samples``: the sample points of the
    loaded mesh (datacheck.PointSamples; default: as above)."""
    from vpcontact.io import datacheck

    mesh, bounds = data["mesh"], data["boundaries"]
    adaptive = time_grid.adaptive is not None
    if samples is None and "file" in mesh:
        samples = datacheck.Samples.unknown(mesh["dim"], time_grid.times, adaptive)
    elif samples is None:
        lengths = [mesh["L1"], mesh["L2"], mesh["L3"]][:mesh["dim"]]
        cells = [mesh["n"] if mesh["kind"] == "structured" else math.ceil(L / mesh["h"])
                 for L in lengths]
        samples = datacheck.Samples(lengths, cells, time_grid.times, adaptive)
    geometric = "file" not in mesh and bounds == DEFAULT_BOUNDARIES
    vp = data["material"].get("viscoplastic")
    contact = data.get("contact", {})
    try:
        loads = datacheck.check_loads(data["loads"], samples)
        moved = datacheck.check_displacement(data["loads"].get("displacement", {}), samples)
        if contact:
            datacheck.check_gap(contact.get("g"), bounds["contact"], samples)
        u0, sigma0 = datacheck.check_initial(data.get("initial", {}),
                                             vp["kappa0"] if vp else None, contact.get("g"),
                                             samples, contact.get("direction"), geometric)
    except datacheck.DataError as exc:
        raise CaseError(f"{source}: {exc}") from None
    length = body_length(data) if length is None else length
    return max(loads, sigma0, data["material"]["E"] * max(u0, moved) / length)


def check_values_on_mesh(case: Case, samples, length: float) -> float:
    """The checks of validation (app/io/datacheck.py) on the points of the loaded mesh.

    Args:
        case: the validated case.
        samples: the mesh's sample points and the times (datacheck.PointSamples).
        length: the body's size L [m].

    Returns:
        The stress scale of the data on these points (as validation's).

    Raises:
        CaseError: for a value that is not finite, out of range or outside the model's set,
            naming the key and the point (x, t).
    """
    return _check_values(case.raw, case.time, case.source, length, samples)


def body_length(data: dict) -> float:
    """The body's length scale known before the mesh is built.

    Args:
        data: the default-filled case mapping.

    Returns:
        The longest side of the built-in mesh; 1 for a mesh.file (see rescale_for_length).
    """
    mesh = data["mesh"]
    if "file" in mesh:
        return 1.0
    return max([mesh["L1"], mesh["L2"], mesh["L3"]][:mesh["dim"]])


def _gap_number(data: dict) -> float | None:
    """contact.g if it is a number (an expression's scale is unknown: the length serves)."""
    g = data.get("contact", {}).get("g")
    return None if isinstance(g, str) else g


def scaled_petsc_defaults(data: dict, stress: float, length: float | None = None) -> dict:
    """DEFAULT_PETSC's absolute tolerances scaled to the case, so that a body of any size
    or stiffness converges alike (their values hold for the paper's scales: the unit square
    under a stress of 8 N/m^2):
    - snes_atol, on the residual, a vector of nodal forces ~ stress L^(d-1); without loads
      or initial data (u = 0 exactly) the default value serves;
    - snes_vi_zero_tolerance, how close to its bound (in m) SNES VI takes a dof as active:
      relative to the body's size L, and at most 1e-4 of the gap g (a tenth of the limit
      in petsc_limits, so that a small gap keeps a valid default); a gap given by an
      expression: relative to L only.

    Args:
        data: the default-filled case mapping.
        stress: the stress scale of the case's loads and initial data.
        length: the body's size L (default: body_length(data)).

    Returns:
        PETSc option name -> default value.
    """
    length = body_length(data) if length is None else length
    force = stress * length ** (data["mesh"]["dim"] - 1)
    atol = DEFAULT_PETSC["snes_atol"]
    zero = DEFAULT_PETSC["snes_vi_zero_tolerance"] * length
    g = _gap_number(data)
    return {"snes_atol": atol * force / REFERENCE_FORCE if force > 0 else atol,
            "snes_vi_zero_tolerance": min(zero, 1e-4 * g) if g else zero}


def petsc_limits(data: dict, stress: float, length: float | None = None) -> dict:
    """The largest absolute tolerances that still solve a step of this case, with the
    reason (for petscopts.check_petsc_options): a residual tolerance of 1e-3 of the nodal
    force scale stress L^(d-1) (none without loads or initial data: u = 0 exactly), an
    active-set tolerance of 1e-3 of the gap g (a number) and of the body's size L.

    Args:
        data: the default-filled case mapping.
        stress: the stress scale of the case's loads and initial data.
        length: the body's size L (default: body_length(data)).

    Returns:
        PETSc option name -> (largest value, reason).
    """
    length = body_length(data) if length is None else length
    force = stress * length ** (data["mesh"]["dim"] - 1)
    limits = {}
    if force > 0:
        limits["snes_atol"] = (1e-3 * force, f"Newton would stop before solving, the "
                               f"residual's nodal forces are of order {force:.3g} "
                               "(stress x L^(d-1))")
    g = _gap_number(data)
    scale, what = (g, "the gap g") if g is not None and 0 < g < length else (length, "L")
    limits["snes_vi_zero_tolerance"] = (1e-3 * scale, f"SNES VI would take dofs "
                                        f"{1e-3 * scale:.3g} m (1e-3 {what}) or farther "
                                        "from their bound as active")
    return limits


def rescale_for_length(case: Case, length: float, stress: float | None = None) -> Case:
    """The case with its PETSc defaults scaled to the body's size ``length`` (known once a
    mesh.file is loaded; validation takes 1): the scaled absolute tolerances that were not
    given (in the case file or on the command line) are recomputed, and every given option
    is checked again against the new limits.

    Args:
        case: the validated case.
        length: the body's size L [m] (e.g. the largest side of the mesh's bounding box).
        stress: the stress scale of the loads and initial data, if measured on the mesh
            (default: as validation finds it, with E |u| / length for the initial and
            prescribed displacements).

    Returns:
        The case with the new petsc options, petsc_defaults and data_stress.

    Raises:
        CaseError: if a given absolute tolerance is too large for the new scales, or the
            length is not a positive finite number.
    """
    if not MIN_LENGTH <= length <= MAX_LENGTH:
        raise CaseError(f"{case.source}: mesh.file: the body's size {length:g} m is degenerate "
                        f"(allowed: {MIN_LENGTH:g} to {MAX_LENGTH:g})")
    stress = _check_values(case.raw, case.time, case.source, length) if stress is None \
        else float(stress)
    defaults = {**DEFAULT_PETSC, **scaled_petsc_defaults(case.raw, stress, length)}
    limits = petsc_limits(case.raw, stress, length)
    in_file = case.raw.get("petsc", {})
    missing = object()
    given = {k: v for k, v in case.petsc.items()
             if k in in_file or case.petsc_defaults.get(k, missing) != v}
    check_petsc_options(given, case.source, base=defaults, limits=limits)
    petsc = PetscOptions({**defaults, **given}, limits)
    return dataclasses.replace(case, petsc=petsc, data_stress=stress, petsc_defaults=defaults)


def _build(data: dict, source: str, time_grid: TimeGrid, petsc: dict) -> Case:
    """The :class:`Case` of a validated, default-filled case dictionary."""
    mesh, contact, loads = data["mesh"], data.get("contact", {}), data["loads"]
    init, vp = data.get("initial", {}), data["material"].get("viscoplastic")
    fr, mem = contact.get("friction"), contact.get("memory")
    slip = fr.get("slip") if fr else None
    name = data.get("name") or Path(source).stem
    if name in ("", ".", ".."):
        raise CaseError(f"{source}: name: the file name gives the case name {name!r}, which "
                        "cannot name an output directory; set name (allowed: letters, digits, "
                        "'_', '.' and '-', starting with a letter or digit)")
    g, d = contact.get("g"), contact.get("direction")
    return Case(
        name=name,
        source=source,
        mesh=_mesh_spec(mesh),
        material=Material(float(data["material"]["E"]), float(data["material"]["nu"]),
                          Viscoplastic(float(vp["lambda1"]), float(vp["lambda2"]),
                                       vp["kappa0"] if isinstance(vp["kappa0"], str)
                                       else float(vp["kappa0"])) if vp else None,
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
        numerics=Numerics(**data["solver"]),
        petsc=petsc,
        output=OutputSpec(**data["output"]),
        raw=data,
    )


def _mesh_spec(mesh: dict) -> MeshSpec:
    """The MeshSpec of the default-filled (and settled) mesh section."""
    if "file" in mesh:
        return MeshSpec(mesh["dim"], None, None, None, "file", None, None, None,
                        file=mesh["file"], size=float(mesh.get("size", 1.0)))
    return MeshSpec(mesh["dim"], float(mesh["L1"]), float(mesh["L2"]), float(mesh["L3"]),
                    mesh["kind"], int(mesh["n"]) if mesh["kind"] == "structured" else None,
                    float(mesh["h"]) if mesh["kind"] == "unstructured" else None,
                    mesh["diagonal"], engine=mesh["engine"])


def fast_eligible(case: Case) -> tuple[bool, str]:
    """Can the fast step solver (app/solvers/fast.py) solve this case?

    Args:
        case: the case.

    Returns:
        (eligible, why not: "" when eligible).
    """
    if case.time.scheme != "explicit" and case.material.viscoplastic is not None:
        return False, "the implicit history variant makes the bulk problem nonlinear"
    if case.numerics.quadrature != "vertex" and case.contact.active:
        return False, "the fast solver needs the nodal (vertex) Gamma3 quadrature"
    return True, ""


def load_case(path: str | Path, overrides: list[str] = ()) -> Case:
    """Read, override and validate a case file.

    Args:
        path: the case file.
        overrides: 'section.key=value' strings (``--set``).

    Returns:
        The Case.

    Raises:
        CaseError: for any problem, in one line naming the file and key.
    """
    return validate(load_raw(path, overrides), str(path))
