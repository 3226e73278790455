"""``--set materials.<group>.<key>=...`` changes a group the case has (by its name, or by its
physical tag when the case keys it by tag); a group the case does not have is refused in one
line naming the key and the groups there are, instead of a new group holding one key."""
import pytest

from vpcontact.case import load_raw
from vpcontact.io.errors import CaseError

BY_NAME = """name: groups
mesh: {file: plate.geo, dim: 2}
materials:
  lower: {E: 1000.0, nu: 0.3, plane: strain}
  upper: {E: 2000.0, nu: 0.3, plane: strain}
"""
BY_TAG = BY_NAME.replace("lower:", "10:").replace("upper:", "11:")


def _raw(tmp_path, text, *overrides):
    path = tmp_path / "case.yaml"
    path.write_text(text)
    return load_raw(path, list(overrides))


@pytest.mark.parametrize("setting", ["materials.10.E=5", "materials.middle.nu=0.2",
                                     "materials.10.viscoplastic.lambda1=3"])
def test_a_group_the_case_lacks_is_refused(setting, tmp_path):
    with pytest.raises(CaseError) as info:
        _raw(tmp_path, BY_NAME, setting)
    key = setting.split("=")[0]
    assert str(info.value).startswith(f"--set {key}: no material group "), info.value
    assert "(its groups: lower, upper)" in str(info.value)


def test_a_group_named_or_tagged_is_changed(tmp_path):
    raw = _raw(tmp_path, BY_NAME, "materials.upper.E=5")
    assert set(raw["materials"]) == {"lower", "upper"} and raw["materials"]["upper"]["E"] == 5
    raw = _raw(tmp_path, BY_TAG, "materials.10.E=5")
    assert set(raw["materials"]) == {10, 11} and raw["materials"][10]["E"] == 5


def test_without_a_materials_section_the_key_is_refused(tmp_path):
    text = "name: one\nmesh: {n: 4}\nmaterial: {E: 1000.0, nu: 0.3}\n"
    with pytest.raises(CaseError, match="no material group 'lower' in the case \\(its groups: "
                                        "none: no materials section\\)"):
        _raw(tmp_path, text, "materials.lower.E=5")


def test_a_whole_group_may_still_be_given(tmp_path):
    """A whole group by --set (all its keys) is read; validation checks it against the mesh."""
    raw = _raw(tmp_path, BY_NAME, "materials.extra={E: 5.0, nu: 0.3, plane: strain}")
    assert raw["materials"]["extra"] == {"E": 5.0, "nu": 0.3, "plane": "strain"}
