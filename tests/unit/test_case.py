"""Case files: schema validation with clear messages, overrides, YAML floats, PETSc args;
the keys of general scenes (mesh.file, boundaries, loads per group, gap expressions,
approach direction, plane strain)."""
import dataclasses
import re

import pytest

from conftest import PAPER_CASE, ROOT, make_case, paper_raw
from vpcontact.case import CaseError, load_case, validate
from vpcontact.case.reading import parse_override, safe_load
from vpcontact.cli.parser import split_petsc_args


def test_paper_case_values():
    case = load_case(PAPER_CASE)
    assert case.name == "wang_cheng_2021"
    assert (case.mesh.n, case.mesh.diagonal, case.time.N, case.time.T) == (16, "right", 16, 1.0)
    assert (case.material.E, case.material.nu) == (1000.0, 0.4)
    assert case.material.viscoplastic.lambda1 == 100.0
    assert (case.contact.g, case.contact.c_nu) == (0.012, 100.0)
    assert case.contact.friction.b == 1.0 and case.contact.friction.u1 == 0.01
    assert case.loads.traction == {"top": (0.0, -8.0), "right": (-3.2, 0.0)}
    assert case.petsc["snes_type"] == "vinewtonrsls"


def test_overrides_and_yaml_floats():
    case = load_case(PAPER_CASE, ["mesh.n=32", "time.N=8", "solver.delta=1e-9",
                                  "petsc.snes_rtol=1e-12"])
    assert case.mesh.n == 32 and case.time.N == 8
    assert case.numerics.delta == 1e-9 and case.petsc["snes_rtol"] == 1e-12
    assert safe_load("x: 1e-4")["x"] == 1e-4
    assert parse_override("loads.traction.top=[0, -4]") == ("loads.traction.top", [0, -4])


def test_overrides_of_list_entries(tmp_path):
    """--set name[i]: an entry of a list (a contact pair's laws), existing entries only."""
    from vpcontact.case import load_raw
    path = tmp_path / "pairs.yaml"
    path.write_text("contact:\n  pairs:\n    - {surface: a, target: b}\n"
                    "    - {surface: c, target: d, g: 0.5}\n")
    raw = load_raw(path, ["contact.pairs[1].g=0.01", "contact.pairs[0].friction.coulomb.mu=0.3",
                          "contact.pairs[1]={surface: e, target: f}"])
    assert raw["contact"]["pairs"] == [
        {"surface": "a", "target": "b", "friction": {"coulomb": {"mu": 0.3}}},
        {"surface": "e", "target": "f"}]
    for item, words in (("contact.pairs[2].g=1", "'pairs' has 2 entries (allowed: pairs[0] "
                                                 "to pairs[1])"),
                        ("contact[0].g=1", "'contact' is not a list"),
                        ("contact.pairs[0].surface.x=1", "'surface' is not a section")):
        with pytest.raises(CaseError, match=re.escape(f"--set {item.split('=')[0]}: {words}")):
            load_raw(path, [item])


def test_unknown_key_is_named_with_suggestion():
    raw = paper_raw()
    raw["material"]["lamda1"] = 3.0
    with pytest.raises(CaseError, match=r"material\.lamda1( \(line \d+\))?: unknown "
                                        r"key.*allowed: E, elasticity, nu"):
        validate(raw, "my.yaml")
    raw = paper_raw()
    raw["contact"]["friction"]["u_1"] = 3.0
    with pytest.raises(CaseError, match=r"(?s)my\.yaml.*contact\.friction\.u_1.*did you mean 'u1'"):
        validate(raw, "my.yaml")


@pytest.mark.parametrize("section,key,value,pattern", [
    ("material", "E", -1.0, r"material\.E"),
    ("material", "nu", 0.5, r"material\.nu"),
    ("contact", "g", -0.01, r"contact\.g"),
    ("time", "N", 0, r"time\.N"),
    ("time", "T", "one", r"time\.T"),
    ("mesh", "diagonal", "up", r"mesh\.diagonal.*allowed: right, left"),
    ("solver", "quadrature", "simpson", r"solver\.quadrature.*vertex, gauss"),
])
def test_bad_values_are_named(section, key, value, pattern):
    raw = paper_raw()
    raw.setdefault(section, {})[key] = value
    with pytest.raises(CaseError, match=pattern):
        validate(raw, "bad.yaml")


