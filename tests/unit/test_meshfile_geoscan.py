"""A case's gmsh files never make gmsh execute, write or end anything, and
every file a .geo reads is part of the checkpoint's fingerprint."""
import os
from pathlib import Path

import pytest
from mpi4py import MPI

from vpcontact.meshes import MeshFileError, geoscan, load_mesh_file
from vpcontact.meshes.geoscan import GeoScanError, mesh_files, tokens

SQUARE = """Point(1) = {0, 0, 0, 0.5}; Point(2) = {1, 0, 0, 0.5};
Point(3) = {1, 1, 0, 0.5}; Point(4) = {0, 1, 0, 0.5};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Curve("bottom") = {1}; Physical Surface("body") = {1};
"""
MARK = "MARK"        # replaced by the path of a file the statement would create


def _write(path: Path, text: str) -> Path:
    path.write_text(text if text.endswith("\n") else text + "\n")
    return path


# (statement, the word the message quotes); each would create MARK if gmsh ran it
EXECUTES = [
    ('SystemCall "touch MARK";', "'SystemCall' runs a shell command"),
    ('System "touch MARK";', "'System' runs a shell command"),
    ('NonBlockingSystemCall "touch MARK";', "'NonBlockingSystemCall' runs"),
    ('SystemCall /* hidden */ StrCat("touch ", "MARK");', "'SystemCall' runs"),
    ('OnelabRun("sh", "-c \'touch MARK\'");', "'OnelabRun' runs a program"),
    ('Save "MARK";', "'Save' writes a file"),
    ('Print "MARK";', "'Print' writes a file"),
    ('Printf("x") > "MARK";', "'Printf(...) >' writes a file"),
    ('Printf("%g", 1) >> "MARK";', "'Printf(...) >' writes a file"),
    ('CreateDir "MARK";', "'CreateDir' creates a directory"),
    ('Plugin(GSHHS).OutFileName = "MARK";', "'Plugin' runs a gmsh plugin"),
    ('Solver.Executable0 = "MARK";', "the option Solver.Executable0 is not allowed"),
    ('General.AbortOnError = 4;', "the option General.AbortOnError is not allowed"),
    ("Mesh.PartitionTopologyFile = 1;", "the option Mesh.PartitionTopologyFile is not"),
    ("PartitionMesh 2;", "'PartitionMesh' partitions the mesh"),
    ('Geometry.DoubleClickedPointCommand = "Exit;";',
     "the option Geometry.DoubleClickedPointCommand is not"),
    ("Exit;", "'Exit' ends the process"),
    ("Abort;", "'Abort' ends the parsing"),
    ("Sleep 100;", "'Sleep' makes gmsh wait"),
    ('x = GetValue("x?", 1);', "'GetValue' reads the terminal"),
    ('s = GetEnv("HOME");', "'GetEnv' reads the environment"),
    ('S2N[StrCat("System", "Call")] "touch MARK";', "'S2N' builds a name at run time"),
    ('StringToName["Save"] "MARK";', "'StringToName' builds a name"),
    # a macro's body is scanned where it stands, called or not
    ('Macro M\n  SystemCall "touch MARK";\nReturn\nCall M;', "'SystemCall' runs"),
    ('Function F\n  SystemCall "touch MARK";\nReturn\nCall F;', "'SystemCall' runs"),
    ("If (0)\n  Exit;\nEndIf", "'Exit' ends the process"),
]


@pytest.mark.parametrize("statement, message", EXECUTES, ids=[e[0][:30] for e in EXECUTES])
def test_a_statement_that_executes_is_refused_before_gmsh_runs_it(tmp_path, statement,
                                                                   message):
    mark = tmp_path / "created"
    geo = _write(tmp_path / "part.geo", SQUARE + statement.replace("MARK", str(mark)))
    word = message.split("'")[1].split("(")[0] if "'" in message else message.split()[2]
    line = SQUARE.count("\n") + 1 + next(k for k, s in enumerate(statement.split("\n"))
                                          if word in s)
    with pytest.raises(MeshFileError) as err:
        load_mesh_file(MPI.COMM_SELF, geo, 2)
    text = str(err.value)
    assert "\n" not in text and message in text, text
    assert text.startswith(f"{geo}, line {line}: "), text
    assert not mark.exists()


