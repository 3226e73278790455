"""Reading a case file: the YAML text with line numbers, hardened, and the ``--set`` overrides.

The text is read only from a regular file of at most MAX_FILE_BYTES bytes of UTF-8 and parsed
by a safe loader (plain data, no Python objects; tags refused, duplicate keys refused, 1e-4
read as a float); anchors are expanded by YAML, and the data after expansion is bounded
(MAX_CASE_SIZE values), finite and of sensible magnitude.  The result is a ``RawCase``: the
mapping as given, with the line of every key for the messages (``with_lines``).  Nothing here
knows the schema; validation (app/case/validation.py) does.
"""
from __future__ import annotations

import math
import re
import stat
from pathlib import Path

import yaml

from vpcontact.io.casekey import GROUP_MAPS
from vpcontact.io.errors import CaseError

MAX_INT_DIGITS = 30
MAX_CASE_SIZE = 2_000_000   # numbers, strings and containers after alias expansion
MAX_FILE_BYTES = 50_000_000
# magnitude of a nonzero number of the case (outside PETSc options): products and squares
# of a few data values stay within double precision
MIN_MAGNITUDE, MAX_MAGNITUDE = 1e-100, 1e100


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


_INDEXED = re.compile(r"(.+)\[([0-9]{1,6})\]")     # a list entry: contact.pairs[1].g


def _set_path(data: dict, dotted: str, value) -> None:
    """data at the key path ``dotted`` (sections by name, list entries as name[i]) =
    value; missing sections are created, a list entry must exist, and a key of a material
    group only in a group the case has (``_material_group``)."""
    keys = dotted.split(".")
    if keys[0] == "materials" and len(keys) > 2:
        keys[1] = _material_group(data, keys[1], dotted)
    node = data
    for key in keys[:-1]:
        node = _entry(node, key, dotted)
    last = keys[-1]
    if keys[:-1] in (["loads", kind] for kind in GROUP_MAPS) and \
            re.fullmatch(rf"[0-9]{{1,{MAX_INT_DIGITS}}}", last):
        last = int(last)                  # a physical tag, as YAML reads the key 3:
    indexed = _INDEXED.fullmatch(last)
    if indexed:
        entries, i = _list(node, indexed.group(1), int(indexed.group(2)), dotted)
        entries[i] = value
        return
    node[last] = value


def _material_group(data: dict, group: str, dotted: str):
    """The key of the case's material group that ``--set materials.<group>.<key>`` names: a
    name, or a physical tag written as digits (as YAML reads the key 10:).  A --set does not
    create a group by one of its keys (it would be a group without the others)."""
    groups = data.get("materials")
    groups = groups if isinstance(groups, dict) else {}
    if group in groups:
        return group
    if re.fullmatch(rf"[0-9]{{1,{MAX_INT_DIGITS}}}", group) and int(group) in groups:
        return int(group)
    raise CaseError(f"--set {dotted}: no material group {group!r} in the case (its groups: "
                    f"{', '.join(map(str, groups)) or 'none: no materials section'}); a --set "
                    "changes a group's keys, it does not add a group")


def _entry(node: dict, key: str, dotted: str) -> dict:
    """The section ``key`` of node (created if missing), or the list entry key = name[i]
    (a physical tag, an int key, is a section)."""
    indexed = isinstance(key, str) and _INDEXED.fullmatch(key)
    if indexed:
        entries, i = _list(node, indexed.group(1), int(indexed.group(2)), dotted)
        if not isinstance(entries[i], dict):
            raise CaseError(f"--set {dotted}: '{key}' is not a section")
        return entries[i]
    if not isinstance(node.get(key, {}), dict):
        raise CaseError(f"--set {dotted}: '{key}' is not a section")
    return node.setdefault(key, {})