def test_incompatible_combinations():
    with pytest.raises(CaseError, match=r"loads\.traction\.bottom"):
        make_case(loads={"traction": {"bottom": [0.0, 1.0]}})
    with pytest.raises(CaseError, match=r"b - c1 u1"):
        make_case(contact={"friction": {"b": 0.1, "c1": 60.0, "c2": 60.0, "u1": 0.01}})
    with pytest.raises(CaseError, match=r"mesh\.h"):
        make_case(mesh={"kind": "unstructured"})


@pytest.mark.parametrize("given", ["condensed", "fast"])
def test_the_condensed_solver_under_its_name_and_its_former_one(given):
    case = make_case(solver={"method": given})
    assert case.numerics.method == "condensed"
    assert case.raw["solver"]["method"] == given          # the case as written
    implicit = {"T": 1.0, "N": 4, "scheme": "implicit"}
    with pytest.raises(CaseError, match=rf"^test-case: solver\.method \(line 38\): '{given}' "
                                        r"is not possible here: the implicit history variant"):
        make_case(solver={"method": given}, time=implicit)
    assert make_case(solver={"method": "auto"}, time=implicit).numerics.method == "auto"


def test_not_a_mapping(tmp_path):
    p = tmp_path / "x.yaml"
    p.write_text("- just\n- a list\n")
    with pytest.raises(CaseError, match=r"x\.yaml.*mapping"):
        load_case(p)
    p.write_text("mesh: [unclosed\n")
    with pytest.raises(CaseError, match=r"x\.yaml: not valid YAML"):
        load_case(p)


def test_terms_follow_the_case():
    assert "nonmonotone friction (4.2)" in make_case().active_terms()
    raw = paper_raw()
    del raw["contact"]["friction"]
    frictionless = validate(raw)
    assert frictionless.contact.friction is None
    assert not any("friction" in t for t in frictionless.active_terms())
    elastic_raw = paper_raw()
    del elastic_raw["material"]["viscoplastic"]
    assert validate(elastic_raw).material.viscoplastic is None


def test_split_petsc_args():
    ours, petsc = split_petsc_args(["run", "c.yaml", "-snes_monitor", "--set", "mesh.n=4",
                                    "-snes_rtol", "1e-12", "-ksp_type", "preonly",
                                    "-snes_linesearch_damping", "-0.5", "--out", "d"])
    assert ours == ["run", "c.yaml", "--set", "mesh.n=4", "--out", "d"]
    assert petsc == {"snes_monitor": None, "snes_rtol": "1e-12", "ksp_type": "preonly",
                     "snes_linesearch_damping": "-0.5"}


# ----------------------------------------------------------------------------- general scenes
PLATE_GEO = (ROOT / "tests" / "cases_invalid" / "plate.geo").read_text()


def _case_file(tmp_path, text: str, mesh: str | None = "plate.geo"):
    """A case file in tmp_path (with a mesh file of that name: a .geo of the unit square,
    whose dimension validation reads; a .msh that only exists) and its Case."""
    if mesh:
        (tmp_path / mesh).write_text(PLATE_GEO if mesh.endswith(".geo") else
                                     "// a mesh file; validation only checks that it exists\n")
    path = tmp_path / "scene.yaml"
    path.write_text(text)
    return load_case(path)


SCENE = """
mesh: {file: plate.geo}
boundaries: {clamped: [wall], contact: [base]}
material: {E: 1000.0, nu: 0.3, plane: strain}
contact: {g: "0.01 + 0.1*x**2", direction: [0, -2]}
loads:
  traction: {lid: [0, -1.0], 7: [0.5, 0]}
  pressure: {side: "2*t", 3: {table: [[0, 0], [1, 4.0]]}}
  displacement: {5: [null, "-0.015*t"], sym: [0, null]}
time: {T: 1.0, N: 4}
"""


