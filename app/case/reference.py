"""The case-file reference (docs/case-file.md), generated from the schema so it cannot drift.

``make docs`` (``python -m vpcontact.case.reference``) rewrites the block between the markers of
docs/case-file.md; tests/unit/test_docs.py fails when the page is out of date.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from vpcontact.case.schema import SCHEMA
from vpcontact.solvers.options import DEFAULT_PETSC

START, END = "<!-- case-reference:start -->", "<!-- case-reference:end -->"
PAGE = "docs/case-file.md"


def _type(sub: dict) -> str:
    if "enum" in sub:
        return " \\| ".join(f"`{v}`" for v in sub["enum"])
    if "oneOf" in sub:
        return " or ".join(_type(s) for s in sub["oneOf"])
    t = sub.get("type", "")
    if t == "array":
        return "list"
    values = sub.get("additionalProperties")
    if t == "object" and isinstance(values, dict) and "propertyNames" not in sub:
        return f"map: group -> {_type(values)}"      # loads keyed by boundary group
    bounds = []
    if "minimum" in sub:
        bounds.append(f">= {sub['minimum']}")
    if "exclusiveMinimum" in sub:
        bounds.append(f"> {sub['exclusiveMinimum']}")
    if "maximum" in sub:
        bounds.append(f"<= {sub['maximum']}")
    if "exclusiveMaximum" in sub:
        bounds.append(f"< {sub['exclusiveMaximum']}")
    return t + (f" ({', '.join(bounds)})" if bounds else "")


def _rows(schema: dict, prefix: str = ""):
    required = set(schema.get("required", []))
    for key, sub in schema.get("properties", {}).items():
        path = f"{prefix}{key}"
        req = key in required
        if sub.get("type") == "object" and "properties" in sub:
            yield path, req, "section", "", sub.get("description", "")
            yield from _rows(sub, path + ".")
        else:
            default = json.dumps(sub["default"]) if "default" in sub else ""
            yield path, req, _type(sub), default, sub.get("description", "")


def reference_markdown() -> str:
    """The case-file reference from the schema.

    Returns:
        A Markdown table of every key (type, default, meaning) and the default PETSc
        options.
    """
    lines = ["| key | type / allowed | default | meaning |", "|---|---|---|---|"]
    for path, req, typ, default, desc in _rows(SCHEMA):
        name = f"`{path}`" + (" (required)" if req else "")
        desc = desc.replace("|", "\\|").replace("<", "\\<")     # a table cell, no HTML
        lines.append(f"| {name} | {typ} | {default} | {desc} |")
    lines += ["", "Default PETSc options: " + ", ".join(f"`{k} {v}`" for k, v in
                                                   DEFAULT_PETSC.items()) + "."]
    return "\n".join(lines)


def render(page: str) -> str:
    """The page with its generated block replaced.

    Args:
        page: the page's text, with the START and END markers.

    Returns:
        The text with ``reference_markdown()`` between the markers.
    """
    head, rest = page.split(START, 1)
    _, tail = rest.split(END, 1)
    return f"{head}{START}\n{reference_markdown()}\n{END}{tail}"


def main() -> int:
    """``python -m vpcontact.case.reference [PAGE]``: regenerate the page's reference block.

    Returns:
        The exit status, 0.
    """
    path = Path(sys.argv[1] if len(sys.argv) > 1 else PAGE)
    path.write_text(render(path.read_text()))
    print(f"updated the case-file reference in {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
