"""A law written by the user from the command line (`material.viscoplastic.law: python`,
`--law-module FILE.py`) and from the Python API (`Simulation(case, comm, law=...)`): Perzyna's
law written as a user would (tests/userlaws/perzyna_law.py) gives the built-in perzyna's run
to 1e-12 (norms, iterations and contact.csv), explicit and implicit; the refusals (no
--law-module, no such class, a law that breaks the protocol, an import error) exit 2 with one
line naming the key, the option or the module and class.  The runs are cli.main in this
process, on the paper's case at h = k = 1/4."""
import csv
import functools
import json
import re

import numpy as np
import pytest

from conftest import (
    PAPER_CASE,
    ROOT,
    cli_in_process,
    contact_rows,
    make_case,
    paper_raw,
    summary_steps,
)

LAW_MODULE = ROOT / "tests" / "userlaws" / "perzyna_law.py"
TINY = ["--set", "mesh.n=4", "--set", "time.N=4"]
PYTHON_LAW = ["--set", "material.viscoplastic={law: python, class: UserPerzyna, params: "
                       "{lambda1: 100.0, lambda2: 100.0}}"]
KEYS = ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y", "max_vm", "max_kappa")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The built-in perzyna and the python law, explicit and implicit: {(law, scheme): dir}."""
    out = {}
    for scheme in ("explicit", "implicit"):
        for law, extra in (("perzyna", []), ("python", ["--law-module", LAW_MODULE,
                                                        *PYTHON_LAW])):
            d = tmp_path_factory.mktemp(f"{law}_{scheme}")
            code = cli_in_process(["run", PAPER_CASE, "--out", d, "--quiet", "--no-plots",
                                   "--overwrite", *TINY, "--set", f"time.scheme={scheme}",
                                   *extra])
            assert code == 0, (law, scheme)
            out[law, scheme] = d
    return out


@pytest.mark.parametrize("scheme", ["explicit", "implicit"])
def test_python_perzyna_equals_the_builtin(runs, scheme):
    ref, user = summary_steps(runs["perzyna", scheme]), summary_steps(runs["python", scheme])
    assert len(ref) == len(user) == 4
    for a, b in zip(ref, user):
        assert a["newton_iterations"] == b["newton_iterations"]
        for key in KEYS:
            assert b[key] == pytest.approx(a[key], rel=1e-12, abs=1e-300), key
    assert ref[-1]["max_kappa"] > 0                       # the law flowed
    (state0, c0), (state1, c1) = contact_rows(runs["perzyna", scheme]), \
        contact_rows(runs["python", scheme])
    assert state0 == state1 and c0.shape == c1.shape
    scale = np.abs(c0).max(axis=0)
    assert np.all(np.abs(c1 - c0) <= 1e-12 * scale)
    summary = json.loads((runs["python", scheme] / "summary.json").read_text())
    assert summary["laws"]["viscoplastic"]["name"] == "user perzyna"


def test_api_law_equals_the_builtin(runs):
    """Simulation(case, comm, law=class with its constants) on the perzyna case gives the
    command line's perzyna run."""
    from mpi4py import MPI

    from userlaws.perzyna_law import UserPerzyna
    from vpcontact.simulation import Simulation
    case = make_case(paper_raw(), mesh={"n": 4}, time={"N": 4})
    sim = Simulation(case, MPI.COMM_WORLD,
                     law=functools.partial(UserPerzyna, lambda1=100.0, lambda2=100.0))
    assert sim.run().status == "completed"
    assert type(sim.problem.law).__name__ == "UserLaw"
    for a, b in zip(summary_steps(runs["perzyna", "explicit"]), sim.steps):
        for key in KEYS:
            assert b[key] == pytest.approx(a[key], rel=1e-12, abs=1e-300), key


