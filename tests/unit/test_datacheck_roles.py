"""The groups' roles checked on the groups, not their spellings: a mesh file's group named
once by its name and once by its physical tag is one group (before, such a case escaped
validation's checks: a load on a clamped group was dropped, two tractions summed, the contact
group clamped ended in an internal error)."""
import pytest
import yaml
from mpi4py import MPI

from conftest import PAPER_CASE, make_case
from meshtools import write_rotated_square
from vpcontact.case import CaseError
from vpcontact.model.problem import ContactProblem
from vpcontact.simulation import build_mesh


@pytest.fixture(scope="module")
def square(tmp_path_factory):
    return write_rotated_square(tmp_path_factory.mktemp("roles") / "square.msh", 2, 0.0)


@pytest.fixture(scope="module")
def tag(square):
    body = build_mesh(make_case(_raw(square)), MPI.COMM_SELF)
    return body.groups


def _raw(square, **sections) -> dict:
    raw = yaml.safe_load(PAPER_CASE.read_text())
    raw["mesh"] = {"file": str(square)}
    raw["boundaries"] = {"clamped": ["left"], "contact": ["bottom"]}
    raw["time"]["N"] = 2
    raw.update(sections)
    return {k: v for k, v in raw.items() if v is not None}


def _refused(square, **sections) -> str:
    case = make_case(_raw(square, **sections))
    with pytest.raises(CaseError) as err:
        ContactProblem(case, build_mesh(case, MPI.COMM_SELF))
    return str(err.value)


def test_a_load_on_the_clamped_group_by_its_tag(square, tag):
    for kind, value in (("traction", [0.0, 1.0]), ("pressure", 1.0),
                        ("displacement", [0.0, None])):
        loads = {"traction": {"top": [0.0, -8.0]}, kind: {tag["left"]: value}}
        text = _refused(square, loads=loads)
        assert f"loads.{kind}.{tag['left']}: {tag['left']} is the clamped group 'left' " \
            f"(physical tag {tag['left']};" in text, text


def test_the_contact_group_clamped_by_its_tag(square, tag):
    text = _refused(square, boundaries={"clamped": ["left", tag["bottom"]],
                                        "contact": ["bottom"]})
    assert "boundaries.contact: 'bottom' is the clamped group" in text, text


def test_a_load_on_the_contact_group_by_its_tag(square, tag):
    text = _refused(square, loads={"traction": {"top": [0.0, -8.0]},
                                   "displacement": {tag["bottom"]: [0.0, 0.0]}})
    assert f"loads.displacement.{tag['bottom']}: {tag['bottom']} is the contact group " \
        "'bottom'" in text, text


@pytest.mark.parametrize("role", ["clamped", "contact", "traction", "displacement"])
def test_one_group_twice_in_a_role(square, tag, role):
    if role in ("clamped", "contact"):
        other = "contact" if role == "clamped" else "clamped"
        name = "left" if role == "clamped" else "bottom"
        sections = {"boundaries": {role: [name, tag[name]],
                                   other: ["bottom" if role == "clamped" else "left"]}}
        key = f"boundaries.{role}"
    else:
        value = [0.0, -1.0] if role == "traction" else [None, -0.001]
        sections = {"loads": {role: {"top": value, tag["top"]: value}}}
        name, key = "top", f"loads.{role}"
    text = _refused(square, **sections)
    assert f"{key}: '{name}' and {tag[name]} are the same group (physical tag " \
        f"{tag[name]})" in text, text


NUMBER_NAMED = """Point(1) = {0, 0, 0, 0.5}; Point(2) = {1, 0, 0, 0.5};
Point(3) = {1, 1, 0, 0.5}; Point(4) = {0, 1, 0, 0.5};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Curve("7", 1) = {3}; Physical Curve("left", 4) = {4};
Physical Surface("body", 10) = {1};
"""


@pytest.mark.parametrize("ref, hint", [
    (7, "; 7 unquoted is a physical number: write '7' for the group named so"),
    ("4", "; '4' quoted is a name: write 4 without quotes for the physical group of that "
          "number")], ids=["number-for-a-name", "name-for-a-number"])
def test_a_group_named_by_a_number_gets_a_hint(tmp_path, ref, hint):
    geo = tmp_path / "numbers.geo"
    geo.write_text(NUMBER_NAMED)
    text = _refused(geo, boundaries={"clamped": ["left"]}, contact=None,
                    loads={"traction": {ref: [0.0, -1.0]}})
    assert text.endswith(hint), text
