"""What a gmsh file may make gmsh do: every statement is checked before gmsh sees the file.

gmsh 4.8's ``.geo`` language (Parser/Gmsh.l and Gmsh.y of gmsh 4.8.4) can run shell commands
(``SystemCall``, ``System``, ``NonBlockingSystemCall``, ``OnelabRun``, a ``Merge`` of a
``.py``/``.exe``/``.gz`` file), write files (``Save``, ``Print``, ``Printf(...) > "file"``,
``CreateDir``, ``Save View``, ``SendToServer``, plugins, the ``Solver.*``/``Print.*``/
``General.*`` options that name executables and files), end the process (``Exit``,
``Abort``), wait (``Sleep``) or read the terminal (``GetValue``, ``GetStringValue``) and what
is not part of the case (``GetEnv``, ``FileExists``, ``ListFromFile``).  A case must never
do any of this, so ``mesh_files`` tokenises each file as gmsh's scanner does (``//`` and
``/* */`` comments, ``"..."`` and ``'...'`` strings, whole words, so neither a comment nor a
string nor spacing hides or fakes a statement) and refuses every such word wherever it
stands: in a branch never taken, in a ``Macro``/``Function`` body (called by ``Call``, so the
scan of the body is the scan of the call) or as a variable name alike.  A name built at run
time (``StringToName``/``S2N``) could name any command and is refused too.

The files gmsh reads are followed: ``Include "f"`` (parsed like the file itself, from any
suffix), ``Merge "f"`` (a ``.geo`` is parsed; a CAD file ``.step``/``.stp``/``.iges``/
``.igs``/``.brep``/``.stl`` or a ``.msh`` that starts with ``$MeshFormat`` is data; any
other suffix could be parsed as a script or run, and is refused), ``ShapeFromFile("f")``
(CAD data), and the ``<file>.opt`` that gmsh merges after every file it merges (parsed).  A
file name must be a literal string (relative names are relative to the file that names
them, as gmsh's FixRelativePath makes them).  A ``.msh`` is data only if it starts with a
mesh header: gmsh parses any other file as a script.

``mesh_files`` returns every file the mesh is made of, so that the checkpoint's fingerprint
(app/io/checkpoint.py) changes with any of them.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

# the words gmsh acts on that a case may not use, and why (one line each)
_FORBIDDEN = {
    "SystemCall": "runs a shell command",
    "System": "runs a shell command",
    "NonBlockingSystemCall": "runs a shell command",
    "OnelabRun": "runs a program",
    "Exit": "ends the process",
    "Abort": "ends the parsing",
    "Save": "writes a file",
    "Print": "writes a file",
    "CreateDir": "creates a directory",
    "SendToServer": "sends data to a server",
    "Plugin": "runs a gmsh plugin (plugins can read and write files)",
    "Sleep": "makes gmsh wait",
    "PartitionMesh": "partitions the mesh (and can write a topology file)",
    "GetValue": "reads the terminal",
    "GetStringValue": "reads the terminal",
    "GetEnv": "reads the environment, which is not part of the case",
    "FileExists": "looks at files that are not part of the case",
    "ListFromFile": "reads a file that is not part of the case",
    "StringToName": "builds a name at run time (it could name any command)",
    "S2N": "builds a name at run time (it could name any command)",
}
# option categories: a .geo may set Mesh.* and Geometry.* (but not the partitioning, which
# writes a topology file, nor a command for the GUI) and these General.* only
_OPTION_CATEGORIES = ("General", "Solver", "PostProcessing", "View", "Print", "Mesh",
                      "Geometry")
_ALLOWED_OPTIONS = {("General", "Terminal"), ("General", "Verbosity"),
                    ("General", "NumThreads")}
_REFUSED_MESH_OPTIONS = re.compile(r"Partition.*|NbPartitions|.*Command")
# Merge: gmsh reads these suffixes (exact spelling, as in Common/OpenFile.cpp) as CAD data
_CAD = {".stl", ".STL", ".brep", ".brp", ".BRP", ".rle", ".iges", ".IGES", ".igs", ".IGS",
        ".step", ".STEP", ".stp", ".STP"}
# the first line of a file gmsh reads as a mesh (else it parses the file as a script)
_MESH_HEADERS = (b"$MeshFormat", b"$Comments", b"$NOD", b"$ELM", b"$PTS", b"$PARA")
_MAX_FILES = 200
_MAX_STRING = 1023            # gmsh 4.8's parsestring() keeps at most this many characters
_WORD = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_NUMBER = re.compile(r"[0-9]+\.?[0-9]*(?:[Ee][-+]?[0-9]+)?|\.[0-9]+(?:[Ee][-+]?[0-9]+)?")


class GeoScanError(ValueError):
    """A gmsh file that would make gmsh execute, write or read what a case may not."""


@dataclass(frozen=True)
class Token:
    """One token of gmsh's scanner: kind "word", "string", "number" or "op"; its line."""

    kind: str
    text: str
    line: int


