"""Two identical elastic cylinders (cases/identical_cylinders.yaml: R = 1, E = 1000, nu = 0.3,
plane strain, Coulomb mu = 0.4, the lower mesh the mirror image of the upper one), pressed
by a pure normal approach and then sheared, against the symmetry of the problem and the
closed forms of Johnson, Contact Mechanics, 4.2 and 7.2 (tests/references/
contact_closed_forms.py):

- the normal approach: by symmetry (u_x(x, y) = u_x(x, -y), u_y(x, y) = -u_y(x, -y)) the
  jump is vertical and there is no friction: max |sigma_tau| <= 1e-3 max p_n with the case's
  node-to-segment rule (measured 2e-14 at mesh.size 4; before the averaged pair normal
  0.16: the target's normal at the closest point is tilted by x / R), and <= 2e-2 with the
  mortar rule (measured 1.0e-2 at the contact edges: its normal part takes the surface
  node's own u_i against the target's mean, which is not mirror-symmetric; before 0.19);
- Cattaneo-Mindlin (the shear Q ~ mu P / 2 in one step, the depth held): the stick zone is
  centred (point symmetry: within 1e-6 a, measured 3e-10; before -0.10 a), its half-width
  c = a sqrt(1 - Q / (mu P)) within one contact cell h at mesh.size 4 and 2 (measured -6.4 %
  and -3.2 % of a, h = 9.9 % and 5 %), the error falling with h; the shear traction q(x)
  within 0.2 mu p0 (max) and 0.07 mu p0 (rms) of Mindlin's at mesh.size 4, 0.15 and 0.05 at
  2 (measured 0.167, 0.054; 0.123, 0.037), both falling.  P and Q are the contact force on
  the upper cylinder, a and p0 the Hertz values of P for identical cylinders (R* = R / 2);
- mpirun -n 2 gives the serial contact.csv to 1e-8 of each column's scale.
"""
import csv
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from conftest import make_case, run_cli
from references.contact_closed_forms import hertz_cylinders, mindlin_shear, mindlin_stick_halfwidth
from vpcontact.case import load_raw
from vpcontact.observers import Observer
from vpcontact.post.quantities import contact_table
from vpcontact.simulation import run

ROOT = Path(__file__).parents[2]
CASE = ROOT / "cases" / "identical_cylinders.yaml"
E, NU, MU, R, HC = 1000.0, 0.3, 0.4, 1.0, 0.0025     # HC: the .geo's cell size on the arcs


class _Tables(Observer):
    """contact_table after every accepted step."""

    def __init__(self):
        self.tables = []

    def step(self, sim, record):
        self.tables.append(contact_table(sim.problem))


def _run(size: float, rule: str = "node_to_segment", N: int = 2) -> list[dict]:
    """The shipped case at mesh.size, pressed in its first step (t = 1/2) and sheared in
    the second (N = 2; N = 1: pressed only), in this process: the measures of each step."""
    raw = load_raw(CASE)
    assert raw["contact"]["pairs"][0]["rule"] == "node_to_segment"
    assert raw["contact"]["pairs"][0]["friction"] == {"coulomb": {"mu": MU}}
    assert all(m == {"E": E, "nu": NU, "plane": "strain"} for m in raw["materials"].values())
    raw["mesh"].update({"file": str(CASE.with_suffix(".geo")), "size": size})
    raw["contact"]["pairs"][0]["rule"] = rule
    for ramp in raw["loads"]["displacement"]["upper_top"]:
        assert ramp["table"][1][0] == 0.25 and len(ramp["table"]) == 3
        ramp["table"][1][0] = 0.5               # the end of the normal approach
    raw["time"].update({"T": 0.5 * N, "N": N})
    rec = _Tables()
    result = run(make_case(raw), MPI.COMM_WORLD, [rec])
    assert result.status == "completed"
    return [_measure(s, t) for s, t in zip(result.summary["steps"], rec.tables)]


def _measure(step: dict, tab: dict) -> dict:
    """P, Q, the Hertz a and p0 of P, the table sorted by x and the nodes in contact."""
    Q, P = -step["contact_force"][0], step["contact_force"][1]
    a, p0 = hertz_cylinders(P, R, R, E, NU, E, NU)
    order = np.argsort(tab["x"])
    t = {k: v[order] for k, v in tab.items()}
    touch = t["neg_sigma_nu"] > 1e-6 * t["neg_sigma_nu"].max()
    return {"P": P, "Q": Q, "a": a, "p0": p0, "t": t, "touch": touch}


