"""Property-based tests (hypothesis) of case validation: whatever the dictionary, validate()
returns a Case or raises CaseError, never anything else.  The hypothesis profile of
tests/conftest.py makes the examples the same on every machine (derandomized, no example
database, no deadline or too_slow health check)."""
import copy

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import example, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from conftest import paper_raw  # noqa: E402
from vpcontact.case import Case, CaseError, validate  # noqa: E402
from vpcontact.case.reading import safe_load  # noqa: E402
from vpcontact.case.schema import SCHEMA  # noqa: E402

KEYS = sorted(SCHEMA["properties"]) + ["mesh.n", "material.E", "material.nu", "time.N",
                                       "time.T", "contact.g", "loads.f0", "solver.method",
                                       "mesh.file", "mesh.size", "mesh.engine",
                                       "material.plane", "contact.direction",
                                       "boundaries.clamped", "boundaries.contact",
                                       "loads.traction", "loads.pressure",
                                       "loads.displacement"]
scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**12, 10**12),
                    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=20))
values = st.recursive(scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=4)),
    max_leaves=12)


def _validate(data):
    try:
        case = validate(data, "hypothesis.yaml")
    except CaseError as exc:
        assert str(exc).startswith("hypothesis.yaml: ") and "\n" not in str(exc)
        return None
    assert isinstance(case, Case)
    return case


@settings(max_examples=200)
@given(st.dictionaries(st.sampled_from(KEYS + ["x"]), values, max_size=6))
@example({"mesh": {None: 1}, "material": {3: 1.0}})
def test_random_top_level_dicts(data):
    _validate(data)


@settings(max_examples=200)
@given(st.sampled_from(KEYS), values)
def test_one_key_of_the_paper_case_replaced(key, value):
    """The valid paper case with one key set to anything: a Case or a CaseError."""
    data = copy.deepcopy(dict(paper_raw()))
    node = data
    *parents, last = key.split(".")
    for p in parents:
        node = node.setdefault(p, {}) if isinstance(node.get(p), dict) else node
    node[last] = value
    _validate(data)


@settings(max_examples=100)
@given(st.text(max_size=200))
@example("?")                       # {None: None}: a non-string key (found by hypothesis)
@example("mesh: {1: 2}\n")
def test_random_yaml_text_never_crashes_the_loader(text):
    """Arbitrary text through the safe loader and validation: parsed data or YAMLError
    (load_raw turns that into CaseError), then Case or CaseError."""
    import yaml
    try:
        data = safe_load(text)
    except (yaml.YAMLError, RecursionError):
        return
    if isinstance(data, dict):
        _validate(data)


groups = st.one_of(st.sampled_from(["left", "right", "top", "bottom", "front", "x"]),
                   st.integers(-3, 12), st.booleans(), st.none(), st.floats(-1, 5),
                   st.text(max_size=6))
components = st.one_of(st.none(), st.floats(allow_nan=True), st.sampled_from(
    ["t", "x*y", "1/x", "-0.01*t", "z", "sqrt(x - 0.5)", ""]), st.integers(-5, 5))


@settings(max_examples=200)
@given(st.dictionaries(st.sampled_from(["traction", "pressure", "displacement"]),
                       st.dictionaries(groups, st.one_of(components,
                                                         st.lists(components, max_size=4)),
                                       max_size=3), max_size=3),
       st.dictionaries(st.sampled_from(["clamped", "contact", "other"]),
                       st.one_of(st.lists(groups, max_size=3), groups), max_size=2),
       st.booleans())
@example({"pressure": {3: 1.0, "3": 2.0}}, {}, True)
@example({"displacement": {"top": [None, None]}}, {"clamped": []}, False)
def test_random_scene_groups(loads, boundaries, with_contact):
    """Loads keyed by any group (names, YAML's integer tags, junk keys) and any boundaries
    on the paper case: a Case whose groups are the given ones, or a CaseError."""
    data = copy.deepcopy(dict(paper_raw()))
    data["loads"] = loads
    data["boundaries"] = boundaries
    if not with_contact:
        del data["contact"]
    case = _validate(data)
    if case is not None:
        assert set(case.loads.traction) | set(case.loads.pressure) | \
            set(case.loads.displacement) <= {"left", "right", "top", "bottom"}
        assert not set(case.boundaries.clamped) & set(case.boundaries.contact)