@pytest.mark.parametrize("extra, message", [
    ([], "material.viscoplastic.law: python runs the class UserPerzyna of a Python module: "
         "give the module with --law-module FILE.py (a case file alone never runs code)"),
    (["--law-module", ROOT / "tests" / "userlaws" / "nothing.py"],
     "--law-module {root}/tests/userlaws/nothing.py: no such Python file"),
    (["--law-module", LAW_MODULE, "--set", "material.viscoplastic.class=Missing"],
     "--law-module {module}: no class Missing (material.viscoplastic.class)"),
    (["--law-module", LAW_MODULE, "--set", "material.viscoplastic.class=WrongM"],
     "--law-module {module}: class WrongM: m = 0: the number of internal variables kappa "
     "must be an integer >= 1"),
    (["--law-module", LAW_MODULE, "--set", "material.viscoplastic.class=WrongShape"],
     "--law-module {module}: class WrongShape: Gk returned an array of shape (6,), expected "
     "(6, 1)"),
    (["--law-module", LAW_MODULE, "--set", "material.viscoplastic.class=NotFinite"],
     "--law-module {module}: class NotFinite: G or Gk returned non-finite values (NaN/Inf) "
     "at 6 cell(s) at sigma = 0, eps = 0, kappa = 0"),
    (["--law-module", LAW_MODULE, "--set", "material.viscoplastic.params={lambda1: 1.0}"],
     "UserPerzyna(elasticity, **material.viscoplastic.params) failed"),
    (["--law-module", LAW_MODULE, "--set", "material.viscoplastic.class=RaisesInG"],
     "--law-module {module}: class RaisesInG: G(sigma, eps, kappa) raised KeyError: 'x' at "
     "sigma = 0, eps = 0, kappa = 0"),
    (["--law-module", LAW_MODULE, "--set", "material.viscoplastic.class=FailingInit"],
     "--law-module {module}: class FailingInit: FailingInit(elasticity, "
     "**material.viscoplastic.params) failed: raised RuntimeError: no licence for this law"),
    (["--law-module", LAW_MODULE, "--set", "material.viscoplastic.class=ExitsInInit"],
     "--law-module {module}: class ExitsInInit: ExitsInInit(elasticity, "
     "**material.viscoplastic.params) failed: raised SystemExit"),
])
@pytest.mark.parametrize("command", ["run", "check"])
def test_refusals(command, extra, message, tmp_path, capsys):
    """One line, exit 2, before any step; nothing of the module runs without the option."""
    args = [command, PAPER_CASE, *TINY, *PYTHON_LAW, *extra]
    if command == "run":
        args += ["--out", tmp_path / "out", "--quiet", "--no-plots"]
    assert cli_in_process(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert message.format(root=ROOT, module=LAW_MODULE) in err, err
    assert not (tmp_path / "out" / "summary.json").exists()


def test_import_error_names_the_line(tmp_path, capsys):
    bad = tmp_path / "bad_law.py"
    bad.write_text("import numpy\n\nraise ValueError('no constants')\n")
    assert cli_in_process(["check", PAPER_CASE, *PYTHON_LAW, "--law-module", bad]) == 2
    err = capsys.readouterr().err
    assert f"--law-module {bad}: importing it raised ValueError: no constants (line 3)" in err


@pytest.mark.parametrize("body, raised", [
    ("import sys\nsys.exit(0)\n", "raised SystemExit (line 2)"),
    ("import sys\n\nsys.exit()\n", "raised SystemExit (line 3)"),
    ("import sys\nsys.exit(3)\n", "raised SystemExit: 3 (line 2)"),
])
@pytest.mark.parametrize("command", ["run", "check"])
def test_a_module_that_exits_is_refused(command, body, raised, tmp_path, capsys):
    """A module that calls sys.exit when imported is refused like one that raises: one
    line, exit 2, nothing computed (it ended the process with its own code, 0 or 3, and no
    message before)."""
    module = tmp_path / "exits.py"
    module.write_text(body)
    args = [command, PAPER_CASE, *TINY, *PYTHON_LAW, "--law-module", module]
    if command == "run":
        args += ["--out", tmp_path / "out", "--quiet", "--no-plots"]
    assert cli_in_process(args) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"vpcontact: error: --law-module {module}: importing it {raised}"
    assert not (tmp_path / "out").exists()


def _failed_run(tmp_path, capsys, cls: str, params: str) -> dict:
    """A run of the python law ``cls`` that must fail cleanly: exit 1, one error line and no
    traceback, summary.json with status failed; returns its failure."""
    out = tmp_path / "out"
    code = cli_in_process(["run", PAPER_CASE, *TINY, "--law-module", LAW_MODULE, "--set",
                           f"material.viscoplastic={{law: python, class: {cls}, params: "
                           f"{{{params}}}}}", "--out", out, "--quiet", "--no-plots"])
    err = capsys.readouterr().err
    assert code == 1, err
    assert "Traceback" not in err and "this is a bug" not in err, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed"
    return summary["failure"]


def test_a_law_that_exits_during_the_run_fails_the_step(tmp_path, capsys):
    """G calls sys.exit(0) once sigma is not zero: the explicit update of step 2 (G at
    sigma_1, the first nonzero stress; sigma_0 = 0) fails, naming the law; before, the run
    ended with exit 0 and no summary."""
    failure = _failed_run(tmp_path, capsys, "ExitsInG", "lambda1: 100.0, lambda2: 100.0")
    assert failure["step"] == 2
    assert failure["reason"] == f"--law-module {LAW_MODULE}: class ExitsInG: " \
                                "G(sigma, eps, kappa) raised SystemExit"


def test_wrong_shapes_during_the_run_fail_the_step(tmp_path, capsys):
    """Gk flat once sigma is not zero: the explicit update of step 2 fails (exit 1, a
    summary); before, the run ended as bad input (exit 2) without summary.json after a
    step was computed."""
    failure = _failed_run(tmp_path, capsys, "ShapeLater", "lambda1: 100.0, lambda2: 100.0")
    assert failure["step"] == 2
    assert re.fullmatch(f"--law-module {re.escape(str(LAW_MODULE))}: class ShapeLater: Gk "
                        r"returned an array of shape \(\d+,\), expected \(\d+, 1\)",
                        failure["reason"]), failure["reason"]


def test_a_law_that_raises_where_its_rate_is_estimated(tmp_path, capsys):
    """A law without a rate bound (its rate estimated at every accepted state) whose G
    raises above ||sigma||_VM = 15: the paper's run reaches max ||sigma||_VM = 17.97 at
    step 1, so the estimate at sigma_1 fails (a warning), and the explicit update of step 2,
    G at the same sigma_1, fails the step with the law's message and a summary; before,
    the rate watch ended the run with a traceback and no summary.json."""
    failure = _failed_run(tmp_path, capsys, "RaisesAbove",
                          "lambda1: 100.0, lambda2: 100.0, level: 15.0")
    assert failure["step"] == 2
    assert failure["reason"] == f"--law-module {LAW_MODULE}: class RaisesAbove: " \
                                "G(sigma, eps, kappa) raised RuntimeError: stress too large " \
                                "for my law"


class _Frozen:
    """A user law with m = 2 that does not flow (G = 0, Gk = 0): kappa keeps kappa_0."""

    m = 2

    def __init__(self, elasticity):
        self.elasticity = elasticity

    def G(self, sigma, eps, kappa):
        return np.zeros_like(sigma)

    def Gk(self, sigma, eps, kappa):
        return np.zeros_like(kappa)


def test_kappa0_expression_starts_every_component_of_a_law_with_m_2():
    """kappa0 = "1 + x" with a user law of m = 2: both components start at the cell average
    of 1 + x, the centroid's value (exact for a linear function); it failed with a UFL shape
    error before."""
    from dolfinx.mesh import compute_midpoints
    from mpi4py import MPI

    from vpcontact.simulation import Simulation
    raw = paper_raw()
    raw["material"]["viscoplastic"]["kappa0"] = "1 + x"
    sim = Simulation(make_case(raw, mesh={"n": 4}, time={"N": 1}), MPI.COMM_WORLD,
                     law=_Frozen)
    assert sim.run().status == "completed"
    p = sim.problem
    cells = np.arange(p.state.kappa_cells.shape[0], dtype=np.int32)
    x = compute_midpoints(p.disc.mesh, p.disc.mesh.topology.dim, cells)[:, 0]
    np.testing.assert_allclose(p.state.kappa_cells, np.column_stack([1 + x, 1 + x]),
                               rtol=1e-12)


def test_convergence_study_of_a_python_law(tmp_path):
    """`convergence --law-module`: Perzyna written as a user would gives the built-in's
    errors (levels 4, 8 against 16); without the option the study is refused (exit 2)."""
    common = [PAPER_CASE, "--levels", "4", "8", "--reference", "16", "--no-cache", "--quiet"]
    assert cli_in_process(["convergence", *common, "--out", tmp_path / "b"]) == 0
    assert cli_in_process(["convergence", *common, "--out", tmp_path / "p", "--law-module",
                           LAW_MODULE, *PYTHON_LAW]) == 0
    rows = {k: list(csv.DictReader(open(tmp_path / k / "convergence.csv"))) for k in "bp"}
    assert [r["level"] for r in rows["p"]] == ["4", "8"]
    for a, b in zip(rows["b"], rows["p"], strict=True):
        assert float(b["error"]) == pytest.approx(float(a["error"]), rel=1e-10)
    assert cli_in_process(["convergence", *common, "--out", tmp_path / "x", *PYTHON_LAW]) == 2


def test_run_cache_key_follows_the_law_module(tmp_path):
    """The run cache's key of a python-law case holds the SHA-256 of its module's bytes: an
    edited module is another law (another key), the same bytes elsewhere the same key; a
    case without a python law keeps the key of its sections alone."""
    from vpcontact.case import load_raw, validate
    from vpcontact.io.lawfile import forget_law_module
    from vpcontact.model.lawmodule import prepare_law_module
    from vpcontact.studies.runcache import cache_key
    raw = load_raw(PAPER_CASE, ["mesh.n=4", "time.N=4"])
    plain = cache_key(validate(raw, PAPER_CASE))
    case = validate(load_raw(PAPER_CASE, ["mesh.n=4", "time.N=4", PYTHON_LAW[1]]), PAPER_CASE)
    text = LAW_MODULE.read_text()
    keys = []
    for name, body in (("a.py", text), ("b.py", text), ("c.py", text + "\n# edited\n")):
        (tmp_path / name).write_text(body)
        try:
            prepare_law_module(case.raw, tmp_path / name)
            keys.append(cache_key(case))
        finally:
            forget_law_module()
    assert keys[0] == keys[1] != keys[2] and plain not in keys
    assert cache_key(validate(raw, PAPER_CASE)) == plain
