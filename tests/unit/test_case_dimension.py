"""mesh.dim of a mesh.file is taken from the file (meshes/fileinfo.py): a tetrahedral mesh
without mesh.dim is 3D (it was refused, its loads blamed for 2 components); a mesh.dim that
contradicts the file is refused naming both; the built-in mesh keeps the default 2; gmsh is
not imported by validation."""
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from conftest import ROOT, validate_raw
from vpcontact.case import CaseError
from vpcontact.meshes.fileinfo import FileInfoError, file_dimension

SQUARE_GEO = """Point(1) = {0, 0, 0, 0.5}; Point(2) = {1, 0, 0, 0.5};
Point(3) = {1, 1, 0, 0.5}; Point(4) = {0, 1, 0, 0.5};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Curve("bottom") = {1}; Physical Curve("top") = {3}; Physical Curve("left") = {4};
Physical Surface("body") = {1};
"""
# the unit cube by extrusion: its groups named as the built-in box's sides it uses
CUBE_GEO = SQUARE_GEO.replace('Physical Curve("bottom") = {1}; Physical Curve("top") = {3}; '
                              'Physical Curve("left") = {4};\nPhysical Surface("body") = {1};',
                              'out[] = Extrude {0, 0, 1} { Surface{1}; };\n'
                              'Physical Surface("bottom") = {1}; '
                              'Physical Surface("top") = {out[0]};\n'
                              'Physical Surface("left") = {out[5]};\n'
                              'Physical Volume("body") = {out[1]};')
CURVE_GEO = "Point(1) = {0, 0, 0, 0.5}; Point(2) = {1, 0, 0, 0.5}; Line(1) = {1, 2};\n"


def _msh(tmp_path, geo: str, dim: int, version: float, binary: bool):
    import gmsh
    name = f"{'cube' if dim == 3 else 'square'}_{version}_{int(binary)}"
    src = tmp_path / f"{name}.geo"
    src.write_text(geo)
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.open(str(src))
        gmsh.model.mesh.generate(dim)
        gmsh.option.setNumber("Mesh.MshFileVersion", version)
        gmsh.option.setNumber("Mesh.Binary", int(binary))
        gmsh.write(str(tmp_path / f"{name}.msh"))
    finally:
        gmsh.finalize()
    return tmp_path / f"{name}.msh"


def _geo(tmp_path, text: str, name: str):
    path = tmp_path / name
    path.write_text(text)
    return path


def _raw(path, top=(0.0, -1.0, 0.0), **mesh) -> dict:
    d = len(top)
    return {"mesh": {"file": str(path), **mesh},
            "boundaries": {"clamped": ["left"], "contact": ["bottom"]},
            "material": {"E": 1000.0, "nu": 0.3},
            "loads": {"traction": {"top": list(top)}},
            "contact": {"g": 0.01}, "time": {"T": 1.0, "N": 2},
            "initial": {"u0": [0.0] * d}}


@pytest.mark.parametrize("version, binary", [(4.1, False), (4.1, True), (2.2, False),
                                             (2.2, True)],
                         ids=["4.1-ascii", "4.1-binary", "2.2-ascii", "2.2-binary"])
def test_a_tetrahedral_msh_without_mesh_dim_is_3d(tmp_path, version, binary):
    path = _msh(tmp_path, CUBE_GEO, 3, version, binary)
    # format 4 is read without gmsh (format 2 needs gmsh: then the answer is kept)
    assert file_dimension(path, cheap=True) == (3 if version == 4.1 else None)
    case = validate_raw(_raw(path))
    assert case.mesh.dim == 3 and case.raw["mesh"]["dim"] == 3
    assert validate_raw(case.raw).mesh.dim == 3           # the studies validate case.raw


@pytest.mark.parametrize("version, binary", [(4.1, False), (4.1, True), (2.2, True)],
                         ids=["4.1-ascii", "4.1-binary", "2.2-binary"])
def test_a_triangle_msh_without_mesh_dim_is_2d(tmp_path, version, binary):
    path = _msh(tmp_path, SQUARE_GEO, 2, version, binary)
    assert validate_raw(_raw(path, top=(0.0, -1.0))).mesh.dim == 2


@pytest.mark.parametrize("geo, dim", [(SQUARE_GEO, 2), (CUBE_GEO, 3)], ids=["2d", "3d"])
def test_a_geo_without_mesh_dim(tmp_path, geo, dim):
    path = _geo(tmp_path, geo, "body.geo")
    case = validate_raw(_raw(path, top=(0.0, -1.0, 0.0)[:dim]))
    assert case.mesh.dim == dim


