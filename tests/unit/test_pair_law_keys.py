"""A bad law given inside a contact pair is reported under the key and line where the case
file gives it (``contact.pairs[i].<law>...``), also when the laws are the same in every pair
and validation settles them into the contact section (app/case/pairrules.py settle_laws)."""
import pytest

from conftest import ROOT
from vpcontact.case import load_raw, validate
from vpcontact.io.errors import CaseError

HEAD = f"""name: pairlaw
mesh: {{file: {ROOT / 'tests' / 'data' / 'patch2d.geo'}, dim: 2}}
materials:
  lower: {{E: 1000.0, nu: 0.3, plane: strain}}
  upper: {{E: 1000.0, nu: 0.3, plane: strain}}
boundaries: {{clamped: [lower_bottom]}}
contact:
"""
TAIL = """loads:
  displacement: {upper_left: [0.0, null], lower_left: [0.0, null], upper_top: [null, -0.01]}
time: {T: 1.0, N: 2}
"""
PAIR = """  pairs:
    - surface: lower_top
      target: upper_bottom
"""                                          # the pair's own keys start on line 11


def _message(tmp_path, contact: str, overrides=()) -> str:
    path = tmp_path / "case.yaml"
    path.write_text(HEAD + contact + TAIL)
    with pytest.raises(CaseError) as info:
        validate(load_raw(path, list(overrides)), str(path))
    return str(info.value)


@pytest.mark.parametrize("law, key", [
    ("friction: {coulomb: {mu: -0.3}}", "contact.pairs[0].friction.coulomb.mu (line 11): "
                                        "must be >= 0"),
    ("normal_compliance: {table: [[0, 0], [1, -1]]}",
     "contact.pairs[0].normal_compliance.table (line 11): "),
    ("memory: {b0: 1.0, kernel: table, table: [[1, 1], [0, 1]]}",
     "contact.pairs[0].memory.table (line 11): times must start at 0"),
    ("memory: {b0: 1.0, kernel: power}", "contact.pairs[0].memory.alpha (line 11): required"),
    ("friction: {b: 0.1, c1: 1.0, c2: 1.0, u1: 1.0}",
     "contact.pairs[0].friction (line 11): b - c1 u1 must be >= 0"),
])
def test_a_single_pairs_law_is_named_where_it_is_written(law, key, tmp_path):
    message = _message(tmp_path, PAIR + f"      {law}\n")
    assert key in message, message
    for moved in ("contact.friction", "contact.memory", "contact.normal_compliance"):
        assert moved not in message, message


def test_the_same_law_in_two_pairs_is_named_in_the_first(tmp_path):
    two = ("  pairs:\n"
           "    - {surface: lower_top, target: upper_bottom, friction: {coulomb: {mu: -1}}}\n"
           "    - {surface: lower_right, target: upper_bottom, friction: {coulomb: {mu: -1}}}\n")
    message = _message(tmp_path, two)
    assert "contact.pairs[0].friction.coulomb.mu (line 9): must be >= 0" in message, message


def test_a_law_of_the_contact_section_keeps_its_key(tmp_path):
    message = _message(tmp_path, "  friction: {coulomb: {mu: -0.3}}\n" + PAIR)
    assert "contact.friction.coulomb.mu (line 8): must be >= 0" in message, message


def test_a_pairs_law_given_by_set_names_the_set(tmp_path):
    message = _message(tmp_path, PAIR + "      friction: {coulomb: {mu: 0.3}}\n",
                       ["contact.pairs[0].friction.coulomb.mu=-2"])
    assert ("contact.pairs[0].friction.coulomb.mu: must be >= 0 (a friction coefficient), "
            "got -2 (the value of --set contact.pairs[0].friction.coulomb.mu=-2)") in message


def test_a_pairs_law_checked_on_the_mesh_is_named_where_it_is_written(tmp_path, capsys):
    """b0 < 0 on Gamma3 is found on the loaded mesh's points (app/model/datapoints.py), after
    validation: the message names the pair's key too."""
    from conftest import cli_in_process
    path = tmp_path / "case.yaml"
    path.write_text(HEAD + PAIR + '      memory: {b0: "x - 10", beta: 1.0}\n'
                    "      normal_compliance: {c_nu: 100.0}\n" + TAIL)
    assert cli_in_process(["check", path]) == 2
    err = capsys.readouterr().err
    assert "contact.pairs[0].memory.b0: must be >= 0 on Gamma3" in err, err
