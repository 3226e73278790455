"""Every file of tests/cases_invalid/ is refused with one clear error line naming the key, and
nothing is written or executed.

Each file goes through the checks of ``vpcontact check`` in this process: the case read and
validated, then (data that can only be checked on the mesh) the check's set-up of the mesh and
the problem.  The refusal is a CaseError, the error the command line turns into its one
``vpcontact: error:`` line and exit code 2 (app/cli/main.py); one command-line run keeps that
path covered: exit code 2, one line, no traceback, no output directory.
"""
import re
from pathlib import Path

import pytest

from conftest import ROOT, run_cli

MARKER = Path("/tmp/vpcontact_hacked")     # what 17_python_tag.yaml would write if executed
CORPUS = sorted((ROOT / "tests" / "cases_invalid").glob("*.yaml"))
# refused while the run builds the problem (a rigid motion left free), after validation
SMOKE = ROOT / "tests" / "cases_invalid" / "63_one_of_two_parts_held.yaml"


def _expected(path: Path) -> str:
    head = path.read_bytes().split(b"\n", 1)[0].decode()
    m = re.match(r"# expect: (.+)", head)
    assert m, f"{path.name}: the first line must be '# expect: <text in the message>'"
    return m.group(1).strip()


def test_the_corpus_is_large_enough():
    assert len(CORPUS) >= 20


def _refusal(path: Path) -> str:
    """The error line of ``vpcontact check <path>``, reached in this process: the case read
    and validated, then the check's set-up on the mesh (app/cli/commands.py cmd_check) raise
    a CaseError, which the command line prints as this line."""
    from mpi4py import MPI

    from vpcontact.case import load_case
    from vpcontact.cli.checkrun import report
    from vpcontact.io.errors import CaseError
    from vpcontact.io.messages import error_line
    with pytest.raises(CaseError) as refused:
        report(load_case(str(path)), MPI.COMM_WORLD)
    return error_line(str(refused.value))


@pytest.mark.parametrize("path", CORPUS, ids=[p.stem for p in CORPUS])
def test_invalid_case(path, tmp_path, monkeypatch, capfd):
    monkeypatch.chdir(tmp_path)        # anything written to the working directory shows
    marker = _state(MARKER)            # a marker left by anything else must not matter
    line = _refusal(path)
    out, err = capfd.readouterr()
    assert "Traceback" not in out + err
    assert err == "", err              # the error line alone: no other line on stderr
    assert len([ln for ln in line.splitlines() if ln.strip()]) == 1    # one clear line
    assert line.startswith("vpcontact: error: ") and path.name in line
    assert _expected(path) in line, line
    assert list(tmp_path.iterdir()) == []
    assert _state(MARKER) == marker, "the case file ran a command"


def test_the_command_line_exits_2_with_one_line(tmp_path):
    """The command line's path: a case refused after validation ends the run with exit code
    2 and the error line alone on stderr; no traceback, no output directory."""
    out = tmp_path / "out"
    marker = _state(MARKER)
    proc = run_cli(["run", SMOKE, "--out", out])
    assert proc.returncode == 2, (proc.returncode, proc.stdout[-2000:], proc.stderr[-2000:])
    assert "Traceback" not in proc.stdout + proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, proc.stderr              # one clear line
    assert lines[0].startswith("vpcontact: error: ") and SMOKE.name in lines[0]
    assert _expected(SMOKE) in lines[0], lines[0]
    assert lines[0] == _refusal(SMOKE)               # the line the in-process check gives
    assert not out.exists()
    assert _state(MARKER) == marker, "the case file ran a command"


def _state(path: Path):
    """None if the file is absent, else (size, mtime): did a run create or change it?"""
    try:
        st = path.stat()
    except FileNotFoundError:
        return None
    return st.st_size, st.st_mtime_ns