def _stick_zone(m: dict) -> tuple[float, float]:
    """The stick nodes' zone (slip_state 0 in contact, one block flanked by slip nodes):
    its ends halfway between the last stick node and the first slip node on each side."""
    t, touch = m["t"], m["touch"]
    stick = np.flatnonzero(touch & (t["slip_state"] == 0))
    i, j = stick.min(), stick.max()
    assert (t["slip_state"][i:j + 1] == 0).all()
    assert (t["slip_state"][[i - 1, j + 1]] == 1).all() and m["touch"][[i - 1, j + 1]].all()
    return (t["x"][i - 1] + t["x"][i]) / 2, (t["x"][j] + t["x"][j + 1]) / 2


@pytest.fixture(scope="module")
def coarse():
    return _run(4.0)


@pytest.fixture(scope="module")
def fine():
    return _run(2.0)


def _friction_ratio(m: dict) -> float:
    t = m["t"]
    return np.abs(t["neg_sigma_tau"]).max() / t["neg_sigma_nu"].max()


def test_normal_approach_has_no_friction(coarse, fine):
    """Pressed only (Q = 0 to round-off): max |sigma_tau| <= 1e-3 max p_n at both meshes."""
    for m in (coarse[0], fine[0]):
        assert m["touch"].sum() >= 15
        assert abs(m["Q"]) <= 1e-9 * m["P"]
        assert _friction_ratio(m) <= 1e-3


def test_normal_approach_mortar():
    """The mortar rule under the same approach: max |sigma_tau| <= 2e-2 max p_n."""
    (m,) = _run(4.0, rule="mortar", N=1)
    assert _friction_ratio(m) <= 2e-2


def test_mindlin_stick_zone(coarse, fine):
    """Sheared to Q / (mu P) ~ 0.5: the stick zone centred on x = 0 (1e-6 a), its half-width
    within one contact cell of a sqrt(1 - Q / (mu P)), the error falling with h."""
    errors = []
    for size, m in ((4.0, coarse[1]), (2.0, fine[1])):
        assert 0.45 < m["Q"] / (MU * m["P"]) < 0.55
        lo, hi = _stick_zone(m)
        assert abs(lo + hi) / 2 <= 1e-6 * m["a"]
        c = mindlin_stick_halfwidth(m["a"], m["Q"], MU, m["P"])
        errors.append(abs((hi - lo) / 2 - c))
        assert errors[-1] <= HC * size
    assert errors[1] < errors[0]


def test_mindlin_shear_traction(coarse, fine):
    """The nodal friction stress against Mindlin's q(x) (about x = 0): within 0.2 mu p0 at
    every contact node and 0.07 mu p0 rms at mesh.size 4, 0.15 and 0.05 at 2."""
    out = []
    for m, (most, rms) in ((coarse[1], (0.2, 0.07)), (fine[1], (0.15, 0.05))):
        t, touch = m["t"], m["touch"]
        c = mindlin_stick_halfwidth(m["a"], m["Q"], MU, m["P"])
        err = (t["neg_sigma_tau"][touch] - mindlin_shear(t["x"][touch], m["a"], c, m["p0"],
                                                         MU)) / (MU * m["p0"])
        out.append((np.abs(err).max(), np.sqrt(np.mean(err ** 2))))
        assert out[-1][0] <= most and out[-1][1] <= rms
    assert out[1][0] < out[0][0] and out[1][1] < out[0][1]


def _contact_csv(path: Path) -> dict[str, np.ndarray]:
    """contact.csv's numeric columns, rows sorted by (x, y)."""
    with open(path) as f:
        rows = list(csv.DictReader(f))
    cols = {k: np.array([float(r[k]) for r in rows]) for k in rows[0] if k != "state"}
    order = np.lexsort((cols["y"], cols["x"]))
    return {k: v[order] for k, v in cols.items()}


def test_mpirun_equals_serial(tmp_path):
    """The case at mesh.size 4, 2 steps (t = 1/2: pressed and partly sheared; 1: sheared):
    contact.csv under mpirun -n 2 equals the serial one to 1e-8 of each column's largest
    value."""
    sets = ["--set", "mesh.size=4", "--set", "time.N=2"]
    tables = []
    for n in (1, 2):
        out = tmp_path / f"np{n}"
        proc = run_cli(["run", CASE, "--out", out, "--quiet", *sets], nprocs=n)
        assert proc.returncode == 0, proc.stderr
        tables.append(_contact_csv(out / "contact.csv"))
    one, two = tables
    assert one.keys() == two.keys() and len(one["x"]) == len(two["x"]) > 50
    for key in one:
        scale = max(np.abs(one[key]).max(), 1e-300)
        assert np.abs(two[key] - one[key]).max() <= 1e-8 * scale, key
