"""Reading, overriding and validating case files (YAML, safe loader, JSON schema).

A validated case is split into plain dataclasses: physical data, numerical settings,
PETSc options and output settings are separate objects.
"""
from __future__ import annotations

import copy
import dataclasses
import difflib
import math
import re
import stat
from dataclasses import dataclass, field
from pathlib import Path

import jsonschema
import yaml

from app.io.errors import CaseError
from app.io.petscopts import PetscOptions, check_petsc_options
from app.io.schema import DEFAULT_PETSC, SCHEMA
from meshes.rectangle import SIDES

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


_PATH = re.compile(r"[A-Za-z_]\w*(?:\.[A-Za-z_]\w*|\[\d+\])*")


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
        return re.sub(r"(\.[A-Za-z_]\w*|\[\d+\])$", "", path)

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
        for key, value in data.items():
            if not isinstance(key, str):
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
    """The ``mesh`` section: dimension, sides, structured (n) or unstructured (h)."""

    dim: int
    L1: float
    L2: float
    L3: float
    kind: str
    n: int | None
    h: float | None
    diagonal: str


@dataclass(frozen=True)
class Viscoplastic:
    """``material.viscoplastic``: the Perzyna law's lambda1, lambda2 and kappa0."""

    lambda1: float
    lambda2: float
    kappa0: float | str


@dataclass(frozen=True)
class Material:
    """The ``material`` section: E, nu, and the viscoplastic law or None (elastic)."""

    E: float
    nu: float
    viscoplastic: Viscoplastic | None


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
    """The ``contact`` section: gap g, normal compliance c_nu (4.1), friction, memory."""

    g: float | None
    c_nu: float | None
    friction: Friction | None
    memory: Memory | None = None

    @property
    def active(self) -> bool:
        """Any Gamma3 term present."""
        return any(x is not None for x in (self.g, self.c_nu, self.friction, self.memory))


