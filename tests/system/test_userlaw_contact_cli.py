"""Contact laws written by the user from the command line (`contact.normal_compliance` and
`contact.friction` with `law: python`, `class`, `params`, `--law-module FILE.py`), and the
law module in the checkpoints' fingerprint.

The paper's (4.1) and (4.2) typed out as a user would (tests/userlaws/paper_contact_laws.py,
not the built-in classes) give the built-in run to 1e-12 (norms, iterations, contact.csv)
with SNES VI (UFL) and the condensed solver (numpy); the refusals exit 2 with one line; a
restart with an edited law module is refused, with the same module it is accepted; the
fingerprint of a case without a python law is the sections' hash as before.  The runs are
cli.main in this process, on the paper's case at h = k = 1/4."""
import json
import re
import shutil

import numpy as np
import pytest

from conftest import PAPER_CASE, ROOT, cli_in_process, contact_rows, summary_steps

LAW_MODULE = ROOT / "tests" / "userlaws" / "paper_contact_laws.py"
TINY = ["--set", "mesh.n=4", "--set", "time.N=4"]
NORMAL = "contact.normal_compliance={law: python, class: %s, params: {c: 100.0}}"
FRICTION = ("contact.friction={law: python, class: %s, params: {b: 1.0, c1: 60.0, c2: 60.0, "
            "u1: 0.01}}")
USER = ["--set", NORMAL % "UserCompliance", "--set", FRICTION % "UserFriction"]
KEYS = ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y", "max_vm", "max_kappa")


def _run(out, *extra) -> None:
    code = cli_in_process(["run", PAPER_CASE, "--out", out, "--quiet", "--no-plots", "--overwrite",
                  *TINY, *extra])
    assert code == 0, extra


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The built-in laws and the user's, with SNES VI and the condensed solver."""
    out = {}
    for method in ("snes_vi", "condensed"):
        for laws, extra in (("builtin", []), ("user", ["--law-module", LAW_MODULE, *USER])):
            d = tmp_path_factory.mktemp(f"{laws}_{method}")
            _run(d, "--set", f"solver.method={method}", *extra)
            out[laws, method] = d
    d = tmp_path_factory.mktemp("user_c200")     # another constant: the law takes effect
    _run(d, "--set", "solver.method=condensed", "--law-module", LAW_MODULE, "--set",
         NORMAL.replace("100.0", "200.0") % "UserCompliance")
    out["c200", "condensed"] = d
    return out


@pytest.mark.parametrize("method", ["snes_vi", "condensed"])
def test_user_paper_laws_equal_the_builtin(runs, method):
    ref, user = summary_steps(runs["builtin", method]), summary_steps(runs["user", method])
    assert len(ref) == len(user) == 4
    for a, b in zip(ref, user):
        assert a["newton_iterations"] == b["newton_iterations"]
        for key in KEYS:
            assert b[key] == pytest.approx(a[key], rel=1e-12, abs=1e-300), key
    assert ref[-1]["max_kappa"] > 0
    (s0, c0), (s1, c1) = contact_rows(runs["builtin", method]), contact_rows(runs["user", method])
    assert s0 == s1 and c0.shape == c1.shape
    assert "compliance" in s0                                    # the compliance law acted
    assert np.all(np.abs(c1 - c0) <= 1e-12 * np.abs(c0).max(axis=0))
    laws = json.loads((runs["user", method] / "summary.json").read_text())["laws"]
    assert (laws["contact"]["normal"]["name"], laws["contact"]["friction"]["name"]) == \
        ("user compliance (4.1)", "user friction (4.2)")
    assert laws["contact"]["normal"]["constants"] == {"c": [100.0, ""]}


def test_the_case_law_takes_effect(runs):
    """The user's compliance with c = 200 (the built-in friction kept) moves the run."""
    ref = summary_steps(runs["builtin", "condensed"])
    other = summary_steps(runs["c200", "condensed"])
    assert abs(other[-1]["norm_u_V"] / ref[-1]["norm_u_V"] - 1) > 1e-6


