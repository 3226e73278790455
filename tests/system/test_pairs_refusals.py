"""What check shows of contact.pairs and what it refuses, each refusal in one line naming
the key (exit code 2), on two small blocks written here (Geometry.AutoCoherence = 0: the
bodies share no node):

- the case-level rules (app/case/pairrules.py): the built-in mesh, contact.g,
  boundaries.contact, surface = target, a group that is another pair's
  surface, clamped or loaded pair groups, different laws in two pairs of which one is
  written in Python, memory kernels of two shapes, a pair's own law that breaks a rule of
  the contact section (named in the pair), quadrature gauss, a target group the mesh lacks;
- the mesh-level ones (app/model/pairs.py, built by check): nodes projecting outside the
  target, surfaces that do not face each other, a contact.direction pointing from a target
  toward its surface, an initial interpenetration;
- the report of a valid pair: nodes, target facets, d, g, nodes touching.
"""
import csv
import re

import pytest
import yaml

from conftest import cli_in_process, summary_steps

# two blocks [x0, x1] x [y0, y1], cells of size h; groups <body>_{bottom,right,top,left}
_BLOCK = """
Point({a}) = {{{x0}, {y0}, 0, {h}}}; Point({b}) = {{{x1}, {y0}, 0, {h}}};
Point({c}) = {{{x1}, {y1}, 0, {h}}}; Point({d}) = {{{x0}, {y1}, 0, {h}}};
Line({a}) = {{{a}, {b}}}; Line({b}) = {{{b}, {c}}}; Line({c}) = {{{c}, {d}}};
Line({d}) = {{{d}, {a}}};
Curve Loop({a}) = {{{a}, {b}, {c}, {d}}}; Plane Surface({a}) = {{{a}}};
Physical Curve("{name}_bottom", {a}) = {{{a}}}; Physical Curve("{name}_right", {b}) = {{{b}}};
Physical Curve("{name}_top", {c}) = {{{c}}}; Physical Curve("{name}_left", {d}) = {{{d}}};
Physical Surface("{name}", {e}) = {{{a}}};
"""
LOWER, UPPER = (0.0, 1.0, 0.0, 1.0), (0.0, 1.0, 1.0, 2.0)


def _geo(path, lower=LOWER, upper=UPPER) -> str:
    """The lower block (cells 1/4) and the upper one (cells 1/3), each its own mesh."""
    text = "Geometry.AutoCoherence = 0;\n" + "".join(
        _BLOCK.format(a=10 * i + 1, b=10 * i + 2, c=10 * i + 3, d=10 * i + 4, e=100 + i,
                      x0=x0, x1=x1, y0=y0, y1=y1, h=h, name=name)
        for i, (name, (x0, x1, y0, y1), h) in enumerate((("lower", lower, 0.25),
                                                         ("upper", upper, 1 / 3))))
    path.write_text(text)
    return str(path)


def _raw(geo) -> dict:
    """The lower block's top pressed by the upper block (held by its top and left side)."""
    return {
        "mesh": {"file": geo, "dim": 2},
        "materials": {"upper": {"E": 1000.0, "nu": 0.3, "plane": "strain"},
                      "lower": {"E": 1000.0, "nu": 0.3, "plane": "strain"}},
        "boundaries": {"clamped": ["lower_bottom"]},
        "contact": {"pairs": [{"surface": "lower_top", "target": "upper_bottom"}],
                    "normal_compliance": {"c_nu": 500.0}},
        "loads": {"displacement": {"upper_top": [None, -0.01], "upper_left": [0.0, None],
                                   "lower_left": [0.0, None]}},
        "time": {"T": 1.0, "N": 2},
    }


def _check(tmp_path, raw, capsys):
    """(exit code, stdout, stderr lines) of check on the case."""
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(raw))
    code = cli_in_process(["check", path])
    out = capsys.readouterr()
    return code, out.out, out.err.strip().splitlines()


def _second_pair(raw, **laws):
    """A second pair (upper_right onto lower_right) carrying ``laws``."""
    raw["contact"]["pairs"].append({"surface": "upper_right", "target": "lower_right", **laws})


def _laws_in_pairs(raw, c1: dict, c2: dict):
    """Normal compliance c1 in the first pair, c2 in a second one, none in contact."""
    raw["contact"].pop("normal_compliance")
    raw["contact"]["pairs"][0]["normal_compliance"] = c1
    _second_pair(raw, normal_compliance=c2)


def _surface_lower_bottom(raw):
    """The lower block's bottom as the surface (its outward normal points away from the
    upper block); the lower block held by its left side instead."""
    raw["contact"]["pairs"][0]["surface"] = "lower_bottom"
    raw["boundaries"]["clamped"] = ["lower_left"]
    raw["loads"]["displacement"].pop("lower_left")


