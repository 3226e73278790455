"""A case mapping against the JSON schema (app/case/schema.py): every key alone (type, range,
allowed values, unknown keys with the closest known one), the errors in one line; and the
schema's defaults filled in."""
from __future__ import annotations

import copy
import difflib
import re
from typing import TYPE_CHECKING

from vpcontact.case import schemamemo
from vpcontact.case.schema import SCHEMA
from vpcontact.io.casekey import GROUP_MAPS
from vpcontact.io.errors import CaseError

if TYPE_CHECKING:
    import jsonschema


def check_schema(data: dict, source: str) -> None:
    """Validate the mapping as given against SCHEMA.  A mapping that passed before (the same
    digest, app/case/schemamemo.py) is not checked again, and jsonschema is not imported for
    it.

    Args:
        data: the case mapping (not default-filled).
        source: the case file, for messages.

    Raises:
        CaseError: one line: the first error (by key path), then the others.
    """
    view = _schema_view(data, source)
    key = schemamemo.digest(view)
    if schemamemo.passed(key):
        return
    import jsonschema  # 44 ms: only for a mapping not seen passing (schemamemo)
    validator = jsonschema.Draft7Validator(SCHEMA)
    errors = sorted(validator.iter_errors(view), key=lambda e: list(e.absolute_path))
    if errors:       # one line: the first error, then the others
        msgs = [_explain(e) for e in errors]
        more = f" (also: {'; '.join(msgs[1:])})" if len(msgs) > 1 else ""
        raise CaseError(f"{source}: {msgs[0]}{more}")
    schemamemo.remember(key)


def fill_defaults(data: dict, schema: dict = SCHEMA) -> None:
    """Insert the schema's defaults for missing keys of the present (sub)sections.

    Args:
        data: the case mapping (changed in place).
        schema: the schema of ``data`` (a section's, in the recursion).
    """
    for key, sub in schema.get("properties", {}).items():
        if key not in data and "default" in sub:
            data[key] = copy.deepcopy(sub["default"])
        if isinstance(data.get(key), dict) and sub.get("type") == "object":
            fill_defaults(data[key], sub)
    entries = schema.get("additionalProperties")      # a map of sections (materials)
    if isinstance(entries, dict) and "properties" in entries:
        for key, value in data.items():
            if key not in schema.get("properties", {}) and isinstance(value, dict):
                fill_defaults(value, entries)


def _key_path(err: jsonschema.ValidationError) -> str:
    return ".".join(str(p) for p in err.absolute_path) or "(top level)"


def _explain(err: jsonschema.ValidationError) -> str:
    path = _key_path(err)
    if err.validator == "additionalProperties":
        allowed = sorted(err.schema.get("properties", {}))
        extra = sorted(set(err.instance) - set(allowed))
        msgs = []
        for key in extra:
            shown = key if re.fullmatch(r"\w+", str(key)) else repr(key)
            where = f"{path}.{shown}" if path != "(top level)" else shown
            close = difflib.get_close_matches(str(key), allowed, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            msgs.append(f"{where}: unknown key{hint} (allowed: {', '.join(allowed)})")
        return "; ".join(msgs)
    if err.validator == "required":
        return f"{path}: {err.message}"
    if err.validator == "pattern" and path == "name":
        return f"{path}: {err.instance!r} cannot name an output directory (allowed: " \
               "letters, digits, '_', '.' and '-', starting with a letter or digit)"
    if err.validator == "enum":
        return f"{path}: {err.instance!r} is not allowed (allowed: " \
               f"{', '.join(map(str, err.validator_value))})"
    if err.validator == "oneOf":      # the reason of the one alternative of the right type
        typed = [e for e in err.context if e.validator != "type" and not e.relative_path]
        if len(typed) == 1:
            return f"{path}: {typed[0].message}"
    return f"{path}: {err.message}"


def _schema_view(data: dict, source: str) -> dict:
    """The case with the keys of the group maps of loads as strings, for jsonschema (which
    names object keys by strings; YAML reads a physical tag as an integer key)."""
    materials = data.get("materials")
    if isinstance(materials, dict) and not all(isinstance(k, str) for k in materials):
        both = [k for k in materials if not isinstance(k, str) and str(k) in materials]
        if both:
            raise CaseError(f"{source}: materials.{both[0]}: given twice, as the tag "
                            f"{both[0]} and as the name '{both[0]}' (give one)")
        data = {**data, "materials": {str(k): v for k, v in materials.items()}}
    loads = data.get("loads")
    if not isinstance(loads, dict):
        return data
    view = {**data, "loads": dict(loads)}
    for kind in GROUP_MAPS:
        groups = loads.get(kind)
        if not isinstance(groups, dict) or all(isinstance(k, str) for k in groups):
            continue
        both = [k for k in groups if not isinstance(k, str) and str(k) in groups]
        if both:
            raise CaseError(f"{source}: loads.{kind}.{both[0]}: given twice, as the tag "
                            f"{both[0]} and as the name '{both[0]}' (give one)")
        view["loads"][kind] = {str(k): v for k, v in groups.items()}
    return view
