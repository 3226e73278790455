"""The convergence study and the stability sweep on the user's own scene (mesh.file): the
Hertz cylinder's error decreasing under uniform refinement with its contact half-width
converging to Hertz's, the run cache across studies, the command line, serial == mpirun -n 2,
and the stability variants on a displacement-driven viscoplastic punch."""
import csv

import numpy as np
import pytest
from mpi4py import MPI

from conftest import ROOT, run_cli

HERTZ = ROOT / "cases" / "hertz_cylinder.yaml"
PUNCH = ROOT / "cases" / "punch_relaxation.yaml"
E, NU, R = 1000.0, 0.3, 1.0


def _hertz_study(size, levels, reference, cache_dir):
    from vpcontact.case import load_raw
    from vpcontact.studies import convergence as cv
    raw = load_raw(HERTZ, [f"mesh.size={size}"])
    return cv.study(raw, str(HERTZ), levels, reference, "both", None, MPI.COMM_WORLD,
                    cache_dir, {})


def _half_width(tab):
    """a of p = p0 sqrt(1 - x^2 / a^2), fitted by least squares of p^2 against x^2 on the
    nodes inside the contact (the edge node, with its partial load, left out)."""
    x, p = tab["x"], tab["neg_sigma_nu"]
    inside = p > 1e-6 * p.max()
    use = inside & (x < x[inside].max())
    B, A = np.polyfit(x[use] ** 2, p[use] ** 2, 1)
    return np.sqrt(-A / B)


@pytest.fixture(scope="module")
def hertz(tmp_path_factory):
    cache = tmp_path_factory.mktemp("cache")
    return _hertz_study(2.0, [0, 1, 2], 3, cache), cache


def test_hertz_error_decreases_at_first_order(hertz):
    """Nested refinements of the Hertz mesh (mesh.size 2: 802 to 45826 dofs, N = 1 .. 8):
    the Error falls by about 2 per halving of h = k (observed rates 0.96 and 1.13 against
    the 3-times refined reference: P1 displacements and piecewise constant stresses)."""
    res, _ = hertz
    rows = res["rows"]
    assert [r["level"] for r in rows] == [0, 1, 2] and res["file"]
    assert [r["N"] for r in rows] == [1, 2, 4] and res["reference"].N == 8
    errors = [r["error"] for r in rows]
    rates = [r["rate"] for r in rows[1:]]
    slope = np.polyfit(np.log([r["h"] for r in rows]), np.log(errors), 1)[0]
    hs = ", ".join(f"{r['h']:.4g}" for r in rows)
    print(f"\nHertz convergence: h = {hs}, Error = {errors}, rates = "
          + ", ".join(f"{q:.3f}" for q in rates) + f", fitted slope {slope:.3f}")
    assert errors[0] > errors[1] > errors[2] > 0
    assert all(0.8 < q < 1.5 for q in rates)
    assert 0.9 < slope < 1.3
    for r in rows:          # elastic: no kappa; the stress part dominates
        assert r["e_kappa"] == 0.0 and r["e_sigma"] > 0.9 * r["error"]
        assert r["h"] == pytest.approx(rows[0]["h"] / 2 ** r["level"], rel=1e-12)
        assert r["dofs"] < res["reference"].dofs


def test_hertz_half_width_converges_to_hertz(hertz):
    """The contact half-width fitted from each level's contact table approaches Hertz's
    a = sqrt(4 P R / (pi E*)) (P = twice the quarter's contact force of that run): the
    relative gap shrinks with every refinement, to 0.33% on the reference."""
    res, _ = hertz
    runs = [res["records"][(res["deltas"][0], L)] for L in res["levels"]] + [res["reference"]]
    gaps = []
    for run in runs:
        P = 2.0 * run.last_step["contact_force"][1]
        a = np.sqrt(4.0 * P * R / (np.pi * E / (1.0 - NU ** 2)))
        gaps.append(abs(_half_width(run.contact) / a - 1.0))
    print(f"\nHertz half-width: |a_fit / a_Hertz - 1| = {[f'{g:.4%}' for g in gaps]}")
    assert all(g1 < g0 for g0, g1 in zip(gaps, gaps[1:]))
    assert gaps[-1] < 0.005 and gaps[0] > 1.5 * gaps[-1]