def _held_by_contact(raw):
    """The upper block pressed by a pressure on its top: held vertically by the pair only
    (the condensed solver takes it serially with its compiled back end only: not with a
    fast_* PETSc option)."""
    raw["loads"]["displacement"].pop("upper_top")
    raw["loads"]["pressure"] = {"upper_top": 1.0}
    raw["petsc"] = {"fast_pc_factor_mat_solver_type": "mumps"}


def _builtin_mesh(raw):
    """The built-in rectangle (one body, one material)."""
    raw["mesh"] = {"dim": 2, "n": 4}
    raw["material"] = raw.pop("materials")["upper"]


CASE_RULES = [  # (change of the case, the key the message names, words it holds)
    (_builtin_mesh, "contact.pairs", "mesh.file"),
    (lambda r: r["contact"].update(g=0.0), "contact.g", "not with contact.pairs"),
    (lambda r: r["boundaries"].update(contact=["upper_bottom"]), "boundaries.contact",
     "leave it out"),
    (lambda r: r["contact"]["pairs"][0].update(target="lower_top"), "contact.pairs[0]",
     "the same group"),
    (lambda r: r["contact"]["pairs"].append({"surface": "lower_top", "target": "upper_right"}),
     "contact.pairs[1].surface", "already a surface of another pair"),
    (lambda r: r["contact"]["pairs"].append({"surface": "upper_bottom",
                                             "target": "lower_right"}),
     "contact.pairs[1].surface", "already a target of another pair"),
    (lambda r: r["boundaries"]["clamped"].append("upper_bottom"), "contact.pairs[0].target",
     "boundaries.clamped"),
    (lambda r: r["loads"]["displacement"].update(lower_top=[0.0, None]),
     "contact.pairs[0].surface", "carries a load"),
    (lambda r: _laws_in_pairs(r, {"law": "python", "class": "P"}, {"c_nu": 100.0}),
     "contact.pairs[0].normal_compliance", "law: python serves every pair or none"),
    (lambda r: _second_pair(r, memory={"b0": 1.0, "beta": 2.0}) or
     r["contact"]["pairs"][0].update(memory={"b0": 2.0, "beta": 1.0}),
     "contact.pairs[1].memory.beta", "share the kernel"),
    (lambda r: _second_pair(r, friction={"b": 0.1, "c1": 1.0, "c2": 1.0, "u1": 1.0}),
     "contact.pairs[1].friction", "b - c1 u1 must be >= 0"),
    (lambda r: r.update(solver={"quadrature": "gauss"}), "solver.quadrature", "vertex"),
    (lambda r: _held_by_contact(r) or r.update(solver={"method": "condensed"}),
     "solver.method", "a body's rigid motion is held only by a contact pair"),
    (lambda r: r["contact"]["pairs"][0].update(target="upper_middle"),
     "contact.pairs[0].target",
     "names: lower_bottom, lower_left, lower_right, lower_top, upper_bottom"),
]


@pytest.mark.parametrize("change, key, words", CASE_RULES)
def test_case_refusals(change, key, words, tmp_path, capsys):
    """The case-level rules and a missing group: exit code 2, one line naming the key."""
    raw = _raw(_geo(tmp_path / "two.geo"))
    change(raw)
    code, _, err = _check(tmp_path, raw, capsys)
    assert code == 2 and len(err) == 1, err
    assert re.search(rf": {re.escape(key)}( \(line \d+\))?: ", err[0]) and words in err[0], err


MESH_RULES = [  # (blocks, change of the case, the key named, words of the message)
    # the upper block over [0.25, 0.75]: the lower top's end nodes x = 0, 1 lie past it
    ({"upper": (0.25, 0.75, 1.0, 2.0)}, None, "contact.pairs[0]",
     "2 node(s) of 'lower_top' project outside the target 'upper_bottom'"),
    ({}, _surface_lower_bottom, "contact.pairs[0]", "do not face each other"),
    # a fixed direction from the target toward the surface (lower_top faces +y)
    ({}, lambda r: r["contact"].update(direction=[0.0, -1.0]), "contact.direction",
     "5 node(s) of 'lower_top' whose outward normal makes 90 degrees or more with the "
     "direction"),
    # the upper block 0.1 into the lower one: every lower top node starts inside it
    ({"upper": (0.0, 1.0, 0.9, 2.0)}, None, "contact.pairs[0]",
     "5 node(s) of 'lower_top' start inside the target body 'upper_bottom' (initial "
     "interpenetration, largest 0.1 m)"),
]


@pytest.mark.parametrize("blocks, change, key, words", MESH_RULES)
def test_mesh_refusals(blocks, change, key, words, tmp_path, capsys):
    """The pairs' projection, built by check: exit code 2, one line naming the pair."""
    raw = _raw(_geo(tmp_path / "two.geo", **blocks))
    if change is not None:
        change(raw)
    code, _, err = _check(tmp_path, raw, capsys)
    assert code == 2 and len(err) == 1, err
    assert f": {key}: " in err[0] and words in err[0], err


