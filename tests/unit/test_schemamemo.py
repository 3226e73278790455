"""The memo of case mappings that passed the schema check (app/case/schemamemo.py): a case
run again skips the check and jsonschema's import; everything else is checked as before."""
import copy
import os
import subprocess
import sys
from pathlib import Path

import pytest

from vpcontact.case import load_raw, schemamemo, validate
from vpcontact.io.errors import CaseError

CASE = str(Path(__file__).resolve().parents[2] / "cases" / "wang_cheng_2021.yaml")


@pytest.fixture
def memo_file(tmp_path, monkeypatch):
    path = tmp_path / schemamemo.FILE
    monkeypatch.setattr(schemamemo, "_path", lambda: path)
    return path


def _raw(*overrides):
    return load_raw(CASE, list(overrides))


def test_second_process_skips_jsonschema(tmp_path):
    """The same case in two fresh processes: the first imports jsonschema and remembers the
    pass, the second validates without it, to the same Case."""
    code = ("import sys; from vpcontact.case import load_raw, validate; "
            f"c = validate(load_raw({CASE!r}, ['mesh.n=16']), 'case'); "
            "print('jsonschema' in sys.modules, repr(c.raw), c.numerics.method, c.time.N)")
    env = {**os.environ, "VPCONTACT_CACHE": str(tmp_path / "cache")}
    runs = [subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                           text=True, check=True).stdout.split(" ", 1) for _ in range(2)]
    assert runs[0][0] == "True" and runs[1][0] == "False"
    assert runs[0][1] == runs[1][1]
    assert len((tmp_path / "cache" / schemamemo.FILE).read_text().split()) == 1


def test_a_changed_mapping_is_checked_again(memo_file):
    """After a pass is remembered, one changed value is checked (and refused) as without the
    memo; a refused mapping is never remembered."""
    validate(_raw("mesh.n=16"), "case")
    assert len(memo_file.read_text().split()) == 1
    bad = _raw("mesh.n=16")
    bad["material"] = {**copy.deepcopy(bad["material"]), "Ee": 1.0}
    refused = r"material.Ee \(line 13\): unknown key; did you mean 'E'"
    for _ in range(2):
        with pytest.raises(CaseError, match=refused):
            validate(bad, "case")
    assert len(memo_file.read_text().split()) == 1


def test_digest_tells_values_and_key_types_apart():
    """1, 1.0 and True are different mappings; a non-string key (JSON would write 1 as '1')
    or a value JSON cannot write gives no digest (always checked)."""
    keys = {schemamemo.digest({"a": v}) for v in (1, 1.0, True, "1", [1], None, -0.0, 0.0)}
    assert None not in keys and len(keys) == 8
    assert schemamemo.digest({"a": {"b": 2}}) == schemamemo.digest({"a": {"b": 2}})
    assert schemamemo.digest({1: "x"}) is None
    assert schemamemo.digest({"a": [{2: "x"}]}) is None
    assert schemamemo.digest({"a": object()}) is None


def test_the_schema_is_part_of_the_digest(monkeypatch):
    view = {"name": "x"}
    before = schemamemo.digest(view)
    monkeypatch.setattr(schemamemo, "_schema_text", lambda: '{"type": "object"}')
    assert schemamemo.digest(view) != before


def test_the_memo_keeps_the_last_entries(memo_file):
    keys = [f"{i:064x}" for i in range(schemamemo.MAX_ENTRIES + 8)]
    for k in keys:
        schemamemo.remember(k)
    kept = memo_file.read_text().split()
    assert kept == keys[-schemamemo.MAX_ENTRIES:]
    assert schemamemo.passed(keys[-1]) and not schemamemo.passed(keys[0])
    schemamemo.remember(keys[-5])                     # once only, moved to the end
    assert memo_file.read_text().split()[-1] == keys[-5]
    assert len(memo_file.read_text().split()) == schemamemo.MAX_ENTRIES


def test_unusable_memo_means_checking_every_time(tmp_path, monkeypatch):
    """A memo that cannot be written (its directory is a file) or read (binary garbage):
    validation works and checks the mapping."""
    (tmp_path / "file").write_text("")
    monkeypatch.setattr(schemamemo, "_path", lambda: tmp_path / "file" / schemamemo.FILE)
    validate(_raw("mesh.n=16"), "case")
    assert not schemamemo.passed(schemamemo.digest({"name": "x"}))
    garbage = tmp_path / "garbage"
    garbage.write_bytes(b"\xff\xfe\x00")
    monkeypatch.setattr(schemamemo, "_path", lambda: garbage)
    assert not schemamemo.passed("00")
    validate(_raw("mesh.n=16"), "case")
