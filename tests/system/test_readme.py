"""The commands of the README and of the documentation's pages (docs/*.md) work as written, in a
new shell after `make demo`: every command line of their ```bash blocks has a form that needs no
activated environment (./vpcontact, mpirun -n 2 ./vpcontact, make), and the cheap ones run
verbatim from the repository root with a `python3` first on PATH that is not the project's (a
decoy that fails, as pyenv's lacks mpi4py)."""
import json
import os
import re
import shlex
import subprocess

import pytest

from conftest import MPI_ENV, ROOT

README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").glob("*.md"))]
AS_ROOT = "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 "
FORMS = ("./vpcontact ", "make ", "mpirun -n 2 ./vpcontact ", AS_ROOT + "mpirun -n 2 ./vpcontact ")
CHEAP = re.compile(r"\./vpcontact (check cases/\S+\.yaml|info|--help|\w+ --help)")


def page_commands(pages=PAGES) -> list[str]:
    """The command lines of the pages' ```bash blocks (continuations joined), as written
    (comments included: bash drops them), each once."""
    blocks = [b for page in pages
              for b in re.findall(r"^```bash\n(.*?)^```", page.read_text(), re.S | re.M)]
    lines = "\n".join(blocks).replace("\\\n", " ").splitlines()
    found = [ln.strip() for ln in lines if ln.strip() and not ln.strip().startswith("#")]
    return list(dict.fromkeys(found))


def _command(line: str) -> str:
    """The line without its trailing comment."""
    return shlex.join(shlex.split(line, comments=True))


COMMANDS = page_commands()
README_COMMANDS = page_commands([README])
CHEAP_COMMANDS = [ln for ln in COMMANDS if CHEAP.fullmatch(_command(ln))]


@pytest.fixture(scope="module")
def new_shell_env(tmp_path_factory):
    """The environment of a new shell that has not activated .venv: the test process's
    variables without the Python and MPI ones the tests set, and first on PATH a decoy
    python3 / python that fails loudly (the project's commands must not use them)."""
    decoy = tmp_path_factory.mktemp("decoy")
    for name in ("python3", "python"):
        (decoy / name).write_text("#!/bin/sh\necho 'decoy python3 used' >&2\nexit 97\n")
        (decoy / name).chmod(0o755)
    venv = str(ROOT / ".venv")
    path = [p for p in os.environ.get("PATH", "/usr/bin:/bin").split(":")
            if p and not p.startswith(venv)]
    drop = {"PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV", *MPI_ENV}
    env = {k: v for k, v in os.environ.items() if k not in drop and not k.startswith("OMPI_")}
    env["PATH"] = ":".join([str(decoy), *path])
    assert subprocess.run(["bash", "-c", "python3 -c 1"], env=env).returncode == 97
    return env


def _bash(line, env, timeout=300):
    proc = subprocess.run(["bash", "-c", line], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=timeout)
    assert "decoy python3 used" not in proc.stderr, line
    assert "Traceback" not in proc.stdout + proc.stderr, proc.stderr
    return proc


def test_every_command_has_a_form_that_works_in_a_new_shell():
    assert len(COMMANDS) >= 10
    targets = set(re.findall(r"^([\w-]+):", (ROOT / "Makefile").read_text(), re.M))
    for line in COMMANDS:
        cmd = _command(line)
        assert cmd.startswith(FORMS), f"README command not in an allowed form: {line}"
        words = shlex.split(cmd)
        if words[0] == "make":
            assert words[1] in targets, f"no make target {words[1]!r}: {line}"
        for word in words:              # no placeholders: every case file named exists
            if word.endswith(".yaml"):
                assert (ROOT / word).is_file(), f"{word} does not exist: {line}"
    for page in PAGES:
        text = page.read_text()
        assert not re.search(r"(?<![/\w])python3? -m vpcontact\b", text), page  # a bare python
        assert ".venv/bin/activate" not in text, page


def test_the_cheap_commands_are_found():
    """The README keeps showing check, info and the help (else the test below tests less),
    and the two commands: make setup and the paper case's run."""
    found = " ".join(ln for ln in README_COMMANDS if CHEAP.fullmatch(_command(ln)))
    assert "./vpcontact check cases/" in found and "./vpcontact info" in found
    assert "./vpcontact --help" in found and "./vpcontact run --help" in found
    commands = [_command(ln) for ln in README_COMMANDS]
    assert "make setup" in commands and "./vpcontact run cases/wang_cheng_2021.yaml" in commands


