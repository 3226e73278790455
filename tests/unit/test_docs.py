"""The README's case-file reference matches the schema (regenerate: make docs)."""
from conftest import ROOT
from vpcontact.io.docs import END, START, render
from vpcontact.io.schema import SCHEMA


def test_readme_reference_is_current():
    text = (ROOT / "README.md").read_text()
    assert START in text and END in text
    assert render(text) == text, "README.md is out of date: run `make docs`"


def test_every_schema_key_is_documented():
    text = (ROOT / "README.md").read_text()

    def keys(schema, prefix=""):
        for k, sub in schema.get("properties", {}).items():
            yield prefix + k
            yield from keys(sub, prefix + k + ".")
    for key in keys(SCHEMA):
        assert f"`{key}`" in text, key