def test_an_included_file_is_scanned_and_named(tmp_path):
    mark = tmp_path / "created"
    (tmp_path / "sub").mkdir()
    _write(tmp_path / "sub" / "evil.txt", f'// any suffix is parsed\n\nSystemCall "touch {mark}";')
    _write(tmp_path / "sub" / "mid.geo", 'Include "evil.txt";')   # relative to mid.geo
    geo = _write(tmp_path / "part.geo", SQUARE + 'Include "sub/mid.geo";')
    with pytest.raises(MeshFileError, match=r"sub/evil\.txt, line 3: 'SystemCall' runs"):
        load_mesh_file(MPI.COMM_SELF, geo, 2)
    assert not mark.exists()


def test_opt_files_gmsh_merges_are_scanned(tmp_path):
    """gmsh merges <file>.opt after every file it merges, the .geo and a .msh alike."""
    mark = tmp_path / "created"
    geo = _write(tmp_path / "part.geo", SQUARE)
    _write(tmp_path / "part.geo.opt", f'SystemCall "touch {mark}";')
    with pytest.raises(MeshFileError, match=r"part\.geo\.opt, line 1: 'SystemCall'"):
        load_mesh_file(MPI.COMM_SELF, geo, 2)
    os.remove(tmp_path / "part.geo.opt")
    load_mesh_file(MPI.COMM_SELF, geo, 2)          # meshes and writes no .opt itself
    msh = tmp_path / "part.msh"
    _save_msh(geo, msh)
    _write(tmp_path / "part.msh.opt", f'Save "{mark}";')
    with pytest.raises(MeshFileError, match=r"part\.msh\.opt, line 1: 'Save' writes"):
        load_mesh_file(MPI.COMM_SELF, msh, 2)
    assert not mark.exists()


def _save_msh(geo: Path, msh: Path) -> None:
    from vpcontact.meshes.gmshfile import import_gmsh
    gmsh = import_gmsh()
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.open(str(geo))
        gmsh.model.mesh.generate(2)
        gmsh.write(str(msh))
    finally:
        gmsh.finalize()


def test_a_msh_that_is_a_script_is_refused(tmp_path):
    """gmsh parses a "mesh" without a mesh header as a .geo script."""
    mark = tmp_path / "created"
    msh = _write(tmp_path / "part.msh", SQUARE + f'SystemCall "touch {mark}";')
    with pytest.raises(MeshFileError, match=r"part\.msh is not a gmsh mesh .*\$MeshFormat"):
        load_mesh_file(MPI.COMM_SELF, msh, 2)
    assert not mark.exists()


UNKNOWN_FILES = [
    ('Include StrCat("a", ".geo");', r"'Include' needs a literal file name"),
    ("name = \"a.geo\"; Include name;", r"'Include' needs a literal file name"),
    ('Include "missing.geo";', r"missing\.geo is not a readable file"),
    ('Merge "tool.py";', r"Merge of 'tool\.py'.*only \.geo, \.msh and CAD files"),
    ('Merge "part.msh.gz";', r"Merge of 'part\.msh\.gz'"),
    ('v() = ShapeFromFile(name);', r"'ShapeFromFile' needs a literal file name"),
    ('Include "part.geo";', r"'part\.geo' includes itself"),
    ('x = "unterminated;', r"a string \" is never closed"),
    ("/* unterminated", r"a comment /\* is never closed"),
    # where gmsh's scanner would stop a string or comment early (an error in gmsh 4.8)
    ('s = "' + "A" * 1023 + ' SystemCall \'touch x\';";', r"a string of more than 1023"),
    ('/* \0 SystemCall "touch x"; */', r"line 6: a NUL byte"),
]


@pytest.mark.parametrize("statement, message", UNKNOWN_FILES,
                         ids=[u[0][:24].replace("\0", "NUL") for u in UNKNOWN_FILES])
def test_files_gmsh_would_read_must_be_known(tmp_path, statement, message):
    geo = _write(tmp_path / "part.geo", SQUARE + statement)
    with pytest.raises(MeshFileError, match=message) as err:
        load_mesh_file(MPI.COMM_SELF, geo, 2)
    assert "\n" not in str(err.value)