def tokens(text: str, name: str) -> list[Token]:
    """Split a gmsh script into tokens as gmsh 4.8's scanner (Parser/Gmsh.l) does.

    Args:
        text: the file's text (decoded byte for byte, latin-1).
        name: the file's name, for the messages.

    Returns:
        The tokens, comments and white space dropped.

    Raises:
        GeoScanError: an unterminated comment or string, a string longer than gmsh's
            scanner takes, or a NUL byte (where gmsh and this scanner would differ).
    """
    if "\0" in text:            # gmsh's scanner ends a comment or string at a NUL byte
        line = text.count("\n", 0, text.index("\0")) + 1
        raise GeoScanError(f"{name}, line {line}: a NUL byte; a gmsh script is text")
    out, i, line, n = [], 0, 1, len(text)
    while i < n:
        c = text[i]
        if c in " \t\r\f\n":
            line += c == "\n"
            i += 1
        elif text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            if j < 0:
                raise GeoScanError(f"{name}, line {line}: a comment /* is never closed")
            line += text.count("\n", i, j)
            i = j + 2
        elif c in "\"'":
            j = text.find(c, i + 1)
            if j < 0:
                raise GeoScanError(f"{name}, line {line}: a string {c} is never closed")
            if j - i - 1 > _MAX_STRING:     # gmsh would lex the rest of it as statements
                raise GeoScanError(f"{name}, line {line}: a string of more than "
                                   f"{_MAX_STRING} characters (gmsh's limit)")
            out.append(Token("string", text[i + 1:j], line))
            line += text.count("\n", i, j)
            i = j + 1
        else:
            m = (_NUMBER.match(text, i) if c.isdigit() or c == "." else None) or \
                _WORD.match(text, i)
            kind = "op" if m is None else ("word" if m.re is _WORD else "number")
            word = c if m is None else m.group()
            out.append(Token(kind, word, line))
            i += len(word)
    return out


def _resolve(current: Path, name: str) -> Path:
    """gmsh's FixRelativePath: a relative name is relative to the naming file's directory."""
    p = Path(name)
    return p if p.is_absolute() else current.parent / p


def _literal(toks: list[Token], i: int, shape: tuple[str, ...]) -> str | None:
    """The literal file name of ``toks[i]`` followed by ``shape`` ("S" the string), or None."""
    for k, want in enumerate(shape, start=i + 1):
        if k >= len(toks):
            return None
        if want == "S" and toks[k].kind != "string":
            return None
        if want != "S" and toks[k].text != want:
            return None
    return toks[i + 1 + shape.index("S")].text


def _skip_parentheses(toks: list[Token], i: int) -> int:
    """The index after the parenthesis that closes the one at toks[i] (len if none)."""
    depth = 0
    for k in range(i, len(toks)):
        depth += {"(": 1, ")": -1}.get(toks[k].text, 0) if toks[k].kind == "op" else 0
        if depth == 0:
            return k + 1
    return len(toks)


def _option(toks: list[Token], i: int) -> str | None:
    """The option ``Category.Name`` toks[i] starts if it is not one a .geo may use."""
    category = toks[i].text
    k = i + 1
    if k < len(toks) and toks[k].text == "[":         # View[0].Name
        while k < len(toks) and toks[k].text != "]":
            k += 1
        k += 1
    if k >= len(toks) or toks[k].text not in (".", "["):
        return None
    name = toks[k + 1].text if k + 1 < len(toks) and toks[k].text == "." else "?"
    if category in ("Mesh", "Geometry"):
        return f"{category}.{name}" if _REFUSED_MESH_OPTIONS.fullmatch(name) else None
    return None if (category, name) in _ALLOWED_OPTIONS else f"{category}.{name}"