def _list(node: dict, name: str, i: int, dotted: str) -> tuple[list, int]:
    """(the list ``name`` of node, i), i an existing entry."""
    entries = node.get(name)
    if not isinstance(entries, list):
        raise CaseError(f"--set {dotted}: '{name}' is not a list (name[i] selects an entry "
                        "of a list)")
    if i >= len(entries):
        raise CaseError(f"--set {dotted}: '{name}' has {len(entries)} entries "
                        f"(allowed: {name}[0] to {name}[{len(entries) - 1}])"
                        if entries else f"--set {dotted}: '{name}' has no entries")
    return entries, i


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
    """The parsed case mapping; ``lines`` maps dotted key paths to their 1-based YAML line,
    ``overrides`` the key paths given by ``--set`` to their 'KEY=VALUE' text."""

    lines: dict = {}
    overrides: dict = {}


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


def with_lines(message: str, lines: dict, overrides: dict | None = None) -> str:
    """Add '(line N)' after the key paths of a message that the YAML text has; a message
    naming a key path whose value (or a part of it) came from --set ends with
    '(the value of --set KEY=VALUE)' instead, and no line of the file is cited for it.

    Args:
        message: a CaseError message.
        lines: key path -> line (``key_lines``).
        overrides: key path given by --set -> its 'KEY=VALUE' text (RawCase.overrides).

    Returns:
        The message with the lines.
    """
    overrides = overrides or {}
    if not lines and not overrides:
        return message

    def parent(path: str) -> str:
        return re.sub(r"(\.\w+|\[\d+\])$", "", path)

    given = []

    def add(m):
        path = m.group(0)
        given.extend(text for key, text in overrides.items()
                     if path == key or path.startswith((key + ".", key + "[")))
        if given:
            return path
        while path and path not in lines:       # the deepest key present in the file
            shorter = parent(path)
            path = shorter if shorter != path else ""
        return f"{m.group(0)} (line {lines[path]})" if path else m.group(0)
    # a key path is followed by ': ' where our messages name it
    message = re.sub(r"(?<![\w.\[\]])" + _PATH.pattern + r"(?=: )", add, message)
    return f"{message} (the value of --set {given[0]})" if given else message


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


def _is_tag(key) -> bool:
    """A physical group's tag: an integer >= 0 (not a bool)."""
    return isinstance(key, int) and not isinstance(key, bool) and key >= 0


def check_data(data, path: str, source, budget: list) -> None:
    """Reject non-finite numbers, numbers out of range, keys that are not names (or groups
    in the loads' group maps) and oversized data (YAML alias bombs), naming the key.

    Args:
        data: the (sub)mapping, list or value.
        path: its dotted key path ("" at the top).
        source: the case file, for messages.
        budget: [the number of values still allowed], decremented in place.

    Raises:
        CaseError: for the first value refused.
    """
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
        groups = path in tuple(f"loads.{m}" for m in GROUP_MAPS) + ("materials",)
        for key, value in data.items():
            if groups and not isinstance(key, str) and not _is_tag(key):
                raise CaseError(f"{source}: {path}: the key {key!r} is not a group (a name, or "
                                "a physical tag: an integer >= 0)")
            if not isinstance(key, str) and not groups:
                raise CaseError(f"{source}: {path or '(top level)'}: the key {key!r} is not a "
                                "name (keys are strings such as 'mesh' or 'E')")
            check_data(value, f"{path}.{key}" if path else str(key), source, budget)
    elif isinstance(data, list):
        for i, value in enumerate(data):
            check_data(value, f"{path}[{i}]", source, budget)


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
    data.overrides = {}
    for item in overrides:
        key, value = parse_override(item)
        _set_path(data, key, value)
        data.lines.pop(key, None)              # the value comes from --set, not the file
        data.overrides[key] = item if len(item) <= 80 else item[:77] + "..."
    try:
        check_data(data, "", path, [MAX_CASE_SIZE])
    except RecursionError:
        raise CaseError(f"{path}: the case is nested too deeply") from None
    except CaseError as exc:
        raise CaseError(with_lines(str(exc), data.lines, data.overrides)) from None
    return data

