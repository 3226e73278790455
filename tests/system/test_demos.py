"""The demos in demos/ run serially and under mpirun -n 2, pass their own checks, give the same
final norms on one and two ranks (1e-8 relative), and compute what `./vpcontact run` computes
for the same case (1e-12 relative): a demo goes through the Python API, not the CLI."""
import json
import os
import re
import subprocess
import sys

import pytest

from conftest import MPI_ENV, PAPER_CASE, ROOT, run_cli

DEMOS = sorted(p.name for p in (ROOT / "demos").glob("*.py"))

# The command line run of each demo's final result: the case file, its --set options (and
# other options).
CLI_EQUIVALENT = {
    "demo_wang_cheng.py": (PAPER_CASE, []),
    "demo_stiff_viscosity.py": (PAPER_CASE, ["mesh.n=8", "time.N=16",
                                             "material.viscoplastic.lambda1=10",
                                             "time.scheme=implicit"]),
    "demo_custom_law.py": (PAPER_CASE, ["mesh.n=8", "time.N=8",
                                        "material.viscoplastic={law: python, class: SinhCreep, "
                                        "params: {A: 0.001, s0: 5.0}}"],
                           ["--law-module", ROOT / "demos" / "demo_custom_law.py"]),
}
FINAL = re.compile(r"^final norm_u_V = (\S+) norm_sigma_Q = (\S+)$", re.M)


def run_demo(name: str, nprocs: int, workdir) -> tuple[float, float]:
    """Run demos/<name> as a script (under mpirun -n nprocs if > 1) from ``workdir``, with
    its outputs in workdir/out; check it exits 0 with its checks passed.  Returns its final
    norms (||u_N||_V, ||sigma_N||_Q)."""
    cmd = [sys.executable, str(ROOT / "demos" / name)]
    if nprocs > 1:
        cmd = ["mpirun", "-n", str(nprocs), *cmd]
    env = {**os.environ, **MPI_ENV, "PYTHONPATH": str(ROOT),
           "VPCONTACT_DEMO_OUT": str(workdir / "out")}
    proc = subprocess.run(cmd, cwd=workdir, env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "checks: all passed" in proc.stdout, proc.stdout
    assert "Traceback" not in proc.stderr, proc.stderr
    found = FINAL.findall(proc.stdout)
    assert len(found) == 1, proc.stdout          # printed once, by rank 0
    return float(found[0][0]), float(found[0][1])


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """The serial run of a demo, once per module: (final norms, its working directory)."""
    done = {}

    def get(name):
        if name not in done:
            workdir = tmp_path_factory.mktemp(name.removesuffix(".py"))
            done[name] = run_demo(name, 1, workdir), workdir
        return done[name]
    return get


def test_every_demo_is_tested():
    assert DEMOS, "no demos in demos/"
    assert set(DEMOS) == set(CLI_EQUIVALENT), "add the demo's CLI run to CLI_EQUIVALENT"


@pytest.mark.parametrize("name", DEMOS)
def test_demo_equals_the_cli(name, serial, tmp_path):
    from concurrent.futures import ThreadPoolExecutor
    case, overrides, *options = CLI_EQUIVALENT[name]
    sets = [arg for item in overrides for arg in ("--set", item)]
    with ThreadPoolExecutor(1) as pool:       # the command line's run beside the demo's
        cli = pool.submit(run_cli, ["run", case, "--out", tmp_path / "cli", "--quiet", *sets,
                                    *(options[0] if options else [])])
        norms, _ = serial(name)
        proc = cli.result()
    assert proc.returncode == 0, proc.stdout + proc.stderr
    last = json.loads((tmp_path / "cli" / "summary.json").read_text())["steps"][-1]
    assert norms == pytest.approx((last["norm_u_V"], last["norm_sigma_Q"]), rel=1e-12)


def test_demo_writes_the_fields(serial):
    """demo_wang_cheng.py writes solution.xdmf through the FieldOutput observer where
    VPCONTACT_DEMO_OUT points: u, sigma, sigma_vm and kappa at t_0, ..., t_16."""
    _, workdir = serial("demo_wang_cheng.py")
    xdmf = (workdir / "out" / "solution.xdmf").read_text()
    assert (workdir / "out" / "solution.h5").is_file()
    for field in ("u", "sigma", "sigma_vm", "kappa"):
        assert xdmf.count(f'Attribute Name="{field}"') == 17, field
    times = re.findall(r'<Time Value="([^"]+)"', xdmf)
    assert [float(t) for t in times] == pytest.approx([n / 16 for n in range(17)])


@pytest.mark.mpi
@pytest.mark.parametrize("name", DEMOS)
def test_demo_on_two_ranks(name, serial, tmp_path):
    norms = run_demo(name, 2, tmp_path)
    assert norms == pytest.approx(serial(name)[0], rel=1e-8)
