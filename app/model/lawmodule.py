"""The user's law module of the command line: ``--law-module FILE.py`` imports FILE.py (on
every rank, once per process) and ``material.viscoplastic.law: python`` with ``class: Name``
builds ``Name(elasticity, **params)`` from it, ``contact.normal_compliance`` or
``contact.friction`` with ``law: python`` builds ``Name(**params)`` (app/model/userlaw.py
wraps and checks them).  A case file alone never runs code: without the option a ``python``
law is refused.  The SHA-256 of the module's bytes (``law_module_digest``,
app/io/lawfile.py, where the loaded module is recorded) enters the
checkpoints' fingerprint of a case with a python law, so a restart with an edited module is
refused.
"""
from __future__ import annotations

import hashlib
import importlib.util
import sys
import traceback
from pathlib import Path

from vpcontact.io.errors import CaseError
from vpcontact.io.lawfile import loaded_law_module, python_law_classes, remember_law_module
from vpcontact.model.material import Elasticity
from vpcontact.model.usercode import USER_ERRORS, raised

OPTION = "--law-module FILE.py"


def load_law_module(path) -> object:
    """Import a law module file (every rank of a run calls this).

    Args:
        path: the .py file given with --law-module.

    Returns:
        The module.

    Raises:
        CaseError: no such .py file, or importing it raised (its exception and line named;
            ``sys.exit`` in the module too: SystemExit).
    """
    path = Path(path)
    if path.suffix != ".py" or not path.is_file():
        raise CaseError(f"--law-module {path}: no such Python file (FILE.py)")
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    name = f"vpcontact_law_module_{abs(hash(str(path.resolve())))}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except USER_ERRORS as exc:          # the user's code: report what it raised
        sys.modules.pop(name, None)
        lines = [f.lineno for f in traceback.extract_tb(exc.__traceback__)
                 if Path(f.filename).resolve() == path.resolve()]
        at = f" (line {lines[-1]})" if lines else ""
        raise CaseError(f"--law-module {path}: importing it {raised(exc)}{at}") from None
    remember_law_module(path, module, digest)
    return module


def prepare_law_module(raw: dict, path) -> None:
    """The command line's part: import --law-module if given and check that it defines
    every class a ``python`` law of the case names; refuse a ``python`` law without it.

    Args:
        raw: the validated case mapping (Case.raw).
        path: the --law-module file, or None.

    Raises:
        CaseError: a python law without --law-module, an import error, a missing class.
    """
    wanted = python_law_classes(raw)
    if path is None:
        if wanted:
            key, name = wanted[0]
            raise CaseError(f"{key}.law: python runs the class {name} of a Python module: "
                            f"give the module with {OPTION} (a case file alone never runs "
                            "code)")
        return
    module = load_law_module(path)
    for key, name in wanted:
        _law_class(module, path, name, key)


def _law_class(module, path, name: str, key: str):
    """The class ``name`` of the module, else CaseError naming the module and the key."""
    cls = getattr(module, name, None)
    if not isinstance(cls, type):
        raise CaseError(f"--law-module {path}: no class {name} ({key}.class)")
    return cls


def python_law(vp, elasticity: Elasticity, key: str = "material.viscoplastic"):
    """The ``python`` law of a case: ``Class(elasticity, **params)`` from the loaded module.

    Args:
        vp: the case's Viscoplastic (``cls``, ``params``).
        elasticity: the elasticity E.
        key: the key path of the section, for messages.

    Returns:
        The UserLaw.

    Raises:
        CaseError: no module loaded, no such class, its constructor refused the params, or
            the law breaks the protocol (app/model/userlaw.py).
    """
    from vpcontact.model.userlaw import as_viscoplastic_law
    loaded = loaded_law_module()
    if loaded is None:
        raise CaseError(f"{key}.law: python runs the class {vp.cls} of a Python module: "
                        f"give the module with {OPTION} (a case file alone never runs code)")
    path, module = loaded
    cls = _law_class(module, path, vp.cls, key)
    where = f"--law-module {path}: class {vp.cls}"
    params = dict(vp.params or {})
    try:
        obj = cls(elasticity, **params)
    except USER_ERRORS as exc:          # the user's constructor: report what it raised
        raise CaseError(f"{where}: {vp.cls}(elasticity, **{key}.params) failed: "
                        f"{_what(exc)}") from None
    return as_viscoplastic_law(obj, elasticity, where, params)


def python_contact_laws(contact, skip=()) -> dict:
    """The contact laws of a case written by the user (``law: python``): ``Name(**params)``
    of the loaded module for contact.normal_compliance and contact.friction, checked and
    wrapped (app/model/userlaw.py: UserContactLaw); they replace the case's parts like the
    laws given through the Python API (app/model/contact_laws.py: ``replace_laws``).

    Args:
        contact: the case's Contact.
        skip: the parts given through the Python API instead ("normal", "friction").

    Returns:
        {"normal" | "friction": the law} of the case's python laws ({} if none).

    Raises:
        CaseError: no module loaded, no such class, its constructor refused the params, or
            the object is not a contact law.
    """
    fr = contact.friction
    specs = {"normal": ("contact.normal_compliance", contact.compliance_python),
             "friction": ("contact.friction", fr.python if fr is not None else None)}
    return {part: _contact_law(spec, key, part) for part, (key, spec) in specs.items()
            if spec is not None and part not in skip}


def _contact_law(spec, key: str, part: str):
    """``spec.cls(**spec.params)`` of the loaded module as a UserContactLaw."""
    from vpcontact.model.userlaw import UserContactLaw
    loaded = loaded_law_module()
    if loaded is None:
        raise CaseError(f"{key}.law: python runs the class {spec.cls} of a Python module: "
                        f"give the module with {OPTION} (a case file alone never runs code)")
    path, module = loaded
    cls = _law_class(module, path, spec.cls, key)
    where = f"--law-module {path}: class {spec.cls}"
    try:
        obj = cls(**spec.params)
    except USER_ERRORS as exc:          # the user's constructor: report what it raised
        raise CaseError(f"{where}: {spec.cls}(**{key}.params) failed: {_what(exc)}") \
            from None
    return UserContactLaw(obj, where, part, spec.params)


def _what(exc: BaseException) -> str:
    """A constructor's failure: the message of a TypeError or ValueError (the params do not
    fit), else what it raised (``raised``)."""
    return str(exc) if type(exc) in (TypeError, ValueError) else raised(exc)
