"""Data on a mesh file are checked as on the built-in mesh: once the mesh
is loaded, app/case/datacheck.py's checks run on its own points (app/model/datapoints.py),
with the same one-line error naming the key and the point (x, t), before any computation,
on every rank."""
import re

import numpy as np
import pytest
import yaml
from mpi4py import MPI

import vpcontact.simulation
from conftest import PAPER_CASE, make_case, run_case, run_cli
from meshtools import write_rotated_square
from vpcontact.case import CaseError
from vpcontact.case.datacheck import PointSamples
from vpcontact.model.datapoints import check_data_on_mesh, mesh_samples, with_rounded
from vpcontact.simulation import build_mesh


@pytest.fixture(scope="module")
def square(tmp_path_factory):
    """The paper's unit square, n = 4, as a .msh with the sides named (not rotated)."""
    return write_rotated_square(tmp_path_factory.mktemp("mesh") / "square.msh", 4, 0.0)


def _raw(square, **sections) -> dict:
    raw = yaml.safe_load(PAPER_CASE.read_text())
    raw["mesh"] = {"file": str(square)}
    raw["boundaries"] = {"clamped": ["left"], "contact": ["bottom"]}
    raw["time"]["N"] = 2
    for name, value in sections.items():
        raw[name] = {**raw.get(name, {}), **value}
    return raw


# (sections, the message's start after the file name, where the point named must lie and
# what the datum is there, computed here): each refused on the built-in square too
BAD = [
    ({"loads": {"traction": {"top": ["1/(x-x)", 0.0]}}},
     "loads.traction.top[0]: inf is not a finite number", lambda x, y, t: y == 1.0),
    ({"contact": {"g": "exp(700*x)"}}, "contact.g: ",
     lambda x, y, t: y == 0.0 and np.exp(700 * x) > 1e100),
    ({"contact": {"g": "x - 0.5"}},
     "contact.g: must be >= 0 on Gamma3 (the gap to the foundation), got ",
     lambda x, y, t: y == 0.0 and x < 0.5),
    ({"loads": {"f0": ["log(y - 0.5)", 0.0]}}, "loads.f0[0]: ",
     lambda x, y, t: y <= 0.5),
    ({"loads": {"pressure": {"right": "1/(t - y)"}}},
     "loads.pressure.right: inf is not a finite number", lambda x, y, t: x == 1.0 and y == t),
    ({"loads": {"displacement": {"right": ["sqrt(0.5 - y)", None]}}},
     "loads.displacement.right[0]: nan is not a finite number",
     lambda x, y, t: x == 1.0 and y > 0.5),
    ({"initial": {"u0": ["x*x", "1/(x - 0.25)"]}}, "initial.u0[1]: inf is not a finite number",
     lambda x, y, t: x == 0.25),
    ({"initial": {"sigma0": [["1e200*x", 0], [0, 0]]}}, "initial.sigma0[0][0]: ",
     lambda x, y, t: 1e200 * x > 1e100),
    ({"material": {"viscoplastic": {"lambda1": 1.0, "lambda2": 1.0, "kappa0": "1/y"}}},
     "material.viscoplastic.kappa0: inf is not a finite number", lambda x, y, t: y == 0.0),
]
IDS = ["traction", "gap-huge", "gap-negative", "f0", "pressure-time", "displacement",
       "u0", "sigma0", "kappa0"]
POINT = re.compile(r" at x = (\S+), y = ([^,\s]+)(?:, t = (\S+))?(?: \(allowed|$)")


@pytest.mark.parametrize("sections, message, where", BAD, ids=IDS)
def test_refused_on_the_built_in_mesh_too(sections, message, where):
    """The reference: validation refuses each on the built-in square (same key)."""
    raw = _raw("x.msh", **sections)
    raw["mesh"] = {"n": 4}
    raw.pop("boundaries")
    with pytest.raises(CaseError) as err:
        make_case(raw)
    assert f"test-case: {message}" in str(err.value)


@pytest.mark.parametrize("sections, message, where", BAD, ids=IDS)
def test_refused_on_the_mesh_file_before_any_computation(square, sections, message, where,
                                                          monkeypatch):
    case = make_case(_raw(square, **sections))      # validation cannot see the position
    monkeypatch.setattr(vpcontact.simulation, "ContactProblem", _no_computation)
    with pytest.raises(CaseError) as err:
        run_case(case)
    text = str(err.value)
    assert text.startswith(f"test-case: {message}") and "\n" not in text, text
    m = POINT.search(text)
    assert m, text
    x, y = float(m.group(1)), float(m.group(2))
    t = float(m.group(3)) if m.group(3) else None
    assert where(x, y, t), text


