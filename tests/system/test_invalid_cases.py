"""Every file of tests/cases_invalid/ ends in one clear error line naming the key,
exit code 2, no traceback, and no output directory."""
import re
from pathlib import Path

import pytest

from conftest import ROOT, run_cli

MARKER = Path("/tmp/vpcontact_hacked")     # what 17_python_tag.yaml would write if executed
CORPUS = sorted((ROOT / "tests" / "cases_invalid").glob("*.yaml"))


def _expected(path: Path) -> str:
    head = path.read_bytes().split(b"\n", 1)[0].decode()
    m = re.match(r"# expect: (.+)", head)
    assert m, f"{path.name}: the first line must be '# expect: <text in the message>'"
    return m.group(1).strip()


def test_the_corpus_is_large_enough():
    assert len(CORPUS) >= 20


@pytest.mark.parametrize("path", CORPUS, ids=[p.stem for p in CORPUS])
def test_invalid_case(path, tmp_path):
    out = tmp_path / "out"
    marker = _state(MARKER)            # a marker left by anything else must not matter
    proc = run_cli(["run", path, "--out", out])
    assert proc.returncode == 2, (proc.returncode, proc.stdout[-2000:], proc.stderr[-2000:])
    assert "Traceback" not in proc.stdout + proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, proc.stderr              # one clear line
    assert lines[0].startswith("vpcontact: error: ") and path.name in lines[0]
    assert _expected(path) in lines[0], lines[0]
    assert not out.exists()
    assert _state(MARKER) == marker, "the case file ran a command"


def _state(path: Path):
    """None if the file is absent, else (size, mtime): did a run create or change it?"""
    try:
        st = path.stat()
    except FileNotFoundError:
        return None
    return st.st_size, st.st_mtime_ns