def test_shipped_cases_keep_their_scene():
    """The paper's cases: the built-in mesh with the default boundaries; the new keys at
    their defaults; case.raw validates to the same Case (the studies re-validate it)."""
    from vpcontact.case.model import Boundaries
    for name in ("wang_cheng_2021", "memory", "slip_weakening", "box3d"):
        case = load_case(PAPER_CASE.parent / f"{name}.yaml")
        assert (case.mesh.file, case.mesh.size, case.mesh.engine) == (None, 1.0, "gmsh")
        assert case.mesh.builtin and case.mesh.kind == "structured"
        assert case.boundaries == Boundaries(("left",), ("bottom",))
        assert case.material.plane == ("stress" if case.dim == 2 else None)
        assert case.contact.direction is None and isinstance(case.contact.g, float)
        assert case.loads.pressure == {} and case.loads.displacement == {}
        assert validate(case.raw, case.source) == case
    paper = load_case(PAPER_CASE)
    assert paper.active_terms()[0] == "plane-stress elasticity"
    assert (paper.petsc["snes_atol"], paper.petsc["snes_vi_zero_tolerance"]) == (1e-11, 1e-8)


def test_a_gmsh_scene(tmp_path):
    case = _case_file(tmp_path, SCENE)
    assert case.mesh.file == str(tmp_path / "plate.geo") and case.mesh.kind == "file"
    assert (case.mesh.L1, case.mesh.n, case.mesh.size, case.mesh.builtin) == (None, None, 1.0,
                                                                           False)
    assert case.boundaries.clamped == ("wall",) and case.boundaries.contact == ("base",)
    assert case.material.plane == "strain" and "plane-strain elasticity" in case.active_terms()
    assert case.contact.g == "0.01 + 0.1*x**2" and case.contact.direction == (0.0, -1.0)
    # YAML's integer keys are physical tags, kept as integers
    assert case.loads.traction == {"lid": (0, -1.0), 7: (0.5, 0)}
    assert case.loads.pressure == {"side": "2*t", 3: {"table": [[0, 0], [1, 4.0]]}}
    assert case.loads.displacement == {5: (None, "-0.015*t"), "sym": (0, None)}
    # the stress scale: E |u_D| / L with L = 1 until the mesh is loaded
    assert case.data_stress == pytest.approx(1000.0 * 0.015)
    assert validate(case.raw, "elsewhere/scene.yaml") == dataclasses.replace(
        case, source="elsewhere/scene.yaml")     # mesh.file is absolute in case.raw
    size = _case_file(tmp_path, SCENE.replace("{file: plate.geo}",
                                              "{file: plate.geo, size: 0.5, dim: 2}"))
    assert size.mesh.size == 0.5


def test_a_mesh_file_without_boundaries(tmp_path):
    text = "mesh: {file: m.msh, dim: 3}\nmaterial: {E: 1, nu: 0.3}\nloads: {}\n" \
           "time: {T: 1, N: 1}\n"
    case = _case_file(tmp_path, text, "m.msh")
    assert case.boundaries.clamped == () and case.boundaries.contact == ()
    assert case.material.plane is None and case.dim == 3
    with pytest.raises(CaseError, match=r"boundaries\.contact: required with mesh\.file"):
        _case_file(tmp_path, text + "contact: {g: 0.1}\n", "m.msh")


@pytest.mark.parametrize("mesh,pattern", [
    ("{file: plate.geo, n: 8}", r"mesh\.n( \(line \d+\))?: not used with mesh\.file"),
    ("{file: plate.geo, L1: 2.0}", r"mesh\.L1( \(line \d+\))?: not used with mesh\.file"),
    ("{file: plate.geo, engine: dolfinx}", r"mesh\.engine( \(line \d+\))?: not used"),
    ("{file: plate.msh, size: 0.5}", r"mesh\.size( \(line \d+\))?: only with a \.geo"),
    ("{n: 4, size: 0.5}", r"mesh\.size( \(line \d+\))?: only with a \.geo"),
    ("{file: plate.stl}", r"mesh\.file( \(line \d+\))?: 'plate\.stl' is not a gmsh mesh"),
    ("{file: other.msh}", r"mesh\.file( \(line \d+\))?: 'other\.msh': no such file "
                          r"\(looked for .*other\.msh"),
    ("{file: sub.msh}", r"mesh\.file( \(line \d+\))?: 'sub\.msh': not a readable regular"),
])
def test_mesh_file_keys_are_checked(tmp_path, mesh, pattern):
    (tmp_path / "plate.msh").write_text("")
    (tmp_path / "sub.msh").mkdir()
    with pytest.raises(CaseError, match=pattern):
        _case_file(tmp_path, SCENE.replace("{file: plate.geo}", mesh))