def _no_computation(*args, **kwargs):
    raise AssertionError("the data were not checked before the problem was built")


def test_the_samples_are_the_mesh_points(square):
    """Body: the nodes and cell midpoints; a group: its nodes and facet midpoints."""
    case = make_case(_raw(square, loads={"traction": {"top": [0.0, -8.0]}}))
    body = build_mesh(case, MPI.COMM_SELF)
    samples = mesh_samples(case, body)
    assert isinstance(samples, PointSamples)
    pts = samples.points()
    grid = np.linspace(0.0, 1.0, 5)
    nodes = np.array([[x, y] for x in grid for y in grid])
    cells = body.mesh.geometry.x[body.mesh.geometry.dofmap.array.reshape(-1, 3), :2]
    assert len(pts) == 25 + 32 and _same(pts, np.concatenate([nodes, cells.mean(axis=1)]))
    top = samples.points("top")
    expected = np.array([[x, 1.0] for x in np.linspace(0.0, 1.0, 9)])
    assert len(top) == 9 and _same(top, expected)
    assert len(samples.points("left")) == 9 and len(samples.points("nope")) == 0
    assert check_data_on_mesh(case, body) == pytest.approx(8.0)     # the traction's stress


def _same(points, expected) -> bool:
    """The same set of points (to round-off)."""
    d = np.linalg.norm(points[:, None, :] - expected[None, :, :], axis=2)
    return bool((d.min(axis=0) < 1e-12).all() and (d.min(axis=1) < 1e-12).all())


@pytest.mark.mpi
def test_two_ranks_refuse_alike(square, tmp_path):
    raw = _raw(square, loads={"traction": {"top": ["1/(x-x)", 0.0]}})
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(raw))
    proc = run_cli(["run", path, "--out", tmp_path / "out"], nprocs=2, timeout=300)
    assert proc.returncode == 2, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "Traceback" not in proc.stdout + proc.stderr
    assert "internal error" not in proc.stdout + proc.stderr
    assert "loads.traction.top[0]: inf is not a finite number at x = " in proc.stderr
    assert not (tmp_path / "out" / "summary.json").exists()


def test_check_refuses_alike(square, tmp_path):
    """`vpcontact check` builds the problem as a run does: the same refusal."""
    raw = _raw(square, contact={"g": "exp(700*x)"})
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(raw))
    proc = run_cli(["check", path], timeout=300)
    assert proc.returncode == 2, proc.stdout[-2000:] + proc.stderr[-2000:]
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "contact.g: " in lines[0] and "is out of range at x = " \
        in lines[0], proc.stderr


@pytest.mark.parametrize("sections", [
    {"initial": {"u0": [0, 0]}}, {"loads": {"displacement": {"right": ["0*t", None]}}},
    {"initial": {"sigma0": [["0*x", 0], [0, 0]]}}, {"contact": {"g": "0*x"}}],
    ids=["u0", "displacement", "sigma0", "gap"])
def test_zero_data_run_on_the_mesh_file(square, sections):
    result = run_case(make_case(_raw(square, **sections)))
    assert result.status == "completed", result.summary
    assert np.isfinite(result.problem.u.x.array).all()


def test_round_off_does_not_hide_a_singular_point(tmp_path, monkeypatch):
    """The square turned by 1e-10 degrees: the node meant at (0.5, 1) is 2e-12 away, where
    -5/(x - 0.5) is finite (3e12); the rounded point (0.5, 1) is sampled too."""
    tilted = write_rotated_square(tmp_path / "tilted.msh", 4, 1e-10)
    case = make_case(_raw(tilted, loads={"traction": {"top": [0.0, "-5/(x - 0.5)"]}}))
    monkeypatch.setattr(vpcontact.simulation, "ContactProblem", _no_computation)
    with pytest.raises(CaseError) as err:
        run_case(case)
    assert "loads.traction.top[1]: -inf is not a finite number at x = 0.5, y = 1, t = 0" \
        in str(err.value)


def test_rounding_keeps_points_that_are_not_round_off():
    """Only points within 1e-11 L of a 9-digit point get that point added: not 1/3, not a
    point of the unit circle."""
    a = 0.3
    points = np.array([[0.5 + 2e-12, 1.0], [1 / 3, 0.0], [np.cos(a), np.sin(a)], [0.25, 0.75]])
    got = with_rounded(points, 1.0)
    np.testing.assert_array_equal(got[:4], points)
    np.testing.assert_array_equal(got[4:], [[0.5, 1.0]])
    big = with_rounded(points * 1000.0, 1000.0)             # relative to the body's size
    np.testing.assert_array_equal(big[4:], [[500.0, 1000.0]])
    assert with_rounded(np.zeros((0, 2)), 1.0).shape == (0, 2)
