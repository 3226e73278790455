"""Docstrings written as plain text, shown by autodoc without reStructuredText warnings.

The package's docstrings are plain text with ``literal`` spans and Google-style sections
(napoleon): they write |u_tau|, u_nu^+, k*r, prefix_ and formulas on indented lines, which
reStructuredText reads as substitutions, emphasis, references and block quotes.  After
napoleon, each docstring is made safe: those characters are escaped outside literals, an
indented run inside a paragraph becomes a literal block, a list or block that ends without
a blank line gets one.  The result is parsed with docutils; a docstring that still gives a
warning is shown as a literal block, so ``sphinx-build -W`` holds whatever the prose.
"""
from __future__ import annotations

import copy
import functools
import io
import re

from docutils.core import publish_doctree
from docutils.frontend import get_default_settings
from docutils.parsers.rst import Parser, directives, roles
from sphinx.ext import autosummary

_DIRECTIVE, _ROLE = directives.directive, roles.role      # docutils' own, before Sphinx's
_LITERAL = re.compile(r"(``.+?``|:[\w:+-]+:`[^`]+`)")     # spans left as they are
_BULLET = re.compile(r"(\s*)([-*+]|\d+\.|#\.) ")
_FIELD = re.compile(r"\s*:[^:]+:")
_IGNORED = ("Unknown interpreted text role", "Unknown directive type", "No role entry",
            "No directive entry", 'Trying "')


def _escape(text: str) -> str:
    """Escape | * and a word's trailing _ outside literal spans and roles."""
    parts = _LITERAL.split(text)
    for i in range(0, len(parts), 2):
        part = re.sub(r"(?<!\\)([|*])", r"\\\1", parts[i])
        parts[i] = re.sub(r"(?<=\w)_(?!\w)", r"\\_", part)
    return "".join(parts)


def _indent(line: str) -> int:
    """The line's indentation."""
    return len(line) - len(line.lstrip())


def _kind(line: str) -> str:
    """What a paragraph's first line opens: a bullet, field, directive or plain text."""
    if _BULLET.match(line):
        return "bullet"
    if line.lstrip().startswith(".. "):
        return "directive"
    return "field" if _FIELD.match(line) else "plain"


def safe_lines(lines: list[str]) -> list[str]:
    """The docstring's lines made safe for reStructuredText (see the module docstring).

    Args:
        lines: the docstring after napoleon, one line each.

    Returns:
        The new lines.
    """
    out: list[str] = []
    literal = None          # indentation under which lines are a literal block
    para = None             # (kind, indentation) of the paragraph being read
    for line in lines:
        if not line.strip():
            out.append(line)
            para = para if para is not None and para[0] == "inline" else None
            continue
        ind = _indent(line)
        if literal is not None and ind > literal:
            out.append(line)
            continue
        if literal is not None and para is not None and para[0] == "inline":
            out.append("")                  # end of a literal block made below
            para = None
        literal = None
        if para is not None:
            kind, base = para
            if kind == "plain" and ind > base:          # an indented formula: literal
                out += ["", "::", "", line]
                literal, para = base, ("inline", base)
                continue
            if ind < base or (kind == "bullet" and ind <= base and not _BULLET.match(line)) \
                    or (kind == "plain" and _BULLET.match(line)):
                out.append("")
                para = None
        if para is None:
            para = (_kind(line), ind)
        out.append(_escape(line))
        if line.rstrip().endswith("::") and para[0] != "directive":
            literal = ind
    return out


def _warnings(lines: list[str]) -> list[str]:
    """docutils' warnings and errors for the text, its own directives and roles only."""
    return list(_text_warnings("\n".join(lines)))


@functools.cache
def _settings():
    """docutils' settings for the check, made once (making them costs more than a parse)."""
    settings = get_default_settings(Parser)
    settings.report_level, settings.halt_level = 2, 5
    settings.file_insertion_enabled = settings.raw_enabled = False
    return settings


@functools.lru_cache(maxsize=4096)
def _text_warnings(text: str) -> tuple[str, ...]:
    """The warnings of one text (autosummary and autodoc each process a docstring)."""
    stream = io.StringIO()
    settings = copy.copy(_settings())
    settings.warning_stream = stream
    patched = directives.directive, roles.role
    directives.directive, roles.role = _DIRECTIVE, _ROLE
    try:
        publish_doctree(text, settings=settings)
    except Exception as exc:                    # noqa: BLE001 - any failure: not safe
        return (repr(exc),)
    finally:
        directives.directive, roles.role = patched
    found = re.findall(r"\((?:WARNING|ERROR|SEVERE)/\d\) (.*)", stream.getvalue())
    return tuple(m for m in found if not m.startswith(_IGNORED))


def _as_literal(lines: list[str]) -> list[str]:
    """The original docstring as a literal block, after its escaped first line."""
    first = [_escape(lines[0]), ""] if lines and not _warnings([_escape(lines[0])]) else []
    rest = lines[1:] if first else lines
    return first + ["::", ""] + ["    " + ln for ln in rest] + [""]


def _whole_literals(summary: str) -> str:
    """A summary that ends inside a ``literal`` (Sphinx 5 cuts at a period there) cut before it."""
    if summary.count("``") % 2:
        summary = summary[:summary.rfind("``")].rstrip(" ,;:(") + " ..."
    return summary


class Autosummary(autosummary.Autosummary):
    """autosummary's directive, its summaries cut whole (``_whole_literals``)."""

    def get_items(self, names):
        """The items of the table, as autosummary's, with their summaries cut whole."""
        return [(name, sig, _whole_literals(summary), real)
                for name, sig, summary, real in super().get_items(names)]


def setup(app):
    """Sphinx extension: before napoleon keep each docstring, after it make it safe."""
    app.add_directive("autosummary", Autosummary, override=True)
    originals: dict = {}        # the docstrings as written, kept until napoleon has run

    def keep(_app, what, name, _obj, _options, lines):
        originals[(what, name)] = list(lines)

    def make_safe(_app, what, name, _obj, _options, lines):
        new = safe_lines(lines)
        if _warnings(new):
            new = _as_literal(originals.pop((what, name), lines))
        lines[:] = new

    app.connect("autodoc-process-docstring", keep, priority=100)
    app.connect("autodoc-process-docstring", make_safe, priority=900)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