@pytest.mark.parametrize("sections,pattern", [
    ({"boundaries": {"clamped": ["west"]}},
     r"boundaries\.clamped\[0\]: no such side in 2D \('west'\) \(allowed: left, bottom"),
    ({"boundaries": {"clamped": [3]}}, r"boundaries\.clamped\[0\]: the physical tag 3 is for"),
    ({"boundaries": {"clamped": ["left", "left"]}}, r"boundaries\.clamped\[1\]: 'left' is "
                                                    r"listed twice"),
    ({"boundaries": {"clamped": ["left", "bottom"]}},
     r"boundaries\.contact: the bottom side is also in boundaries\.clamped"),
    ({"boundaries": {"contact": []}}, r"boundaries\.contact: empty in a case with a contact"),
    ({"boundaries": {"clamped": [-1]}}, r"boundaries\.clamped\.0: -1 is less than the min"),
    ({"loads": {"traction": {"left": [0, 1]}}},
     r"loads\.traction\.left: the left side is clamped"),
    ({"loads": {"pressure": {"left": 1.0}}}, r"loads\.pressure\.left: the left side is clamp"),
    ({"loads": {"displacement": {"left": [0, None]}}},
     r"loads\.displacement\.left: the left side is clamped"),
    ({"loads": {"pressure": {"bottom": 1.0}}},
     r"loads\.pressure\.bottom: the bottom side is Gamma3 \(contact\)"),
    ({"loads": {"displacement": {"bottom": [0, None]}}},
     r"loads\.displacement\.bottom: the bottom side is Gamma3"),
    ({"loads": {"traction": {"top": [0, 1]}}, "boundaries": {"contact": ["top"]}},
     r"loads\.traction\.top: the top side is Gamma3"),
    ({"loads": {"pressure": {3: 1.0}}}, r"loads\.pressure\.3: the physical tag 3 is for a "
                                        r"mesh\.file"),
    ({"loads": {"pressure": {"front": 1.0}}}, r"loads\.pressure\.front: no such side in 2D"),
    ({"loads": {"pressure": {"top": "p*t"}}}, r"loads\.pressure\.top: unknown name 'p'"),
    ({"loads": {"pressure": {"top": [1.0]}}}, r"loads\.pressure\.top: \[1\.0\] is not valid"),
    ({"loads": {"displacement": {"top": [None, None]}}},
     r"loads\.displacement\.top: every component is null"),
    ({"loads": {"displacement": {"top": [0.0]}}}, r"loads\.displacement\.top: \[0\.0\] is too "
                                                  r"short"),
    ({"loads": {"displacement": {"top": [0.0, "sin(q)"]}}},
     r"loads\.displacement\.top\[1\]: unknown name 'q'"),
    ({"loads": {"displacement": {"top": [0.0, "1/(t - 0.5)"]}}, "time": {"T": 1.0, "N": 2}},
     r"loads\.displacement\.top\[1\]: inf is not a finite number at x = 0, y = 1, t = 0\.5"),
    ({"loads": {"traction": {-2: [0, 1]}}}, r"loads\.traction: the key -2 is not a group"),
    ({"loads": {"traction": {2.5: [0, 1]}}}, r"loads\.traction: the key 2\.5 is not a group"),
    ({"loads": {"traction": {True: [0, 1]}}}, r"loads\.traction: the key True is not a group"),
    ({"loads": {"pressure": {3: 1.0, "3": 2.0}}}, r"loads\.pressure\.3: given twice"),
    ({"contact": {"g": "0.01*t"}}, r"contact\.g: the initial gap does not depend on time"),
    ({"contact": {"g": "0.01 + z"}}, r"contact\.g: unknown name 'z' \(allowed: x, y, e, pi\)"),
    ({"contact": {"g": "x - 0.5"}}, r"contact\.g: must be >= 0 on Gamma3 .*got -0\.5 at x = 0"),
    ({"contact": {"g": "sqrt(x - 0.5)"}}, r"contact\.g: nan is not a finite number"),
    ({"contact": {"g": -1e-3}}, r"contact\.g: -0\.001 is less than the minimum of 0"),
    ({"contact": {"direction": [0.0, 0.0]}}, r"contact\.direction: the zero vector"),
    ({"contact": {"direction": [0.0, 0.0, -1.0]}}, r"contact\.direction: expected 2 comp"),
    ({"contact": {"direction": ["down", 1]}}, r"contact\.direction\.0: 'down' is not of type"),
    ({"material": {"E": 1.0, "nu": 0.3, "plane": "shell"}},
     r"material\.plane: 'shell' is not allowed \(allowed: stress, strain\)"),
    ({"mesh": {"dim": 3, "n": 2}, "material": {"E": 1.0, "nu": 0.3, "plane": "stress"}},
     r"material\.plane: not used in 3D"),
    ({"mesh": {"engine": "meshio"}}, r"mesh\.engine: 'meshio' is not allowed \(allowed: gmsh, "
                                     r"dolfinx\)"),
])
def test_scene_rules_name_the_key(sections, pattern):
    """Each rule of the scene keys: refused in one line naming the key."""
    with pytest.raises(CaseError) as info:
        make_case(**sections)
    msg = re.sub(r" \(line \d+\)", "", str(info.value))
    assert "\n" not in msg and re.search(pattern, msg), msg