def test_a_friction_law_smooth_in_the_slip_with_snes_vi(tmp_path):
    """psi(rho) = b rho + a rho^2 / 2 written as plain arithmetic with psi'' = a a number
    (QuadraticFriction): SNES VI gives the run of the friction table [[0, b], [1, b + a]]
    (the same psi, the built-in TableFriction) to 1e-12; before, its Jacobian form failed
    to compile (FFCx 0.5: 'LiteralFloat' object has no attribute 'args', an internal
    error)."""
    user, table = tmp_path / "user", tmp_path / "table"
    _run(user, "--set", "solver.method=snes_vi", "--law-module", LAW_MODULE, "--set",
         "contact.friction={law: python, class: QuadraticFriction, params: {b: 1.0, a: 60.0}}")
    _run(table, "--set", "solver.method=snes_vi", "--set",
         "contact.friction={table: [[0.0, 1.0], [1.0, 61.0]]}")
    ref, got = summary_steps(table), summary_steps(user)
    assert len(ref) == len(got) == 4
    for a, b in zip(ref, got):
        assert a["newton_iterations"] == b["newton_iterations"]
        for key in KEYS:
            assert b[key] == pytest.approx(a[key], rel=1e-12, abs=1e-300), key
    (s0, c0), (s1, c1) = contact_rows(table), contact_rows(user)
    assert s0 == s1 and np.all(np.abs(c1 - c0) <= 1e-12 * np.abs(c0).max(axis=0))


def test_a_contact_law_that_raises_during_the_run_fails_the_step(tmp_path, capsys):
    """A compliance whose derivative raises KeyError beyond r = 2e-3 (the probe, at 1e-3, stays
    below): the condensed solver's step that reaches it fails, naming the law and
    the method, with summary.json; before, a traceback and "this is a bug"."""
    out = tmp_path / "out"
    code = cli_in_process(["run", PAPER_CASE, *TINY, "--law-module", LAW_MODULE, "--set",
                           "contact.normal_compliance={law: python, class: RaisingCompliance, "
                           "params: {c: 100.0, level: 2.0e-3}}", "--set",
                           "solver.method=condensed", "--out", out, "--quiet", "--no-plots"])
    err = capsys.readouterr().err
    assert code == 1 and "Traceback" not in err and "this is a bug" not in err, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed"
    assert summary["failure"]["reason"].startswith(
        f"--law-module {LAW_MODULE}: class RaisingCompliance: derivative(x) raised KeyError: "
        "'beyond my table'")


def test_check_lists_the_user_laws(capsys):
    """check names the laws, their params and m_j (the law's own, or not stated)."""
    assert cli_in_process(["check", PAPER_CASE, *TINY, "--law-module", LAW_MODULE, *USER]) == 0
    out = capsys.readouterr().out
    assert "contact: user compliance (4.1): c = 100\n" in out
    assert "contact: user friction (4.2): b = 1, c1 = 60, c2 = 60, u1 = 0.01; m_j = 60 " \
           "N/m^3" in out
    assert "friction (the user's law UserFriction, --law-module)" in out
    assert cli_in_process(["check", PAPER_CASE, *TINY, "--law-module", LAW_MODULE,
                  "--set", FRICTION % "UnstatedFriction"]) == 0
    out = capsys.readouterr().out
    assert "m_j: not stated by the law (no (2.6) margin)" in out
    assert "well-posedness (2.6)" not in out