def test_check_reports_each_pair(tmp_path, capsys):
    """A pair touching at the start (lower top at y = 1: 5 nodes at x = k / 4, the upper
    bottom's 3 facets of 1/3), one 0.05 apart with g = 0.01 by node to segment, and the
    coarser side as the mortar surface (noted)."""
    raw = _raw(_geo(tmp_path / "two.geo"))
    code, out, _ = _check(tmp_path, raw, capsys)
    assert code == 0
    assert "contact pairs: lower_top -> upper_bottom" in out
    assert ("contact pair 0: lower_top -> upper_bottom (mortar): 5 surface nodes (h = 0.25 m), "
            "3 target facets (h = 0.333 m), initial distance d = 0..0 m, g = 0 m, 5 node(s) "
            "touching (d = 0)\n") in out
    raw["contact"]["pairs"][0].update(surface="upper_bottom", target="lower_top")
    code, out, _ = _check(tmp_path, raw, capsys)
    assert code == 0
    assert ("contact pair 0: upper_bottom -> lower_top (mortar): 4 surface nodes (h = 0.333 m), "
            "4 target facets (h = 0.25 m), initial distance d = 0..0 m, g = 0 m, 4 node(s) "
            "touching (d = 0); the surface is the coarser side") in out
    raw = _raw(_geo(tmp_path / "gap.geo", upper=(0.0, 1.0, 1.05, 2.0)))
    raw["contact"]["pairs"][0].update(g=0.01, rule="node_to_segment")
    code, out, _ = _check(tmp_path, raw, capsys)
    assert code == 0
    assert ("contact pair 0: lower_top -> upper_bottom (node_to_segment): 5 surface nodes "
            "(h = 0.25 m), 3 target facets (h = 0.333 m), initial distance d = 0.05..0.05 m, "
            "g = 0.01 m, 0 node(s) touching (d = 0)\n") in out


def test_run_logs_each_pair(tmp_path, capsys):
    """Three stacked blocks a, b, c and two pairs (a_top onto b_bottom, c_bottom onto
    b_top): the log names each pair at set-up and counts its nodes at T; the pairs' counts
    add up to the Gamma3 counts and to the rows of contact.csv of each pair."""
    blocks = [("a", 0.25), ("b", 1 / 3), ("c", 0.2)]   # 5, 4 and 6 nodes along x
    (tmp_path / "three.geo").write_text("Geometry.AutoCoherence = 0;\n" + "".join(
        _BLOCK.format(a=10 * i + 1, b=10 * i + 2, c=10 * i + 3, d=10 * i + 4, e=100 + i,
                      x0=0, x1=1, y0=i, y1=i + 1, h=h, name=name)
        for i, (name, h) in enumerate(blocks)))
    raw = {
        "mesh": {"file": str(tmp_path / "three.geo"), "dim": 2},
        "materials": {b: {"E": 1000.0, "nu": 0.3, "plane": "strain"} for b, _ in blocks},
        "boundaries": {"clamped": ["a_bottom"]},
        "contact": {"pairs": [{"surface": "a_top", "target": "b_bottom"},
                              {"surface": "c_bottom", "target": "b_top"}]},
        "loads": {"displacement": {"c_top": [None, -0.01], "b_left": [0.0, -0.005],
                                   "a_left": [0.0, None], "c_left": [0.0, None]}},
        "time": {"T": 1.0, "N": 1},
    }
    path = tmp_path / "three.yaml"
    path.write_text(yaml.safe_dump(raw))
    out = tmp_path / "out"
    assert cli_in_process(["run", path, "--out", out, "--no-plots"]) == 0
    log = capsys.readouterr().out
    assert ("contact pair 0: a_top -> b_bottom (mortar): 5 surface nodes (h = 0.25 m), 3 "
            "target facets (h = 0.333 m), initial distance d = 0..0 m") in log
    assert ("contact pair 1: c_bottom -> b_top (mortar): 6 surface nodes (h = 0.2 m), 3 "
            "target facets (h = 0.333 m), initial distance d = 0..0 m") in log
    counts = summary_steps(out)[-1]["contact_states"]
    with open(out / "contact.csv") as f:
        table = [(float(r["pair"]), r["state"]) for r in csv.DictReader(f)]
    for i, n in enumerate((5, 6)):
        each = counts["pairs"][i]
        assert each["nodes"] == n == sum(p == i for p, _ in table)
        for s in ("bound", "compliance", "separated"):
            assert each[s] == sum(p == i and state == s for p, state in table)
        assert f"  contact pair {i}: {each}" in log
    for s in ("bound", "compliance", "separated", "nodes"):
        assert counts[s] == sum(c[s] for c in counts["pairs"])
