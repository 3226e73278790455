"""Case files: schema validation with clear messages, overrides, YAML floats, PETSc args."""
import pytest

from app.cli.parser import split_petsc_args
from app.io.case import CaseError, load_case, parse_override, safe_load, validate
from conftest import PAPER_CASE, make_case, paper_raw


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


def test_unknown_key_is_named_with_suggestion():
    raw = paper_raw()
    raw["material"]["lamda1"] = 3.0
    with pytest.raises(CaseError,
                       match=r"material\.lamda1( \(line \d+\))?: unknown key.*allowed: E, nu"):
        validate(raw, "my.yaml")
    raw = paper_raw()
    raw["contact"]["friction"]["u_1"] = 3.0
    with pytest.raises(CaseError, match=r"(?s)my\.yaml.*contact\.friction\.u_1.*did you mean 'u1'"):
        validate(raw, "my.yaml")


@pytest.mark.parametrize("section,key,value,pattern", [
    ("material", "E", -1.0, r"material\.E"),
    ("material", "nu", 0.5, r"material\.nu"),
    ("contact", "g", 0.0, r"contact\.g"),
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