def test_duck_typed_law_runs():
    """An object with the three methods (no ScalarLaw base) is a contact law too."""
    from mpi4py import MPI

    from conftest import make_case, paper_raw
    from vpcontact.io.lawfile import forget_law_module
    from vpcontact.model.lawmodule import load_law_module
    from vpcontact.model.problem import ContactProblem
    from vpcontact.simulation import build_mesh
    raw = paper_raw()
    raw["contact"]["normal_compliance"] = {"law": "python", "class": "DuckCompliance",
                                           "params": {"c": 100.0}}
    case = make_case(raw, mesh={"n": 4}, time={"N": 4})
    load_law_module(LAW_MODULE)
    try:
        problem = ContactProblem(case, build_mesh(case, MPI.COMM_WORLD))
    finally:
        forget_law_module()
    law = problem.contact_law().normal
    assert type(law.user).__name__ == "DuckCompliance"
    r = np.array([-0.01, 0.0, 0.005])
    np.testing.assert_array_equal(law.derivative(r), [0.0, 0.0, 0.5])


def test_python_api_without_the_module():
    """From the Python API a case's python law needs the module loaded (refused, naming the
    key); a law given through contact_laws for that part takes its place (no module)."""
    from mpi4py import MPI

    from conftest import make_case, paper_raw
    from userlaws.paper_contact_laws import UserCompliance
    from vpcontact.io.errors import CaseError
    from vpcontact.model.problem import ContactProblem
    from vpcontact.simulation import build_mesh
    raw = paper_raw()
    raw["contact"]["normal_compliance"] = {"law": "python", "class": "UserCompliance",
                                           "params": {"c": 100.0}}
    case = make_case(raw, mesh={"n": 4}, time={"N": 4})
    body = build_mesh(case, MPI.COMM_WORLD)
    with pytest.raises(CaseError, match="contact.normal_compliance.law: python runs the "
                                        "class UserCompliance"):
        ContactProblem(case, body)
    law = UserCompliance(50.0)
    problem = ContactProblem(case, body, contact_laws={"normal": law})
    assert problem.contact_law().normal is law


M = "--law-module {module}: class "