@pytest.mark.parametrize("line", CHEAP_COMMANDS)
def test_cheap_command_runs_verbatim(line, new_shell_env):
    proc = _bash(line, new_shell_env)
    assert proc.returncode == 0, proc.stderr
    words = shlex.split(_command(line))
    expected = {"check": "dofs:", "info": "dolfinx 0.5.2", "--help": "usage: vpcontact"}
    assert expected[words[-1] if words[-1] == "--help" else words[1]] in proc.stdout


@pytest.mark.mpi
def test_mpirun_command_runs_tiny(new_shell_env, tmp_path):
    """The README's `mpirun -n 2 ./vpcontact run ...` line, verbatim but for its output
    directory and a tiny resolution."""
    line = next(ln for ln in README_COMMANDS if " mpirun -n 2 ./vpcontact run " in f" {ln}")
    cmd = re.sub(r"--out \S+", f"--out {shlex.quote(str(tmp_path / 'np2'))}", _command(line))
    cmd += " --set mesh.n=4 --set time.N=2 --no-plots --quiet"
    env = {**new_shell_env, "OMPI_MCA_rmaps_base_oversubscribe": "1"}   # a 1-core machine
    proc = _bash(cmd, env)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    summary = json.loads((tmp_path / "np2" / "summary.json").read_text())
    assert summary["mpi_ranks"] == 2 and summary["status"] == "completed"
    assert len(summary["steps"]) == 2


def test_launcher_through_a_symlink_from_elsewhere(new_shell_env, tmp_path):
    """A symlink to a symlink to ./vpcontact, run from another directory."""
    (tmp_path / "a").symlink_to(ROOT / "vpcontact")
    (tmp_path / "b").symlink_to(tmp_path / "a")
    proc = subprocess.run([str(tmp_path / "b"), "--version"], cwd=tmp_path, env=new_shell_env,
                          capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stdout.startswith("vpcontact "), proc.stderr


def test_launcher_keeps_the_environment(new_shell_env, tmp_path):
    """OPENBLAS_NUM_THREADS: 1 when unset, the caller's value otherwise; other variables
    pass through.  Probed with a copy of the launcher that runs python -c instead of -m vpcontact
    (beside a symlink to .venv)."""
    code = "import os; print(os.environ['OPENBLAS_NUM_THREADS'], os.environ['VP_PROBE'])"
    text = (ROOT / "vpcontact").read_text()
    assert '-m vpcontact "$@"' in text
    (tmp_path / "vpcontact").write_text(text.replace('-m vpcontact "$@"', f'-c "{code}"'))
    (tmp_path / ".venv").symlink_to(ROOT / ".venv")
    for value, expected in ((None, "1 x"), ("3", "3 x")):
        env = {k: v for k, v in new_shell_env.items() if k != "OPENBLAS_NUM_THREADS"}
        env["VP_PROBE"] = "x"
        if value is not None:
            env["OPENBLAS_NUM_THREADS"] = value
        proc = subprocess.run(["bash", str(tmp_path / "vpcontact")], env=env,
                              capture_output=True, text=True)
        assert proc.stdout.strip() == expected, proc.stderr


def test_launcher_without_the_environment(tmp_path, new_shell_env):
    """A copy of the launcher in a directory without .venv: one line, exit 2."""
    (tmp_path / "vpcontact").write_bytes((ROOT / "vpcontact").read_bytes())
    (tmp_path / "vpcontact").chmod(0o755)
    proc = subprocess.run([str(tmp_path / "vpcontact"), "info"], env=new_shell_env,
                          capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and "run `make setup` first" in proc.stderr


def test_make_help_lists_every_target():
    make = (ROOT / "Makefile").read_text()
    phony = re.search(r"^\.PHONY: (.*)$", make, re.M).group(1).split()
    env = {k: v for k, v in os.environ.items() if k not in ("MAKEFLAGS", "MAKELEVEL", "MFLAGS")}
    out = subprocess.run(["make", "-s", "help"], cwd=ROOT, env=env, capture_output=True,
                         text=True).stdout   # as typed in a shell, not as a sub-make of make test
    for target in set(phony) - {"help"}:
        assert re.search(rf"^make {target}\b", out, re.M), target
    assert "./vpcontact" in out and "python3 -m vpcontact" not in out
