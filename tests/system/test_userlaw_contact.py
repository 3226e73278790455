"""Contact laws written by the user, given through the Python API
(`Simulation(case, comm, contact_laws={"normal": P, "friction": psi})`), and restarts of runs
given laws through the Python API.

A user's ScalarLaw that writes normal compliance (4.1) and friction (4.2) as the paper states
them (closed forms typed here, not the built-in classes) gives the built-in run to 1e-12 with
both step solvers (the condensed solver takes them by its numpy path, the built-in laws by
its compiled kernel); a user compliance p = c (r^+)^2 gives the condensed solver's run = SNES
VI's to 1e-8.  A checkpoint written by a run with API laws restarts with the same laws (and
gives the uninterrupted run) and is refused with other laws, without them, and by the command
line.  Runs in this process on the paper's case at h = k = 1/4."""
import functools

import numpy as np
import pytest
from mpi4py import MPI

from conftest import make_case, paper_raw
from vpcontact import kernels
from vpcontact.io.errors import CaseError
from vpcontact.model.laws import ScalarLaw
from vpcontact.model.primitives import backend

KEYS = ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y", "max_vm", "max_kappa")
TINY = {"mesh": {"n": 4}, "time": {"N": 4}}


class Compliance(ScalarLaw):
    """p(r) = c (r^+)^m (m = 1: the paper's (4.1), P = c/2 (r^+)^2)."""

    name = "user compliance"

    def __init__(self, c, m=1):
        self.c, self.m = c, m

    def energy(self, r):
        if self.m == 1:
            return 0.5 * self.c * backend(r).pos(r) ** 2
        return self.c / (self.m + 1.0) * backend(r).pos(r) ** (self.m + 1.0)

    def derivative(self, r):
        return self.c * backend(r).pos(r) ** self.m

    def second_derivative(self, r):
        ops = backend(r)
        return ops.where(ops.gt(r, 0.0), self.m * self.c * ops.pos(r) ** (self.m - 1), 0.0)


class Friction(ScalarLaw):
    """The paper's (4.2): psi'(rho) = b - c1 rho up to u1, then c2 (rho - u1) + b - c1 u1."""

    name = "user friction"

    def __init__(self, b, c1, c2, u1):
        self.b, self.c1, self.c2, self.u1 = b, c1, c2, u1
        self.m_j = c1

    def energy(self, rho):
        ops, b, c1, c2, u1 = backend(rho), self.b, self.c1, self.c2, self.u1
        return ops.where(ops.le(rho, u1), b * rho - 0.5 * c1 * rho**2,
                         0.5 * c2 * (rho - u1) ** 2 + (b - c1 * u1) * (rho - u1) + b * u1
                         - 0.5 * c1 * u1**2)

    def derivative(self, rho):
        ops, b, c1, c2, u1 = backend(rho), self.b, self.c1, self.c2, self.u1
        return ops.where(ops.le(rho, u1), b - c1 * rho, c2 * (rho - u1) + b - c1 * u1)

    def second_derivative(self, rho):
        ops = backend(rho)
        return ops.where(ops.le(rho, self.u1), -self.c1, self.c2)


def _run(method, contact_laws=None, law=None, outdir=None, restart=None, raw=None,
         **sections):
    from vpcontact.observers import Checkpointer
    from vpcontact.post.divergence import BlowUpMonitor
    from vpcontact.simulation import Simulation
    case = make_case(raw, **TINY, solver={"method": method}, **sections)
    sim = Simulation(case, MPI.COMM_WORLD, outdir=outdir, restart=restart, law=law,
                     contact_laws=contact_laws)
    sim.add(BlowUpMonitor())
    if outdir is not None:
        sim.add(Checkpointer())
    summary = sim.run()
    assert summary.status == "completed"
    return sim


def _same(a, b, rtol):
    """Every step's norms and the last u of two runs agree to rtol."""
    assert len(a.steps) == len(b.steps) == 4
    for x, y in zip(a.steps, b.steps):
        for key in KEYS:
            assert y[key] == pytest.approx(x[key], rel=rtol, abs=1e-300), key
    ua, ub = a.problem.u.x.array, b.problem.u.x.array
    assert np.abs(ub - ua).max() <= rtol * np.abs(ua).max()


@pytest.mark.parametrize("method", ["condensed", "snes_vi"])
def test_user_laws_of_the_paper_equal_the_builtin(method):
    """(4.1) and (4.2) written by the user = the built-in laws to 1e-12; the report and
    (2.6) read the user's laws (their names, m_j)."""
    ref = _run(method)
    user = _run(method, {"normal": Compliance(100.0), "friction": Friction(1.0, 60.0, 60.0,
                                                                           0.01)})
    _same(ref, user, 1e-12)
    assert max(s["max_kappa"] for s in ref.steps) > 0
    if method == "condensed":           # the user's laws: numpy; the built-in: compiled
        assert user.solver.gamma3_problem.contact.mod is None
        assert ref.solver.gamma3_problem.contact.mod is not None or kernels.load() is None
    from vpcontact.post.lawreport import law_report
    report = law_report(user.problem)["contact"]
    assert (report["normal"]["name"], report["friction"]["name"]) == \
        ("user compliance", "user friction")
    assert user.diagnostics.m_j == 60.0


