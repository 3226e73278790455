"""vpcontact: viscoplastic contact with normal compliance, unilateral constraint and
nonmonotone friction (Wang & Cheng 2021), on FEniCSx/dolfinx 0.5.2.

Importing the package changes nothing in the process (no environment variable, no MPI
start-up); the command line prepares its process itself (app/cli/entry.py).  The names of
the Python API below are imported on first use::

    from vpcontact import Simulation, validate
"""

# The one statement of the version: pyproject.toml reads it from here (a literal, so
# setuptools reads it without importing the package).
__version__ = "0.1.0"

# the public API: name -> the module that defines it (imported on first use, PEP 562)
_API = {
    "Simulation": "vpcontact.simulation",
    "RunResult": "vpcontact.simulation",
    "run": "vpcontact.simulation",
    "Case": "vpcontact.case",
    "load_case": "vpcontact.case",
    "validate": "vpcontact.case",
    "Observer": "vpcontact.observers",
    "FieldOutput": "vpcontact.observers",
    "StopRun": "vpcontact.observers",
}

__all__ = ["__version__", *_API]


def __getattr__(name: str):
    """The API's names, imported from their modules on first use."""
    if name not in _API:
        raise AttributeError(f"module 'vpcontact' has no attribute {name!r}")
    import importlib
    return getattr(importlib.import_module(_API[name]), name)