@pytest.mark.parametrize("kind", ["msh", "geo"])
def test_a_mesh_dim_that_contradicts_the_file_is_refused(tmp_path, kind):
    """A tetrahedral file with mesh.dim: 2 and 3-component loads: mesh.dim is blamed, not
    the loads, and the message names both dimensions; the other way round too."""
    cube = _msh(tmp_path, CUBE_GEO, 3, 4.1, False) if kind == "msh" else \
        _geo(tmp_path, CUBE_GEO, "cube.geo")
    with pytest.raises(CaseError) as err:
        validate_raw(_raw(cube, dim=2))
    assert str(err.value).startswith(f"test-case: mesh.dim: 2 contradicts mesh.file "
                                     f"{cube.name}, which is 3D"), err.value
    square = _msh(tmp_path, SQUARE_GEO, 2, 4.1, True) if kind == "msh" else \
        _geo(tmp_path, SQUARE_GEO, "square.geo")
    with pytest.raises(CaseError) as err:
        validate_raw(_raw(square, top=(0.0, -1.0), dim=3))
    assert f"mesh.dim: 3 contradicts mesh.file {square.name}, which is 2D" in str(err.value)


def test_a_msh_4_contradicting_mesh_dim_is_refused_before_its_vectors_are_read(tmp_path):
    """A .msh 4 tells its dimension at once: refused even when the vectors agree with
    mesh.dim."""
    cube = _msh(tmp_path, CUBE_GEO, 3, 4.1, True)
    with pytest.raises(CaseError, match="mesh.dim: 2 contradicts mesh.file"):
        validate_raw(_raw(cube, top=(0.0, -1.0), dim=2))


def test_a_matching_mesh_dim_and_the_built_in_default(tmp_path):
    cube = _msh(tmp_path, CUBE_GEO, 3, 4.1, False)
    assert validate_raw(_raw(cube, dim=3)).mesh.dim == 3
    raw = _raw("x", top=(0.0, -1.0))
    raw["mesh"] = {"n": 2}
    raw.pop("boundaries")
    assert validate_raw(raw).mesh.dim == 2


def test_a_file_of_curves_only_is_refused(tmp_path):
    path = _geo(tmp_path, CURVE_GEO, "line.geo")
    with pytest.raises(CaseError) as err:
        validate_raw(_raw(path, top=(0.0, -1.0)))
    assert "mesh.file: " in str(err.value) and "holds no surface or volume" in str(err.value)
    with pytest.raises(FileInfoError):
        file_dimension(path)


def test_a_geo_that_runs_a_command_is_refused_before_gmsh_opens_it(tmp_path):
    marker = tmp_path / "ran"
    path = _geo(tmp_path, SQUARE_GEO + f'SystemCall "touch {marker}";\n', "bad.geo")
    with pytest.raises(CaseError, match="mesh.file: "):
        validate_raw(_raw(path, top=(0.0, -1.0)))
    assert not marker.exists()


VALIDATE = """
import json, sys
from vpcontact.case import validate
case = validate(json.loads(sys.argv[1]), "test-case")
print(json.dumps([case.mesh.dim, "gmsh" in sys.modules]))
"""


@pytest.mark.parametrize("kind", ["msh", "geo", "builtin"])
def test_validation_does_not_import_gmsh(tmp_path, kind):
    if kind == "builtin":
        raw = _raw("x", top=(0.0, -1.0))
        raw["mesh"] = {"n": 2}
        raw.pop("boundaries")
    else:
        path = _msh(tmp_path, CUBE_GEO, 3, 4.1, True) if kind == "msh" else \
            _geo(tmp_path, CUBE_GEO, "cube.geo")
        raw = _raw(path)
    proc = subprocess.run([sys.executable, "-c", VALIDATE, json.dumps(raw)], cwd=ROOT,
                          capture_output=True, text=True, timeout=120,
                          env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
    assert proc.returncode == 0, proc.stderr
    dim, imported = json.loads(proc.stdout.strip().splitlines()[-1])
    assert dim == (2 if kind == "builtin" else 3) and not imported


def _processes_reading(path) -> list[int]:
    """The processes whose command line names ``path``."""
    found = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/cmdline", "rb") as f:
                    if str(path).encode() in f.read():
                        found.append(int(entry))
            except OSError:
                pass
    return found


def test_sigint_while_gmsh_reads_a_slow_geo_exits_3(tmp_path):
    """A .geo whose script runs long (while its dimension is read, in gmsh's child): SIGINT
    ends the command at once with exit 3 and the child is gone."""
    geo = _geo(tmp_path, SQUARE_GEO + "For i In {1:1000000000}\n  x = i;\nEndFor\n", "slow.geo")
    case = tmp_path / "case.yaml"
    case.write_text(json.dumps(_raw(geo, top=(0.0, -1.0))))
    proc = subprocess.Popen([sys.executable, "-m", "vpcontact", "check", str(case)], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        deadline = time.monotonic() + 60
        while not [p for p in _processes_reading(geo) if p != proc.pid]:
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
            time.sleep(0.1)
        time.sleep(0.5)
        start = time.monotonic()
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 3 and time.monotonic() - start < 10, err
        assert "Traceback" not in err
    finally:
        if proc.poll() is None:
            proc.kill()
    time.sleep(0.5)
    assert _processes_reading(geo) == []