@dataclass(frozen=True)
class Loads:
    """The ``loads`` section: body force f0 and tractions per side of Gamma2."""

    f0: tuple | None
    traction: dict


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
    """The ``solver`` section: step solver, delta, Gamma3 quadrature."""

    method: str
    delta: float
    quadrature: str
    gauss_degree: int


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

    @property
    def dim(self) -> int:
        """The space dimension."""
        return self.mesh.dim

    def active_terms(self) -> list[str]:
        """The model's terms this case has, for the run log.

        Returns:
            Their names.
        """
        terms = ["plane-stress elasticity" if self.dim == 2 else "isotropic elasticity (3D)"]
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
                      space_dim: int | None = None):
    """Length = dim; expressions parse with the allowed names (t if ``in_time``, the
    coordinates of a body of dimension ``space_dim``, default dim); tables increase in t."""
    from app.io import expressions

    names = ("t",) * in_time + ("x", "y", "z")[:space_dim or dim]
    if len(items) != dim:
        raise CaseError(f"{source}: {path}: expected {dim} components (the mesh dimension), "
                        f"got {len(items)}")
    for i, c in enumerate(items):
        if isinstance(c, str):
            try:
                expressions.parse(c, names)
            except expressions.ExpressionError as exc:
                raise CaseError(f"{source}: {path}[{i}]: {exc}") from None
        elif isinstance(c, dict) and "t" not in names:
            raise CaseError(f"{source}: {path}[{i}]: a table in time is not an initial value "
                            f"(allowed: a number or an expression in {', '.join(names)})")
        elif isinstance(c, dict):
            ts = [row[0] for row in c["table"]]
            if any(b <= a for a, b in zip(ts, ts[1:])):
                raise CaseError(f"{source}: {path}[{i}].table: times must increase strictly")


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
    errors = sorted(validator.iter_errors(data), key=lambda e: list(e.absolute_path))
    if errors:       # one line: the first error, then the others
        msgs = [_explain(e) for e in errors]
        more = f" (also: {'; '.join(msgs[1:])})" if len(msgs) > 1 else ""
        raise CaseError(f"{source}: {msgs[0]}{more}")
    _fill_defaults(SCHEMA, data)
    _check_mesh(data["mesh"], source)
    _check_structure(data, source)
    time_grid = dataclasses.replace(_time_grid(data["time"], source),
                                    scheme=data["time"]["scheme"],
                                    adaptive=data["time"].get("adaptive"))
    _check_adaptive(time_grid.adaptive, time_grid.times, source)
    stress = _check_values(data, time_grid, source)
    defaults = {**DEFAULT_PETSC, **scaled_petsc_defaults(data, stress)}
    limits = petsc_limits(data, stress)
    check_petsc_options(data.get("petsc", {}), source, base=defaults, limits=limits)
    petsc = PetscOptions({**defaults, **data.get("petsc", {})}, limits)
    case = dataclasses.replace(_build(data, source, time_grid, petsc), data_stress=stress)
    ok, why = fast_eligible(case)
    if case.numerics.method == "fast" and not ok:
        raise CaseError(f"{source}: solver.method: 'fast' is not possible here: {why} "
                        "(allowed: snes_vi, auto)")
    return case


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
    """Cross-key rules: vector lengths, sides, expressions parse, contact and memory."""
    dim = data["mesh"]["dim"]
    contact = data.get("contact", {})
    loads = data["loads"]
    traction = loads.get("traction", {})
    if contact and "bottom" in traction:
        raise CaseError(f"{source}: loads.traction.bottom: the bottom side is Gamma3 (contact); "
                        "a traction there is only allowed in a case without a contact section")
    sides = SIDES[dim]
    for side in traction:
        if side not in sides:
            raise CaseError(f"{source}: loads.traction.{side}: no such side in {dim}D "
                            f"(allowed: {', '.join(s for s in sides if s != 'left')})")
        _check_components(traction[side], f"loads.traction.{side}", dim, source)
    if "f0" in loads:
        _check_components(loads["f0"], "loads.f0", dim, source)
    if contact and not any(k in contact for k in ("g", "normal_compliance", "friction", "memory")):
        raise CaseError(f"{source}: contact: give at least one of g, normal_compliance, "
                        "memory, friction")
    vp = data["material"].get("viscoplastic")
    if vp and isinstance(vp["kappa0"], str):
        _check_components([vp["kappa0"]], "material.viscoplastic.kappa0", 1, source,
                          in_time=False, space_dim=dim)
    fr = contact.get("friction")
    if fr and fr["b"] - fr["c1"] * fr["u1"] < 0:
        raise CaseError(f"{source}: contact.friction: b - c1 u1 must be >= 0 (the friction "
                        f"force of law (4.2) may not change sign), got "
                        f"{fr['b'] - fr['c1'] * fr['u1']:g}")
    if contact.get("memory"):
        _check_memory(contact["memory"], source)
    init = data.get("initial", {})
    if "u0" in init:
        _check_components(init["u0"], "initial.u0", dim, source, in_time=False)
    if "sigma0" in init:
        rows = init["sigma0"]
        if len(rows) != dim or any(len(r) != dim for r in rows):
            raise CaseError(f"{source}: initial.sigma0: expected a {dim} x {dim} matrix")
        for i, r in enumerate(rows):
            _check_components(r, f"initial.sigma0[{i}]", dim, source, in_time=False)


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


def _check_values(data: dict, time_grid: TimeGrid, source: str) -> float:
    """The data values at sample points of the body and times (app/io/datacheck.py): finite,
    initial values in the model's set.  Returns the stress scale of the data (loads,
    sigma0 and the stress E |u0| / L of the initial displacement)."""
    from app.io import datacheck

    mesh = data["mesh"]
    lengths = [mesh["L1"], mesh["L2"], mesh["L3"]][:mesh["dim"]]
    cells = [mesh["n"] if mesh["kind"] == "structured" else math.ceil(L / mesh["h"])
             for L in lengths]
    samples = datacheck.Samples(lengths, cells, time_grid.times, time_grid.adaptive is not None)
    vp = data["material"].get("viscoplastic")
    init = data.get("initial", {})
    try:
        loads = datacheck.check_loads(data["loads"], samples)
        u0, sigma0 = datacheck.check_initial(init, vp["kappa0"] if vp else None,
                                             data.get("contact", {}).get("g"), samples)
    except datacheck.DataError as exc:
        raise CaseError(f"{source}: {exc}") from None
    return max(loads, sigma0, data["material"]["E"] * u0 / max(lengths))