def test_user_power_compliance_condensed_equals_snes_vi():
    """p = c (r^+)^2 (c = 1e4: comparable to c_nu r at r ~ g): the condensed solver's run
    equals SNES VI's to 1e-8, and differs from (4.1)'s (the law took effect)."""
    laws = {"normal": Compliance(1.0e4, 2)}
    fast, snes = _run("condensed", laws), _run("snes_vi", laws)
    _same(snes, fast, 1e-8)
    linear = _run("condensed", {"normal": Compliance(1.0e4 * 0.012)})
    diff = np.abs(linear.problem.u.x.array - fast.problem.u.x.array).max()
    assert diff > 1e-6 * np.abs(fast.problem.u.x.array).max()


def test_refusals():
    """A part the case lacks, an unknown part, an object that is not a ScalarLaw."""
    from vpcontact.model.contact_laws import ContactLaw, NormalCompliance, replace_laws
    case_law = ContactLaw(normal=NormalCompliance(1.0))
    with pytest.raises(ValueError, match=r"contact_laws\['friction'\]: the case has no "
                                         r"contact.friction"):
        replace_laws(case_law, {"friction": Friction(1.0, 1.0, 1.0, 1.0)})
    with pytest.raises(ValueError, match="'memory' is not a replaceable part"):
        replace_laws(case_law, {"memory": Compliance(1.0)})
    with pytest.raises(ValueError, match="str is not a ScalarLaw"):
        replace_laws(case_law, {"normal": "p = c r"})
    assert replace_laws(case_law, None) is case_law
    raw = paper_raw()
    del raw["contact"]["friction"]
    with pytest.raises(CaseError, match="contact_laws.*no contact.friction"):
        _run("condensed", {"friction": Friction(1.0, 1.0, 1.0, 1.0)}, raw=raw)


@pytest.fixture(scope="module")
def checkpointed(tmp_path_factory):
    """A run with a viscoplastic and a contact law given through the API, checkpoints at
    steps 2 and 4."""
    from userlaws.perzyna_law import UserPerzyna
    laws = {"law": functools.partial(UserPerzyna, lambda1=100.0, lambda2=100.0),
            "contact_laws": {"normal": Compliance(100.0)}}
    out = tmp_path_factory.mktemp("api_laws")
    return _run("condensed", outdir=out, output={"checkpoint_every": 2}, **laws), out, laws


def test_restart_with_the_same_api_laws(checkpointed):
    """New objects with the same classes and constants: the restart from step 2 gives the
    uninterrupted run."""
    from userlaws.perzyna_law import UserPerzyna
    from vpcontact.io.checkpoint import Checkpoint
    full, out, _ = checkpointed
    again = _run("condensed", restart=Checkpoint(out / "checkpoint_000002.npz"),
                 law=functools.partial(UserPerzyna, lambda1=100.0, lambda2=100.0),
                 contact_laws={"normal": Compliance(100.0)})
    _same(full, again, 1e-12)


@pytest.mark.parametrize("change", ["contact", "viscoplastic", "none"])
def test_restart_with_other_laws_is_refused(checkpointed, change):
    from userlaws.perzyna_law import UserPerzyna
    from vpcontact.io.checkpoint import Checkpoint
    _, out, laws = checkpointed
    laws = dict(laws)
    if change == "contact":
        laws["contact_laws"] = {"normal": Compliance(200.0)}
    elif change == "viscoplastic":
        laws["law"] = functools.partial(UserPerzyna, lambda1=50.0, lambda2=100.0)
    else:
        laws = {}
    with pytest.raises(CaseError, match="the laws given through the Python API differ from "
                                        "the checkpointed run's"):
        _run("condensed", restart=Checkpoint(out / "checkpoint_000002.npz"), **laws)


def test_fingerprint(checkpointed):
    """The fingerprint of a case without API laws is the sections' hash as before (recomputed
    here); with API laws it differs, and the command line's check refuses the checkpoint."""
    import hashlib

    from vpcontact.io.canonical import stable_json
    from vpcontact.io.checkpoint import Checkpoint, case_fingerprint
    _, out, _ = checkpointed
    case = make_case(**TINY)
    data = {k: case.raw.get(k) for k in ("mesh", "material", "contact", "loads", "initial",
                                         "boundaries")}
    data.update(times=list(case.time.times), scheme=case.time.scheme,
                adaptive=case.time.adaptive)
    today = hashlib.sha256(stable_json(data).encode()).hexdigest()
    assert case_fingerprint(case) == case_fingerprint(case, None) == today
    assert case_fingerprint(case, {"viscoplastic": {"class": "x"}}) != today
    why = Checkpoint(out / "checkpoint_000002.npz").check(
        make_case(**TINY, solver={"method": "condensed"}, output={"checkpoint_every": 2}))
    assert "was written with laws given through the Python API (viscoplastic: " \
           "userlaws.perzyna_law.UserPerzyna (lambda1 = 100.0, lambda2 = 100.0)" in why