@pytest.mark.parametrize("sections,check", [
    ({"boundaries": {"clamped": [], "contact": ["bottom"]}},
     lambda c: c.boundaries.clamped == ()),
    ({"boundaries": {"clamped": ["left", "right"]}, "loads": {"traction": {"top": [0, -8]}}},
     lambda c: c.boundaries.clamped == ("left", "right")),
    ({"contact": {"g": 0.0}}, lambda c: c.contact.g == 0.0),
    ({"contact": {"g": "0.012 + 0.01*x"}}, lambda c: c.contact.g == "0.012 + 0.01*x"),
    ({"contact": {"direction": [3.0, -4.0]}}, lambda c: c.contact.direction == (0.6, -0.8)),
    ({"material": {"E": 1000.0, "nu": 0.4, "plane": "strain"}},
     lambda c: c.material.plane == "strain"),
    ({"loads": {"pressure": {"top": "8*t"}, "displacement": {"right": [None, 0.0]}}},
     lambda c: c.loads.pressure == {"top": "8*t"} and
     c.loads.displacement == {"right": (None, 0.0)}),
    ({"loads": {"traction": {"bottom": [0, 1]}}, "contact": None},    # no contact section
     lambda c: c.loads.traction == {"bottom": (0, 1)} and not c.contact.active),
    ({"loads": {"traction": {"left": [0, 1]}}, "boundaries": {"clamped": []}},
     lambda c: c.loads.traction == {"left": (0, 1)}),
    ({"mesh": {"engine": "dolfinx"}}, lambda c: c.mesh.engine == "dolfinx"),
])
def test_scene_keys_accepted(sections, check):
    assert check(make_case(**sections))


