"""Facts the README and the pages state about the project, checked against the project: the
number of shipped cases, the Python modules the pages suggest (the environment has them),
the gmsh .msh formats that load (tests/unit/test_meshfile.py, test_msh_formats, loads them)."""
import importlib.util
import re

from conftest import ROOT

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
NUMBERS = {w: i for i, w in enumerate(
    "zero one two three four five six seven eight nine ten eleven twelve thirteen fourteen "
    "fifteen sixteen seventeen eighteen nineteen twenty".split())}
MSH_FORMATS = ("4.1", "2.2")            # both load, ASCII and binary (test_msh_formats)


def test_readme_counts_the_shipped_cases():
    said = re.findall(r"cases/ has (\w+) shipped cases", (ROOT / "README.md").read_text())
    assert said, "the README no longer states the number of shipped cases"
    shipped = len(list((ROOT / "cases").glob("*.yaml")))
    assert [NUMBERS.get(w, w) for w in said] == [shipped] * len(said)


def test_the_pages_suggest_only_modules_the_environment_has():
    """The pages' Python blocks import, and their text names for reading the outputs, only
    modules that are installed here (pandas was suggested for history.csv: it is not)."""
    for page in PAGES:
        text = page.read_text()
        code = "\n".join(re.findall(r"```python\n(.*?)```", text, re.S))
        names = set(re.findall(r"^\s*(?:import|from) ([A-Za-z_]\w*)", code, re.M))
        names |= {"pandas", "polars"} & set(re.findall(r"\w+", text))
        for name in names - {"vpcontact", "my_laws"}:
            assert importlib.util.find_spec(name) is not None, f"{page.name}: {name}"


def test_the_pages_name_every_msh_format_that_loads():
    """Where a page states the .msh format, it names 4.1 and 2.2 (ASCII and binary)."""
    stated = 0
    for page in PAGES:
        for sentence in re.findall(r"\.msh`? \(format [^)]*\)", page.read_text()):
            stated += 1
            assert all(v in sentence for v in MSH_FORMATS) and "binary" in sentence, \
                f"{page.name}: {sentence}"
    assert stated >= 2                  # the user guide and the case-file reference