def _statements(toks: list[Token], path: Path, name: str) -> list[tuple[str, Path, int]]:
    """Refuse what a case may not do; the files the script reads as (how, path, line)."""
    files = []
    for i, tok in enumerate(toks):
        if tok.kind != "word":
            continue
        where = f"{name}, line {tok.line}"
        word = tok.text
        if word in _FORBIDDEN:
            raise GeoScanError(f"{where}: '{word}' {_FORBIDDEN[word]}; a case's gmsh file "
                               "may not run commands, write files or end gmsh: remove it")
        if word in _OPTION_CATEGORIES and (option := _option(toks, i)) is not None:
            raise GeoScanError(f"{where}: the option {option} is not allowed in a case's "
                               "gmsh file (Mesh.* and Geometry.* but partitioning and GUI "
                               "commands, and General.Terminal/Verbosity/NumThreads are): "
                               "remove it")
        if word == "Printf" and _skip_parentheses(toks, i + 1) < len(toks) and \
                toks[_skip_parentheses(toks, i + 1)].text != ";":
            raise GeoScanError(f"{where}: 'Printf(...) >' writes a file; a case's gmsh file "
                               "may not write files: remove the redirection")
        shape = {"Include": ("S", ";"), "Merge": ("S", ";"), "MergeWithBoundingBox": ("S", ";"),
                 "ShapeFromFile": ("(", "S", ")")}.get(word)
        if shape is None:
            continue
        literal = _literal(toks, i, shape)
        if not literal:
            raise GeoScanError(f"{where}: '{word}' needs a literal file name (a \"string\"), "
                               "so that vpcontact can check the file before gmsh reads it")
        how = {"Include": "include", "ShapeFromFile": "cad"}.get(word, "merge")
        files.append((how, _resolve(path, literal), tok.line))
    return files


def _read(path: Path, name: str, size: int = -1) -> bytes:
    """The file's first ``size`` bytes (all: -1)."""
    try:
        with open(path, "rb") as f:
            return f.read(size)
    except OSError as err:
        raise GeoScanError(f"{name}: cannot read {path}: {err.strerror or err}") from None


def _merged_kind(path: Path, where: str) -> str:
    """How gmsh reads a merged file: "script" (parsed) or "data"; other suffixes refused."""
    if path.suffix == ".geo":
        return "script"
    if path.suffix in _CAD:
        return "data"
    if path.suffix == ".msh":
        readable = path.is_file() and _read(path, where, 64).startswith(_MESH_HEADERS)
        return "data" if readable or not path.is_file() else "script"
    raise GeoScanError(f"{where}: Merge of {path.name!r}: vpcontact lets a .geo merge only "
                       ".geo, .msh and CAD files (.step .stp .iges .igs .brep .stl)")


def mesh_files(path) -> list[Path]:
    """Every file a gmsh mesh file makes gmsh read, each script checked (module docstring).

    Args:
        path: the case's .msh or .geo file.

    Returns:
        The files, the given one first, each once: scripts (.geo, included files, .opt
        files), merged meshes and CAD files.

    Raises:
        GeoScanError: a script uses a statement a case may not use, names a file by an
            expression, includes itself, or a file it names cannot be read.
    """
    path = Path(path)
    first = "script" if path.suffix.lower() == ".geo" else "data"
    if first == "data" and path.is_file() and not _read(path, str(path), 64).startswith(
            _MESH_HEADERS):
        raise GeoScanError(f"{path} is not a gmsh mesh (it does not start with $MeshFormat), "
                           "and gmsh would run it as a script; give a .msh saved by gmsh")
    seen: dict[Path, None] = {}
    _visit(path, first, str(path), (), seen, merged=True)
    return list(seen)


def _visit(path: Path, kind: str, where: str, stack: tuple, seen: dict, merged: bool) -> None:
    """Add ``path`` (and what it reads) to ``seen``; a script is scanned first.  ``merged``:
    gmsh reads the file with MergeFile, which then merges ``<file>.opt`` if it exists."""
    key = Path(path)
    if key in stack:
        raise GeoScanError(f"{where}: {path.name!r} includes itself (through "
                           f"{' -> '.join(p.name for p in stack)}); remove the cycle")
    if key in seen:
        return
    if len(seen) >= _MAX_FILES:
        raise GeoScanError(f"{where}: more than {_MAX_FILES} files are included or merged")
    if not path.is_file():
        raise GeoScanError(f"{where}: {path} is not a readable file (it is named by a gmsh "
                           "file of the case)")
    data = _read(path, where, -1 if kind == "script" else 1)
    seen[key] = None
    if kind == "script":
        name = str(path)
        for how, child, line in _statements(tokens(data.decode("latin-1"), name), path, name):
            at = f"{name}, line {line}"
            sub = "script" if how == "include" else "data" if how == "cad" else \
                _merged_kind(child, at)
            _visit(child, sub, at, stack + (key,), seen, merged=how == "merge")
    opt = Path(f"{path}.opt")
    if merged and opt.exists():
        _visit(opt, "script", f"{path} (gmsh reads {opt.name} with it)", stack + (key,), seen,
               merged=True)
