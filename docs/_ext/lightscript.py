"""The demos as pages: a jupytext light script (demos/*.py) turned into MyST Markdown.

In the light format a paragraph of comment lines is text and everything else is code; a
cell between ``# +`` and ``# -`` is code whatever it holds, and the ``# ---`` header at the
top is metadata.  ``setup`` registers a hook that writes one page per demo into
``generated/demos/`` before Sphinx reads its sources.
"""
from __future__ import annotations

from pathlib import Path

HERE = Path(__file__).resolve().parent
DEMOS = HERE.parents[1] / "demos"
OUT = HERE.parent / "generated" / "demos"


def _strip_header(lines: list[str]) -> list[str]:
    """The lines after the ``# ---`` metadata header, if the script starts with one."""
    if lines and lines[0].strip() == "# ---":
        end = next(i for i in range(1, len(lines)) if lines[i].strip() == "# ---")
        return lines[end + 1:]
    return lines


def _paragraphs(lines: list[str]):
    """(is_text, lines) for each paragraph; a ``# +`` ... ``# -`` cell is one code paragraph."""
    para, cell = [], False
    for line in lines + [""]:
        if line.strip() == "# +" and not para:
            cell = True
            continue
        if cell and line.strip() == "# -":
            while para and not para[-1].strip():
                para.pop()
            yield False, para
            para, cell = [], False
        elif cell or line.strip():
            para.append(line)
        elif para:
            yield all(ln.startswith("#") for ln in para), para
            para = []


def to_markdown(script: str) -> str:
    """A light script as a MyST page: comment paragraphs become text, the rest code blocks.

    Args:
        script: the text of a jupytext light script.

    Returns:
        The page, with consecutive code paragraphs in one ```python block.
    """
    blocks: list[tuple[bool, list[str]]] = []
    for is_text, para in _paragraphs(_strip_header(script.splitlines())):
        if is_text:
            blocks.append((True, [ln[2:] if ln.startswith("# ") else ln[1:] for ln in para]))
        elif blocks and not blocks[-1][0]:
            blocks[-1][1].extend(["", *para])
        else:
            blocks.append((False, list(para)))
    out = []
    for is_text, para in blocks:
        out.append("\n".join(para) if is_text else "\n".join(["```python", *para, "```"]))
    return "\n\n".join(out) + "\n"


def write_pages(demos: Path = DEMOS, out: Path = OUT) -> list[Path]:
    """Write one page per demo (only where its text changed, so a rebuild reads none again).

    Args:
        demos: the folder of the light scripts.
        out: the folder of the pages.

    Returns:
        The pages' paths.
    """
    out.mkdir(parents=True, exist_ok=True)
    pages = []
    for script in sorted(demos.glob("*.py")):
        page = out / f"{script.stem}.md"
        text = to_markdown(script.read_text())
        if not page.is_file() or page.read_text() != text:
            tmp = page.with_suffix(f".{script.stat().st_mtime_ns}.tmp")
            tmp.write_text(text)
            tmp.replace(page)
        pages.append(page)
    return pages


def setup(app):
    """Sphinx extension: the demo pages are written when the builder starts."""
    app.connect("builder-inited", lambda _app: write_pages())
    return {"parallel_read_safe": True, "parallel_write_safe": True}