@pytest.mark.parametrize("extra, message", [
    (["--set", NORMAL % "UserCompliance"],
     "contact.normal_compliance.law: python runs the class UserCompliance of a Python "
     "module: give the module with --law-module FILE.py (a case file alone never runs code)"),
    (["--set", FRICTION % "UserFriction"],
     "contact.friction.law: python runs the class UserFriction of a Python module: give the "
     "module with --law-module FILE.py"),
    (["--law-module", LAW_MODULE, "--set", NORMAL % "Missing"],
     "--law-module {module}: no class Missing (contact.normal_compliance.class)"),
    (["--law-module", LAW_MODULE, "--set", FRICTION % "UserCompliance"],
     M + "UserCompliance: UserCompliance(**contact.friction.params) failed"),
    (["--law-module", LAW_MODULE, "--set", NORMAL % "NoSecondDerivative"],
     M + "NoSecondDerivative: not a contact law: no method second_derivative(x)"),
    (["--law-module", LAW_MODULE, "--set", NORMAL % "WrongShape"],
     M + "WrongShape: derivative(x) returned an array of shape (2,), expected (3,)"),
    (["--law-module", LAW_MODULE, "--set", NORMAL % "NotFinite"],
     M + "NotFinite: energy(x) returned non-finite values (NaN/Inf) at x = [-0.001, 0.0, "
         "0.001]"),
    (["--law-module", LAW_MODULE, "--set", NORMAL % "NumpyOnly"],
     M + "NumpyOnly: energy(x) on a UFL expression (SNES VI's forms) raised UFLException: "
         "UFL conditions cannot be evaluated as bool in a Python context; write the law "
         "with the primitives of vpcontact.model.primitives.backend(x)"),
    (["--law-module", LAW_MODULE, "--set", FRICTION % "NegativeMj"],
     M + "NegativeMj: m_j = -1.0: the largest decreasing slope of psi' (2.6) must be a "
         "number >= 0"),
    (["--set", "contact.normal_compliance={law: python, class: UserCompliance, c_nu: 1.0}"],
     "contact.normal_compliance.c_nu: not with law: python"),
    (["--set", "contact.friction.law=python"], "contact.friction.b: not with law: python"),
    (["--set", "contact.friction.class=UserFriction"],
     "contact.friction.class: only with law: python"),
    (["--set", "contact.normal_compliance={law: python}"],
     "contact.normal_compliance.class: required with law python"),
])
def test_refusals(extra, message, tmp_path, capsys):
    """One line, exit 2, before any step; nothing of the module runs without the option."""
    args = ["run", PAPER_CASE, *TINY, *extra, "--out", tmp_path / "out", "--quiet",
            "--no-plots"]
    assert cli_in_process(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    err = re.sub(r" \(line \d+\)", "", err)          # where the case file gives the key
    assert message.format(module=LAW_MODULE) in err, err
    assert not (tmp_path / "out" / "summary.json").exists()


def test_restart_with_an_edited_module_is_refused(tmp_path, capsys):
    """The module's bytes are in the fingerprint: the same module restarts, an edited one
    (one constant changed) is refused with a message naming the module."""
    module = tmp_path / "laws.py"
    shutil.copy(LAW_MODULE, module)
    laws = ["--law-module", module, *USER, "--set", "solver.method=condensed"]
    _run(tmp_path / "a", *laws, "--set", "output.checkpoint_every=2")
    checkpoint = tmp_path / "a" / "checkpoint_000002.npz"
    meta = json.loads(str(np.load(checkpoint)["meta"]))
    import hashlib
    assert meta["law_module"]["sha256"] == hashlib.sha256(module.read_bytes()).hexdigest()
    _run(tmp_path / "b", *laws, "--restart", checkpoint)
    np.testing.assert_allclose([s["norm_u_V"] for s in summary_steps(tmp_path / "b")],
                               [s["norm_u_V"] for s in summary_steps(tmp_path / "a")], rtol=1e-12)
    module.write_text(module.read_text().replace("0.5 * self.c * backend", "0.25 * self.c * "
                                                 "backend"))
    capsys.readouterr()
    assert cli_in_process(["run", PAPER_CASE, *TINY, *laws, "--restart", checkpoint, "--out",
                  tmp_path / "c", "--quiet", "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert f"was written with the law module {module} (SHA-256" in err
    assert "an edited law module is another law" in err


def _sections_hash(case, **extra) -> str:
    """The checkpoints' fingerprint recomputed: the sections, the time grid, extra keys."""
    import hashlib

    from vpcontact.io.canonical import stable_json
    data = {k: case.raw.get(k) for k in ("mesh", "material", "contact", "loads", "initial",
                                         "boundaries")}
    data.update(times=list(case.time.times), scheme=case.time.scheme,
                adaptive=case.time.adaptive, **extra)
    return hashlib.sha256(stable_json(data).encode()).hexdigest()


@pytest.mark.parametrize("part", ["contact", "viscoplastic"])
def test_fingerprint(part):
    """The paper case's fingerprint is the sections' hash as before (recomputed here), with
    or without a law module loaded; a case with a python law (contact or viscoplastic) adds
    the SHA-256 of the module's bytes."""
    import hashlib

    from conftest import make_case, paper_raw
    from vpcontact.io.checkpoint import case_fingerprint
    from vpcontact.io.lawfile import forget_law_module
    from vpcontact.model.lawmodule import load_law_module
    case = make_case(mesh={"n": 4}, time={"N": 4})
    assert case_fingerprint(case) == _sections_hash(case)
    raw = paper_raw()
    if part == "contact":
        raw["contact"]["normal_compliance"] = {"law": "python", "class": "UserCompliance",
                                               "params": {"c": 100.0}}
    else:
        raw["material"]["viscoplastic"] = {"law": "python", "class": "UserPerzyna"}
    user = make_case(raw, mesh={"n": 4}, time={"N": 4})
    load_law_module(LAW_MODULE)
    try:
        assert case_fingerprint(case) == _sections_hash(case)
        with_module = case_fingerprint(user)
    finally:
        forget_law_module()
    digest = hashlib.sha256(LAW_MODULE.read_bytes()).hexdigest()
    assert with_module == _sections_hash(user, law_module=digest)
    assert case_fingerprint(user) == _sections_hash(user)       # no module loaded (the API)