def test_an_unreadable_include_is_refused(tmp_path, monkeypatch):
    part = _write(tmp_path / "part.geo", SQUARE + 'Include "sizes.geo";')
    sizes = _write(tmp_path / "sizes.geo", "h = 0.5;")

    def locked(path, *args, **kwargs):
        if Path(path) == sizes:
            raise PermissionError(13, "Permission denied")
        return open(path, *args, **kwargs)
    monkeypatch.setattr(geoscan, "open", locked, raising=False)   # root reads any file
    with pytest.raises(GeoScanError, match=r"cannot read .*sizes\.geo: Permission denied"):
        mesh_files(part)


def test_comments_and_strings_do_not_fool_the_scan(tmp_path):
    """Words in comments and strings are not statements; a mesh with what a case may use
    (Include, Merge of a .geo, Mesh./Geometry. options, Printf to the terminal) loads."""
    _write(tmp_path / "sizes.geo", "// SystemCall \"x\";\nh = 0.5; /* Exit; */")
    _write(tmp_path / "extra.geo", 'Printf(\'h = %g; Save "x"\', h);')
    geo = _write(tmp_path / "part.geo", 'Include "sizes.geo";\nMerge "extra.geo";\n'
                 + SQUARE.replace("0.5}", "h}") + 'title = "SystemCall \'ls\'; Exit;";\n'
                 "Mesh.Algorithm = 6; Geometry.Tolerance = 1e-9; General.Terminal = 0;\n"
                 "SystemCallX = 1; MySave = 2; // words that only contain a command\n")
    assert mesh_files(geo) == [geo, tmp_path / "sizes.geo", tmp_path / "extra.geo"]
    m = load_mesh_file(MPI.COMM_SELF, geo, 2)
    assert m.groups == {"bottom": 1}


def test_tokens_follow_gmsh_scanner():
    toks = tokens('a=1.5e-3;// c\n/* x\ny */ s = \'q"q\'; b = .5; Exit1;', "f")
    assert [(t.kind, t.text, t.line) for t in toks] == [
        ("word", "a", 1), ("op", "=", 1), ("number", "1.5e-3", 1), ("op", ";", 1),
        ("word", "s", 3), ("op", "=", 3), ("string", 'q"q', 3), ("op", ";", 3),
        ("word", "b", 3), ("op", "=", 3), ("number", ".5", 3), ("op", ";", 3),
        ("word", "Exit1", 3), ("op", ";", 3)]


def _case(tmp_path, geo_name="part.geo"):
    from vpcontact.case import load_case
    path = tmp_path / "case.yaml"
    path.write_text(f"mesh: {{file: {geo_name}, dim: 2}}\n"
                    "material: {E: 1000.0, nu: 0.3, plane: strain}\n"
                    "boundaries: {clamped: [bottom]}\nloads: {}\ntime: {T: 1.0, N: 2}\n")
    return load_case(path)


def test_a_change_in_an_included_file_changes_the_fingerprint(tmp_path):
    from vpcontact.io.checkpoint import case_fingerprint
    _write(tmp_path / "sizes.geo", "h = 0.5;")
    _write(tmp_path / "part.geo", 'Include "sizes.geo";\n' + SQUARE.replace("0.5}", "h}"))
    case = _case(tmp_path)
    before = case_fingerprint(case)
    assert case_fingerprint(case) == before
    _write(tmp_path / "sizes.geo", "h = 0.25;")
    assert case_fingerprint(case) != before
    # a single .msh keeps the digest checkpoints already hold
    _save_msh(tmp_path / "part.geo", tmp_path / "part.msh")
    import hashlib

    from vpcontact.io.canonical import stable_json
    msh_case = _case(tmp_path, "part.msh")
    raw = msh_case.raw
    data = {k: raw.get(k) for k in ("mesh", "material", "contact", "loads", "initial",
                                    "boundaries")}
    data.update(times=list(msh_case.time.times), scheme=msh_case.time.scheme,
                adaptive=msh_case.time.adaptive,
                mesh_file=hashlib.sha256((tmp_path / "part.msh").read_bytes()).hexdigest())
    assert case_fingerprint(msh_case) == hashlib.sha256(stable_json(data).encode()).hexdigest()