def scaled_petsc_defaults(data: dict, stress: float) -> dict:
    """DEFAULT_PETSC's absolute tolerances scaled to the case, so that a body of any size
    or stiffness converges alike (their values hold for the paper's scales: the unit square
    under a stress of 8 N/m^2):
    - snes_atol, on the residual, a vector of nodal forces ~ stress L^(d-1); without loads
      or initial data (u = 0 exactly) the default value serves;
    - snes_vi_zero_tolerance, how close to its bound (in m) SNES VI takes a dof as active:
      relative to the body's size L, and at most 1e-4 of the gap g (a tenth of the limit
      in petsc_limits, so that a small gap keeps a valid default).

    Args:
        data: the default-filled case mapping.
        stress: the stress scale of the case's loads and initial data.

    Returns:
        PETSc option name -> default value.
    """
    mesh = data["mesh"]
    length = max([mesh["L1"], mesh["L2"], mesh["L3"]][:mesh["dim"]])
    force = stress * length ** (mesh["dim"] - 1)
    atol = DEFAULT_PETSC["snes_atol"]
    zero = DEFAULT_PETSC["snes_vi_zero_tolerance"] * length
    g = data.get("contact", {}).get("g")
    return {"snes_atol": atol * force / REFERENCE_FORCE if force > 0 else atol,
            "snes_vi_zero_tolerance": min(zero, 1e-4 * g) if g else zero}


def petsc_limits(data: dict, stress: float) -> dict:
    """The largest absolute tolerances that still solve a step of this case, with the
    reason (for petscopts.check_petsc_options): a residual tolerance of 1e-3 of the nodal
    force scale stress L^(d-1) (none without loads or initial data: u = 0 exactly), an
    active-set tolerance of 1e-3 of the gap g and of the body's size L.

    Args:
        data: the default-filled case mapping.
        stress: the stress scale of the case's loads and initial data.

    Returns:
        PETSc option name -> (largest value, reason).
    """
    mesh = data["mesh"]
    length = max([mesh["L1"], mesh["L2"], mesh["L3"]][:mesh["dim"]])
    force = stress * length ** (mesh["dim"] - 1)
    limits = {}
    if force > 0:
        limits["snes_atol"] = (1e-3 * force, f"Newton would stop before solving, the "
                               f"residual's nodal forces are of order {force:.3g} "
                               "(stress x L^(d-1))")
    g = data.get("contact", {}).get("g")
    scale, what = (g, "the gap g") if g is not None and 0 < g < length else (length, "L")
    limits["snes_vi_zero_tolerance"] = (1e-3 * scale, f"SNES VI would take dofs "
                                        f"{1e-3 * scale:.3g} m (1e-3 {what}) or farther "
                                        "from their bound as active")
    return limits


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
    return Case(
        name=name,
        source=source,
        mesh=MeshSpec(mesh["dim"], float(mesh["L1"]), float(mesh["L2"]), float(mesh["L3"]),
                      mesh["kind"], int(mesh["n"]) if mesh["kind"] == "structured" else None,
                      float(mesh["h"]) if mesh["kind"] == "unstructured" else None,
                      mesh["diagonal"]),
        material=Material(float(data["material"]["E"]), float(data["material"]["nu"]),
                          Viscoplastic(float(vp["lambda1"]), float(vp["lambda2"]),
                                       vp["kappa0"] if isinstance(vp["kappa0"], str)
                                       else float(vp["kappa0"])) if vp else None),
        contact=Contact(
            float(contact["g"]) if "g" in contact else None,
            float(contact["normal_compliance"]["c_nu"]) if "normal_compliance" in contact
            else None,
            Friction(*(float(fr[k]) for k in ("b", "c1", "c2", "u1")),
                     Slip(float(slip["theta_inf"]), float(slip["s0"])) if slip else None)
            if fr else None,
            Memory(float(mem["b0"]), float(mem["beta"]), mem["kernel"], mem.get("alpha"),
                   mem.get("tau"), tuple(map(tuple, mem["table"])) if "table" in mem else None,
                   mem["sum"]) if mem else None),
        loads=Loads(tuple(loads["f0"]) if "f0" in loads else None,
                    {k: tuple(v) for k, v in loads.get("traction", {}).items()}),
        initial=Initial(tuple(init["u0"]) if "u0" in init else None,
                        tuple(map(tuple, init["sigma0"])) if "sigma0" in init else None),
        time=time_grid,
        numerics=Numerics(**data["solver"]),
        petsc=petsc,
        output=OutputSpec(**data["output"]),
        raw=data,
    )


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
