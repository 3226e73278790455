"""The documentation: the case-file reference matches the schema (regenerate: make docs),
every relative link of the README and the pages leads to a file, the demos and docstrings
become valid pages, and the Sphinx build passes with warnings as errors."""
import os
import re
import shutil
import subprocess
import sys
import time

import pytest

from conftest import ROOT
from vpcontact.case.reference import END, PAGE, START, render
from vpcontact.case.schema import SCHEMA

sys.path.insert(0, str(ROOT / "docs" / "_ext"))
from lightscript import to_markdown  # noqa: E402
from plaindoc import _warnings, safe_lines  # noqa: E402

REFERENCE = ROOT / PAGE
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def test_reference_is_current():
    text = REFERENCE.read_text()
    assert START in text and END in text
    assert render(text) == text, f"{PAGE} is out of date: run `make docs`"


def test_every_schema_key_is_documented():
    text = REFERENCE.read_text()

    def keys(schema, prefix=""):
        for k, sub in schema.get("properties", {}).items():
            yield prefix + k
            yield from keys(sub, prefix + k + ".")
    for key in keys(SCHEMA):
        assert f"| `{key}`" in text, key


def test_relative_links_lead_to_files():
    """Links and images of the README and the pages (not URLs, not anchors of the page)."""
    for page in PAGES:
        for target in re.findall(r"\]\(([^)\s]+)\)", page.read_text()):
            if re.match(r"[a-z]+:", target) or target.startswith("#"):
                continue
            path = (page.parent / target.split("#")[0]).resolve()
            assert path.exists(), f"{page.name}: {target}"


def test_cited_paths_exist():
    """Every file or folder of the repository the README and the pages name (app/..., forms/...,
    tests/..., ...) is there: the pages follow the code when it moves."""
    cited = re.compile(r"(?<![\w/.])(?:app|forms|meshes|tests|cases|demos|docs)/[\w./*-]*[\w/*]")
    missing = [f"{page.name}: {path}" for page in PAGES
               for path in sorted(set(cited.findall(page.read_text())))
               if not path.startswith("docs/_build") and not list(ROOT.glob(path.rstrip("/")))]
    assert not missing, missing


def test_readme_is_an_entry_page():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 300
    assert text.count("![") == 1                       # one picture
    for page in ("user-guide", "case-file", "solvers", "verification", "model",
                 "architecture", "performance"):
        assert f"(docs/{page}.md)" in text, page


def test_light_script_to_page():
    script = "\n".join([
        "# ---", "# jupyter:", "#   jupytext: {}", "# ---", "",
        "# # Title", "#", "# Some *text*.", "",
        "# +", "import os", "", "# a comment in a cell", "x = 1", "", "# -", "",
        "y = 2", "", "z = 3  # trailing", "", "# More text", "#     indented code", "",
        "# a comment touching code", "w = 4"])
    assert to_markdown(script) == "\n".join([
        "# Title", "", "Some *text*.", "",
        "```python", "import os", "", "# a comment in a cell", "x = 1", "", "y = 2", "",
        "z = 3  # trailing", "```", "",
        "More text", "    indented code", "",
        "```python", "# a comment touching code", "w = 4", "```", ""])


@pytest.mark.parametrize("doc", [
    ["The norm |u_tau| and u_nu^+ times k*r, with the prefix vpcontact_ and ``a|b*``."],
    ["Step:", "    sigma_n = E eps(u_n) + H_n,", "    kappa_n = kappa_{n-1}.", "Then more."],
    ["Terms:", "- one", "- two,", "  continued", "The end."],
    ["Text::", "", "    |literal| *kept*", "", "After."],
    ["A list", "- item", "", ":param x: the |x| value", "    continued", ":returns: y"],
])
def test_plain_docstrings_become_valid_rest(doc):
    assert _warnings(doc) != [] or doc[0].startswith("Text")     # as written: warnings
    assert _warnings(safe_lines(doc)) == []


def test_literal_blocks_keep_their_text():
    doc = ["Text::", "", "    |literal| *kept*_", "", "After |x|."]
    assert safe_lines(doc) == ["Text::", "", "    |literal| *kept*_", "", r"After \|x\|."]


@pytest.mark.slow
def test_sphinx_build_passes_with_warnings_as_errors(tmp_path):
    """``make docs``'s build (-W: a warning fails it) into a temporary directory, API
    reference and demos included (make test runs it: 22-30 s of CPU when measured).  Read
    and written by two processes (-j 2; the extensions declare themselves parallel safe and
    a warning in either still fails the build): 31 s -> 19 s of wall time on two cores."""
    # a copy of the pages (with the demos beside them), so that the stubs Sphinx generates
    # (docs/generated) are this build's own, whatever else builds the docs meanwhile
    src = tmp_path / "docs"
    shutil.copytree(ROOT / "docs", src, ignore=shutil.ignore_patterns("_build", "generated"))
    (tmp_path / "demos").symlink_to(ROOT / "demos")
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-j", "2", "-b", "html",
         "-d", str(tmp_path / "doctrees"), str(src), str(tmp_path / "html")],
        capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr[-4000:]
    html = tmp_path / "html"
    assert (html / "generated" / "api" / "vpcontact.simulation.html").is_file()
    assert (html / "generated" / "demos" / "demo_wang_cheng.html").is_file()
    assert "Args" not in (html / "generated" / "api" / "vpcontact.case.reference.html").read_text()
    print(f"sphinx build: {time.perf_counter() - start:.1f} s")
