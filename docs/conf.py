"""Sphinx configuration of the vpcontact documentation (``make docs``: HTML in docs/_build).

The pages are Markdown (MyST); the API reference is generated from the docstrings
(autosummary over the package, autodoc, napoleon for the Google-style Args/Returns); the
demos become pages through ``_ext/lightscript.py``.
"""
import importlib.util
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent / "_ext"))

import vpcontact  # noqa: E402

project = "vpcontact"
author = "the vpcontact authors"
version = release = vpcontact.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "lightscript",
    "plaindoc",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_ext", "figures"]

# Markdown: $...$ and $$...$$ math as in the pages and the demos; anchors for ## headings
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3

# API reference: every module of the package, found by walking it (api.md), so a module
# added or moved is picked up without listing it.  Importing vpcontact.__main__ would run
# the command line: mocked, and so skipped by the walk.
autosummary_generate = True
autosummary_mock_imports = ["vpcontact.__main__"]
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_ivar = True          # Attributes: a field list, not a second description


def _drop_stale_stubs(app):
    """Remove the API pages of modules that no longer exist (moved or renamed)."""
    for stub in (Path(app.srcdir) / "generated" / "api").glob("*.rst"):
        try:
            found = importlib.util.find_spec(stub.stem) is not None
        except ImportError:
            found = False
        if not found:
            stub.unlink(missing_ok=True)


def setup(app):
    """Stale API pages go before autosummary writes the current ones."""
    app.connect("builder-inited", _drop_stale_stubs, priority=100)

html_theme = "alabaster"
html_title = f"vpcontact {release}"
html_static_path = []