@pytest.mark.parametrize("sections,accepted", [
    # the built-in mesh with its default boundaries: u0 against Gamma1 = {x = 0} and g
    ({"initial": {"u0": [0, "-0.02*x"]}}, False),
    ({"initial": {"u0": [0, "-0.03*x"]}, "contact": {"g": "0.012 + 0.01*x"}}, False),
    ({"initial": {"u0": [0, "-0.02*x"]}, "contact": {"g": "0.012 + 0.01*x"}}, True),
    ({"initial": {"u0": [0, "-0.011*x"]}, "contact": {"g": 0.0}}, False),
    ({"initial": {"u0": ["0.01*x", "-0.01*x"]}, "contact": {"g": 0.012, "direction": [1, -1]}},
     False),
    ({"initial": {"u0": ["0.01*x", "-0.01*x"]}, "contact": {"g": 0.012, "direction": [-1, -1]}},
     True),
    # other boundaries: the geometric checks wait for the mesh's nodes
    ({"initial": {"u0": [0, "-0.02*x"]}, "boundaries": {"contact": ["top"]},
      "loads": {"traction": {"right": [-3.2, 0]}}}, True),
    ({"initial": {"u0": ["y", 0]}, "boundaries": {"clamped": ["right"]},
      "loads": {"traction": {"top": [0, -8]}}}, True),
])
def test_geometric_checks_of_u0_only_with_the_default_boundaries(sections, accepted):
    if accepted:
        make_case(**sections)
    else:
        with pytest.raises(CaseError, match=r"initial\.u0: violates u_nu <= g"):
            make_case(**sections)


def test_a_gmsh_scene_checks_what_does_not_need_the_mesh(tmp_path):
    def refused(old, new, pattern):
        with pytest.raises(CaseError) as info:
            _case_file(tmp_path, SCENE.replace(old, new))
        assert re.search(pattern, re.sub(r" \(line \d+\)", "", str(info.value))), info.value
    refused('g: "0.01 + 0.1*x**2"', 'g: "-0.01"', r"contact\.g: must be >= 0 on Gamma3")
    refused("[0, -1.0]", '[0, "1/(t - 0.5)"]', r"loads\.traction\.lid\[1\]: inf")
    refused('"-0.015*t"', '"-0.015*q"', r"loads\.displacement\.5\[1\]: unknown name 'q'")
    refused("[0, -2]", "[0, 0, -1]", r"contact\.direction: expected 2")
    # what depends on the position is checked on the mesh's nodes, not here
    case = _case_file(tmp_path, SCENE.replace("[0, -1.0]", '["1/x", 0]') +
                      'initial: {u0: ["y", 0]}\n')
    assert case.initial.u0 == ("y", 0)


def test_rescale_for_length(tmp_path):
    """For a mesh.file the PETSc defaults are scaled to the body's size once it is known; the
    options given in the case file or on the command line stay, checked against the new
    limits."""
    from vpcontact.case import rescale_for_length
    case = _case_file(tmp_path, SCENE)
    assert case.petsc["snes_vi_zero_tolerance"] == pytest.approx(1e-8)
    small = rescale_for_length(case, 1e-3)
    assert small.petsc["snes_vi_zero_tolerance"] == pytest.approx(1e-11)
    # E |u_D| / L: 15 N/m^2 for L = 1, 15000 for L = 1e-3; force scale stress L^(d-1)
    assert small.data_stress == pytest.approx(15000.0)
    assert small.petsc["snes_atol"] == pytest.approx(1e-11 * 15000.0 * 1e-3 / 8.0)
    assert small.petsc.limits["snes_atol"][0] == pytest.approx(1e-3 * 15.0)
    assert rescale_for_length(case, 1e-3, stress=800.0).petsc["snes_atol"] == \
        pytest.approx(1e-11 * 800.0 * 1e-3 / 8.0)
    again = rescale_for_length(small, 1.0)
    assert again.petsc == case.petsc and again.data_stress == case.data_stress
    given = _case_file(tmp_path, SCENE + "petsc: {snes_vi_zero_tolerance: 1.0e-7}\n")
    assert rescale_for_length(given, 10.0).petsc["snes_vi_zero_tolerance"] == 1e-7
    cli = dataclasses.replace(case, petsc={**case.petsc, "snes_atol": 1e-4})
    assert rescale_for_length(cli, 10.0).petsc["snes_atol"] == 1e-4
    with pytest.raises(CaseError, match=r"petsc\.snes_atol: 0\.0001 is too large: .* of "
                                        r"order 0\.001"):
        rescale_for_length(cli, 1e-3, stress=1.0)
    with pytest.raises(CaseError, match=r"mesh\.file: the body's size"):
        rescale_for_length(case, 0.0)
