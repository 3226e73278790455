"""A restart accepts the same case spelled another way (app/io/casekey.py): a default
written out, an integer for a number, a group by its physical tag instead of its name; and
still refuses a real change (another modulus, contact rule, group or mesh).  Two blocks of
tests/data/patch2d.geo (facet groups 1-8, cell groups lower 10 and upper 11) in contact,
checkpointed after each of 2 steps; each restart continues from step 2's checkpoint
(nothing left to compute) or is refused (exit 2) before anything is computed."""
import pytest
import yaml

from conftest import ROOT, run_cli

ELASTIC = {"E": 1000.0, "nu": 0.3, "plane": "strain"}


def _case(**changes) -> dict:
    """The two blocks, the upper one pressed down, with some keys replaced ("a.b": value)."""
    raw = {"name": "spellings",
           "mesh": {"file": str(ROOT / "tests" / "data" / "patch2d.geo"), "dim": 2},
           "materials": {"lower": dict(ELASTIC), "upper": dict(ELASTIC)},
           "boundaries": {"clamped": ["lower_bottom"]},
           "contact": {"pairs": [{"surface": "lower_top", "target": "upper_bottom",
                                  "normal_compliance": {"c_nu": 1e5}}]},
           "loads": {"displacement": {"upper_left": [0.0, None], "lower_left": [0.0, None],
                                      "upper_top": [None, "-0.01 * t"]}},
           "time": {"T": 1.0, "N": 2}, "output": {"checkpoint_every": 1}}
    for path, value in changes.items():
        *parents, last = path.split(".")
        node = raw
        for key in parents:
            node = node[int(key)] if isinstance(node, list) else node[key]
        if value is None:
            node.pop(last)
        else:
            node[last] = value
    return raw


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """The checkpointed run of the case as first written."""
    tmp = tmp_path_factory.mktemp("spellings")
    case = tmp / "case.yaml"
    case.write_text(yaml.safe_dump(_case()))
    proc = run_cli(["run", case, "--out", tmp / "first", "--quiet"])
    assert proc.returncode == 0, proc.stderr
    return tmp / "first"


def _restart(written, tmp_path, raw: dict):
    geo = raw["mesh"]["file"]
    if geo.startswith("COPY:"):            # the mesh file copied here, edited by the text
        old, new = geo[5:].split("->")
        text = (ROOT / "tests" / "data" / "patch2d.geo").read_text()
        raw["mesh"]["file"] = str(tmp_path / "copy.geo")
        (tmp_path / "copy.geo").write_text(text.replace(old, new))
    case = tmp_path / "restart.yaml"
    case.write_text(yaml.safe_dump(raw))
    return run_cli(["run", case, "--out", tmp_path / "re", "--quiet", "--restart", written])


SAME = {
    "default rule written out": {"contact.pairs.0.rule": "mortar"},
    "default g written out": {"contact.pairs.0.g": 0},
    "integer modulus": {"materials.lower.E": 1000, "materials.upper.E": 1000},
    "clamped by tag": {"boundaries.clamped": [1]},
    "pair by tags": {"contact.pairs.0.surface": 3, "contact.pairs.0.target": 5},
    "load by tag": {"loads.displacement": {8: [0.0, None], "lower_left": [0.0, None],
                                           7: [None, "-0.01 * t"]}},
    "materials by tag": {"materials": {10: dict(ELASTIC), 11: dict(ELASTIC)}},
    "output settings differ": {"output.every": 2},
    "the mesh file copied elsewhere": {"mesh.file": "COPY:->"},
}


@pytest.mark.parametrize("changes", SAME.values(), ids=SAME.keys())
def test_an_equivalent_spelling_restarts(changes, written, tmp_path):
    proc = _restart(written, tmp_path, _case(**changes))
    assert proc.returncode == 0, proc.stderr
    assert "different case" not in proc.stderr


OTHER = {
    "another modulus": {"materials.lower.E": 1001},
    "another rule": {"contact.pairs.0.rule": "node_to_segment"},
    "another extra gap": {"contact.pairs.0.g": 0.001},
    "another clamped group": {"boundaries.clamped": [2]},
    "another target": {"contact.pairs.0.target": 6},
    "groups swapped by tag": {"materials": {11: dict(ELASTIC, E=2000.0), 10: dict(ELASTIC)}},
    "another mesh (coarser lower block)": {"mesh.file": "COPY:hl = 1 / 7;->hl = 1 / 5;"},
}


@pytest.mark.parametrize("changes", OTHER.values(), ids=OTHER.keys())
def test_a_real_change_is_refused(changes, written, tmp_path):
    proc = _restart(written, tmp_path, _case(**changes))
    assert proc.returncode == 2, proc.stderr
    assert "was written for a different case" in proc.stderr, proc.stderr
    assert not (tmp_path / "re").exists()