def test_hertz_study_again_comes_from_the_cache(hertz):
    """A second study meshes the .geo again into new temporary files: the levels' content
    is the same, so every run comes from the cache with the same Error."""
    res, cache = hertz
    again = _hertz_study(2.0, [0, 1, 2], 3, cache)
    assert all(r["cached"] for r in again["rows"]) and again["reference"].cached
    assert [r["error"] for r in again["rows"]] == [r["error"] for r in res["rows"]]


@pytest.fixture(scope="module")
def cli_study(tmp_path_factory):
    out = tmp_path_factory.mktemp("conv") / "out"
    proc = run_cli(["convergence", HERTZ, "--set", "mesh.size=4", "--levels", "0", "1",
                    "--out", out, "--no-cache"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return out, proc


def test_convergence_command_on_a_mesh_file(cli_study):
    """Default reference = the largest level + 1; the outputs of the built-in study."""
    out, proc = cli_study
    rows = list(csv.DictReader(open(out / "convergence.csv")))
    assert [(r["level"], r["n"], r["N"]) for r in rows] == [("0", "", "1"), ("1", "", "2")]
    assert float(rows[1]["error"]) < float(rows[0]["error"])
    md = (out / "convergence.md").read_text()
    assert "reference the mesh refined 2 times" in md and "| r | h | k |" in md
    assert (out / "convergence.png").read_bytes()[:4] == b"\x89PNG"
    assert "reference run r = 2, N = 4" in proc.stdout


@pytest.mark.mpi
def test_two_ranks_give_the_same_errors_on_a_mesh_file(cli_study, tmp_path):
    out, _ = cli_study
    proc = run_cli(["convergence", HERTZ, "--set", "mesh.size=4", "--levels", "0", "1",
                    "--out", tmp_path / "np2", "--no-cache"], nprocs=2)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    serial = list(csv.DictReader(open(out / "convergence.csv")))
    for a, b in zip(serial, csv.DictReader(open(tmp_path / "np2" / "convergence.csv")),
                    strict=True):
        for key in ("error", "e_sigma", "e_u"):
            assert float(b[key]) == pytest.approx(float(a[key]), rel=1e-8), key


@pytest.mark.parametrize("levels,reference,overrides,pattern", [
    ([1, 2], 2, [], "below the reference"),
    ([2, 1], 3, [], "increase strictly"),
    ([-1, 1], 2, [], "integers >= 0"),
    ([0], None, ["time.grading=1.1"], "uniform steps"),
])
def test_bad_levels_of_a_mesh_file_are_refused(levels, reference, overrides, pattern):
    from vpcontact.case import load_raw, validate
    from vpcontact.io.errors import CaseError
    from vpcontact.studies import convergence as cv
    case = validate(load_raw(HERTZ, overrides), str(HERTZ))
    levels, reference = cv.resolve_levels(case, levels, reference)
    with pytest.raises(CaseError, match=pattern):
        cv.plan_runs(levels, reference, "both", case)


def test_bad_levels_exit_2_before_any_output(tmp_path):
    proc = run_cli(["convergence", HERTZ, "--levels", "1", "3", "--reference", "2", "--out",
                    tmp_path / "o", "--no-cache"])
    assert proc.returncode == 2 and "below the reference 2" in proc.stderr, proc.stderr
    assert not (tmp_path / "o").exists()


# ----------------------------------------------------------------------------- stability
def test_scale_handles_expressions_tables_and_free_components():
    from vpcontact.studies.stability import apply_changes
    raw = {"loads": {"displacement": {"top": [None, {"table": [[0.0, 0.0], [1.0, -0.1]]}],
                                      "side": ["0.01*t", 2.0]}},
           "contact": {"g": "y"}}
    out = apply_changes(raw, {"loads.displacement": ("scale", -2.0), "contact.g": ("scale", 10.0),
                              "loads.traction": ("scale", 3.0)})
    assert out["loads"]["displacement"]["top"] == [None, {"table": [[0.0, -0.0], [1.0, 0.2]]}]
    assert out["loads"]["displacement"]["side"] == ["(0.01*t)*(-2.0)", -4.0]
    assert out["contact"]["g"] == "(y)*(10.0)" and "traction" not in out["loads"]


@pytest.fixture(scope="module")
def punch_sweep():
    from vpcontact.case import load_raw
    from vpcontact.studies import stability as st
    raw = load_raw(PUNCH, ["mesh.size=4"])
    keep = {"baseline", "lambda1=0.01, k=T/16", "g x10", "pulling away (loads x-1)",
            "E scaled x1e6 (E = 1e9)", "h/2", "nodal normals (no contact.direction)"}
    # the stiff variant with the explicit scheme only (the implicit one is slow to fail)
    outcomes = st.sweep(raw, MPI.COMM_WORLD, {}, None, 4, source=str(PUNCH),
                        select=lambda v: ("explicit",) if v.name == "lambda1=0.01, k=T/16"
                        else v.name in keep)
    return raw, keep, {(o.variant.name, o.scheme): o for o in outcomes}


def test_stability_sweep_on_a_mesh_file(punch_sweep):
    """The punch (a .geo, viscoplastic, driven by a prescribed displacement, contact
    direction given): every chosen variant runs with both schemes on the case's own mesh;
    the scaled material reproduces the baseline, h/2 runs on the next refinement, the
    stiff explicit variant blows up and the gap variant scales the expression."""
    raw, keep, out = punch_sweep
    assert {name for name, _ in out} == keep and len(out) == 2 * len(keep) - 1
    for o in out.values():
        assert o.status in ("completed", "failed", "diverged"), (o.variant.name, o.reason)
        assert o.status == "completed" or o.reason
    base = {s: out[("baseline", s)] for s in ("explicit", "implicit")}
    assert all(b.status == "completed" and b.bounded for b in base.values())
    for s in ("explicit", "implicit"):
        finer = out[("h/2", s)]
        assert finer.status == "completed" and 3 * base[s].dofs < finer.dofs < 5 * base[s].dofs
        assert out[("E scaled x1e6 (E = 1e9)", s)].scaling_error < 1e-6
        assert out[("pulling away (loads x-1)", s)].status == "completed"
    assert not out[("lambda1=0.01, k=T/16", "explicit")].bounded
    assert out[("g x10", "explicit")].variant.changes == {"contact.g": ("scale", 10.0)}


def test_stability_variants_fit_the_scene():
    """Variants whose data a scene lacks are left out (and said so); a gap expression gets
    factors, a number the given values; --n and --refine belong to their kind of mesh."""
    from vpcontact.case import load_raw
    from vpcontact.io.errors import CaseError
    from vpcontact.studies import stability as st
    raw = load_raw(HERTZ)
    names = [v.name for v in st.default_variants(raw, {"mesh.file": "finer.msh"})]
    assert "g x0.001" in names and "g=1e-06" not in names and "h/2" in names
    assert not any(n.startswith(("lambda1=", "c_nu=", "b=30")) for n in names)
    assert st.not_applicable(raw) == [
        "stiff viscosity: the case has no material.viscoplastic",
        "near-Signorini c_nu: the case has no contact.normal_compliance",
        "friction: the case has no contact.friction"]
    with pytest.raises(CaseError, match="^--n: not used with mesh.file"):
        st.base_case(raw, 8, 4, str(HERTZ))
    with pytest.raises(CaseError, match="^--refine: only with mesh.file"):
        st.base_case(load_raw(ROOT / "cases" / "wang_cheng_2021.yaml"), None, 4, refine=1)
    with pytest.raises(CaseError, match="^--refine: -1 is not allowed"):
        st.base_case(raw, None, 4, str(HERTZ), refine=-1)


def test_growth_of_a_load_ramp_is_not_a_blow_up():
    """The Hertz push grows linearly in t: with 1024 steps the norms grow 1024-fold from
    the first step, yet only 2-fold from the base's first time point T/2, which the growth
    is measured against: the fine-step variant is bounded."""
    from vpcontact.case import load_raw
    from vpcontact.studies import stability as st
    raw = load_raw(HERTZ, ["mesh.size=8"])
    out = st.sweep(raw, MPI.COMM_WORLD, {}, None, 2, source=str(HERTZ),
                   select=lambda v: ("explicit",) if v.group == "time step" else False)
    fine = next(o for o in out if o.variant.name == "k=1/1024")
    assert fine.status == "completed" and fine.steps == 1024
    assert fine.growth_sigma == pytest.approx(2.0, rel=0.1) and fine.bounded


def _two_materials_one_pair() -> dict:
    """tests/data/patch2d.geo: a Norton lower block, a Chaboche upper block, one pair with
    its own gap, compliance, memory and Coulomb friction, the upper top pressed down."""
    def block(law: dict) -> dict:
        return {"E": 1000.0, "nu": 0.3, "plane": "strain", "viscoplastic": law}
    return {"name": "pairs", "mesh": {"file": str(ROOT / "tests" / "data" / "patch2d.geo"),
                                      "dim": 2},
            "materials": {"lower": block({"law": "norton", "A": 1e-3, "n": 2.0}),
                          "upper": block({"law": "chaboche", "n": 3.0, "k": 1.0, "K": 10.0,
                                          "C": 100.0, "gamma": 5.0, "Q": 2.0, "b": 3.0})},
            "boundaries": {"clamped": ["lower_bottom"]},
            "contact": {"pairs": [{"surface": "lower_top", "target": "upper_bottom",
                                   "g": 0.002, "normal_compliance": {"c_nu": 2000.0},
                                   "memory": {"b0": 100.0, "beta": 1.0},
                                   "friction": {"coulomb": {"mu": 0.3}}}]},
            "loads": {"displacement": {"upper_top": [0.0, "-0.01*t"]}},
            "time": {"T": 1.0, "N": 2}}


def test_stability_variants_act_on_materials_and_pairs():
    """A case with materials and a pair's laws: the c_nu, gap, friction and material
    variants change every group's and the pair's data (before, the sweep looked only at
    material.* and contact.*: it left them out as absent); the variants that cannot act
    say precisely why (no lambda1 in Norton's and Chaboche's laws, Coulomb friction has no
    b, c1).  Run (explicit, 2 steps): the changed c_nu and the frictionless pair change the
    solution, and the scaled materials (Norton's A by f^-n, Chaboche's k, K, C, Q, the
    pair's c_nu and b0 by f) reproduce the baseline exactly scaled (u equal, sigma x f:
    measured 5e-16)."""
    from vpcontact.studies import stability as st
    raw = _two_materials_one_pair()
    assert st.not_applicable(raw) == [
        "stiff viscosity: materials.lower: norton's law has no viscosity lambda1, "
        "materials.upper: chaboche's law has no viscosity lambda1",
        "friction b=30, c1=300: contact.pairs[0].friction is coulomb friction, not law "
        "(4.2): no b, c1"]
    variants = {v.name: v for v in st.default_variants(raw)}
    pair = ("contact", "pairs", 0)
    assert variants["c_nu=10000"].changes == {pair + ("normal_compliance", "c_nu"): 1e4}
    assert variants["g=0.001"].changes == {pair + ("g",): 1e-3}
    assert variants["frictionless"].changes == {pair + ("friction",): None}
    assert variants["nu=0"].changes == {("materials", g, "nu"): 0.0 for g in ("lower", "upper")}
    scaled = variants["E scaled x1e6 (every material)"].changes
    assert scaled[("materials", "lower", "viscoplastic", "A")] == ("scale", 1e6 ** -2.0)
    assert scaled[("materials", "upper", "viscoplastic", "K")] == ("scale", 1e6)
    keep = {"baseline", "c_nu=10000", "frictionless", "E scaled x1e6 (every material)"}
    out = {o.variant.name: o for o in st.sweep(
        raw, MPI.COMM_WORLD, {}, None, 2,
        select=lambda v: ("explicit",) if v.name in keep else False)}
    assert set(out) == keep and all(o.status == "completed" for o in out.values())
    u0 = out["baseline"].norms["u"]
    assert abs(out["c_nu=10000"].norms["u"] / u0 - 1) > 1e-2
    assert abs(out["frictionless"].norms["u"] / u0 - 1) > 1e-4
    assert out["E scaled x1e6 (every material)"].scaling_error < 1e-10
