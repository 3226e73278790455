"""The ``--law-module FILE.py`` this process has loaded (its path, the module and the SHA-256
of its bytes as imported) and the ``python`` laws a case names.  The law builders
(app/model/lawmodule.py, which imports the file and builds the laws) and the checkpoints'
fingerprint and meta (app/io/checkpoint.py: ``law_module``) share them here, below both.
"""
from __future__ import annotations

from pathlib import Path

_loaded: dict = {}          # "path", "module", "sha256": the module of --law-module


def remember_law_module(path: Path, module: object, sha256: str) -> None:
    """Record the law module this process has imported (replacing an earlier one).

    Args:
        path: the .py file given with --law-module.
        module: the imported module.
        sha256: the SHA-256 of the file's bytes as imported (hex).
    """
    _loaded.update(path=path, module=module, sha256=sha256)


def loaded_law_module() -> tuple[Path, object] | None:
    """The law module this process has imported.

    Returns:
        (its path, the module), or None if none is loaded.
    """
    if "module" not in _loaded:
        return None
    return _loaded["path"], _loaded["module"]


def law_module_digest() -> dict | None:
    """The loaded law module's file and the SHA-256 of its bytes as imported.

    Returns:
        {"path", "sha256"}, or None if no module is loaded.
    """
    if "module" not in _loaded:
        return None
    return {"path": str(_loaded["path"]), "sha256": _loaded["sha256"]}


def forget_law_module() -> None:
    """Forget the loaded module (a process that runs several cases, e.g. the tests)."""
    _loaded.clear()


def python_law_classes(raw: dict) -> list[tuple[str, str]]:
    """The ``python`` laws a case names.

    Args:
        raw: the case mapping (Case.raw).

    Returns:
        [(key path, class name)] of material.viscoplastic, of each materials group and of
        contact.normal_compliance and contact.friction.
    """
    sections = [("material", raw.get("material"))]
    sections += [(f"materials.{group}", section)
                 for group, section in (raw.get("materials") or {}).items()]
    out = [(f"{path}.viscoplastic", sec["viscoplastic"]["class"]) for path, sec in sections
           if isinstance(sec, dict) and isinstance(sec.get("viscoplastic"), dict)
           and sec["viscoplastic"].get("law") == "python"]
    contact = raw.get("contact") or {}
    return out + [(f"contact.{key}", contact[key]["class"])
                  for key in ("normal_compliance", "friction")
                  if isinstance(contact.get(key), dict)
                  and contact[key].get("law") == "python"]
