"""Cattaneo-Mindlin between two identical cylinders under force control
(cases/identical_cylinders_cap.yaml: the mirror-image cylinders of
cases/identical_cylinders.yaml, the upper one's flat side a rigid cap carrying the
resultant (Q, -P), its rotation held at 0; the upper body held only by the contact), against
the closed forms of Johnson, Contact Mechanics, 4.2 and 7.2 (tests/references/
contact_closed_forms.py), at two meshes:

- pressed by P alone: the contact force on the upper body is (0, P) to 1e-9 P and there is
  no friction: max |sigma_tau| <= 1e-3 max p_n (by symmetry the jump is vertical);
- then sheared by Q = mu P / 2 with P held: the contact force is (-Q, P) to 1e-6 P, the cap
  translates sideways without turning; the stick zone is centred on x = 0 (1e-6 a), its
  half-width within one contact cell of c = a sqrt(1 - Q / (mu P)), the error falling with h
  (measured -6.2 %, +0.6 % and -0.06 % of a at mesh.size 4, 2 and 1), and the shear traction
  within 0.2 mu p0 of Mindlin's q(x) (max; measured 0.150, 0.152, 0.083: the nodes at the
  stick-slip kink), its rms within 0.07 / 0.05 mu p0 at mesh.size 4 / 2 and falling
  (measured 0.052, 0.044, 0.019), a and p0 the Hertz values of P for identical cylinders
  (R* = R / 2);
- SNES VI gives the condensed solver's contact table (mesh.size 4) to 1e-6 of the largest
  displacement and pressure.
"""
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI
from test_pairs_identical_cylinders import HC, MU, _friction_ratio, _measure, _stick_zone, _Tables

from conftest import make_case
from references.contact_closed_forms import mindlin_shear, mindlin_stick_halfwidth
from vpcontact.case import load_raw
from vpcontact.simulation import run

CASE = Path(__file__).parents[2] / "cases" / "identical_cylinders_cap.yaml"


def _run(size: float, method: str = "auto") -> list[dict]:
    """The shipped case at mesh.size in two steps: pressed by P (t = 1/2), sheared by
    Q = mu P / 2 (t = 1); the measures of each step, with the applied force and the cap's
    report."""
    raw = load_raw(CASE)
    cap = raw["loads"]["rigid"]["upper_top"]
    assert cap["rotation"] == 0.0 and raw["contact"]["pairs"][0]["friction"] == \
        {"coulomb": {"mu": MU}}
    for ramp in cap["force"]:
        assert ramp["table"][1][0] == 0.25 and len(ramp["table"]) == 3
        ramp["table"][1][0] = 0.5                 # the end of the normal approach
    raw["mesh"].update({"file": str(CASE.parent / raw["mesh"]["file"]), "size": size})
    raw["time"].update({"N": 2})
    raw["solver"]["method"] = method
    rec = _Tables()
    result = run(make_case(raw), MPI.COMM_WORLD, [rec])
    assert result.status == "completed"
    out = []
    for step, tab in zip(result.summary["steps"], rec.tables):
        m = _measure(step, tab)
        m["cap"] = step["rigid"]["upper_top"]
        out.append(m)
    return out


@pytest.fixture(scope="module")
def coarse():
    return _run(4.0)


@pytest.fixture(scope="module")
def fine():
    return _run(2.0)


def test_pressed_by_a_force_without_friction(coarse, fine):
    for m in (coarse[0], fine[0]):
        assert m["P"] == pytest.approx(8.7, rel=1e-9) and abs(m["Q"]) <= 1e-9 * m["P"]
        assert _friction_ratio(m) <= 1e-3
        assert abs(m["cap"]["displacement"][0]) <= 1e-12 and m["cap"]["displacement"][1] < 0


def test_sheared_by_a_force_balances_it(coarse, fine):
    for pressed, m in (coarse, fine):
        assert m["P"] == pytest.approx(8.7, rel=1e-6)
        assert m["Q"] == pytest.approx(MU * 8.7 / 2, rel=1e-6)
        u, theta = m["cap"]["displacement"], m["cap"]["rotation"]
        assert u[0] > 0 and abs(theta) <= 1e-12
        assert u[1] == pytest.approx(pressed["cap"]["displacement"][1], rel=1e-3)


def test_mindlin_stick_zone_and_shear_traction(coarse, fine):
    errors, shear = [], []
    for size, m, (most, rms) in ((4.0, coarse[1], (0.2, 0.07)), (2.0, fine[1], (0.2, 0.05))):
        lo, hi = _stick_zone(m)
        assert abs(lo + hi) / 2 <= 1e-6 * m["a"]
        c = mindlin_stick_halfwidth(m["a"], m["Q"], MU, m["P"])
        errors.append(abs((hi - lo) / 2 - c))
        assert errors[-1] <= HC * size
        t, touch = m["t"], m["touch"]
        err = (t["neg_sigma_tau"][touch] - mindlin_shear(t["x"][touch], m["a"], c, m["p0"],
                                                         MU)) / (MU * m["p0"])
        shear.append((np.abs(err).max(), np.sqrt(np.mean(err ** 2))))
        assert shear[-1][0] <= most and shear[-1][1] <= rms
    assert errors[1] < errors[0]
    assert shear[1][1] < shear[0][1]


def test_snes_vi_equals_the_condensed_solver(coarse):
    snes = _run(4.0, method="snes_vi")
    for a, b in zip(coarse, snes):
        scales = {"u_x": np.abs(np.c_[a["t"]["u_x"], a["t"]["u_y"]]).max(),
                  "neg_sigma_nu": a["t"]["neg_sigma_nu"].max()}
        for key in ("u_x", "u_y", "neg_sigma_nu", "neg_sigma_tau"):
            scale = scales["u_x" if key.startswith("u") else "neg_sigma_nu"]
            assert np.abs(a["t"][key] - b["t"][key]).max() <= 1e-6 * scale, key
