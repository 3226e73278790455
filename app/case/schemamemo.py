"""The case mappings that passed the schema check before, remembered by a digest, so that a
case run again (the same file, the same overrides) skips the check and the import of
jsonschema: 44 ms of the 2D reference's 1.3 s as a whole process; the check itself takes
1 ms (measured).

A digest covers the mapping as the schema sees it (schemacheck._schema_view) in canonical
JSON, SCHEMA itself and the validator's draft, so any change of either is a new entry; a
mapping with keys that are not strings (JSON would confuse 1 and '1') or values that are
not JSON has no digest and is always checked.  Only passes are remembered: a mapping that
fails is checked, and reported, every time.

The digests live in one file of the run cache (app/cachepaths.py), the last
``MAX_ENTRIES`` of them.  Anyone who may write that file may also write the compiled kernels
next to it, which run in every process; an unreadable or unwritable cache only means that
every case is checked.
"""
from __future__ import annotations

import functools
import hashlib
import json
from pathlib import Path

DRAFT = "draft7"           # the validator schemacheck uses (part of every digest)
MAX_ENTRIES = 512          # digests kept (64 hex digits and a newline each)
FILE = "schema-passed"     # in the run cache


@functools.lru_cache(maxsize=1)
def _schema_text() -> str:
    from vpcontact.case.schema import SCHEMA
    return json.dumps(SCHEMA, sort_keys=True)


def _string_keys(value) -> bool:
    """Whether every mapping in ``value`` (nested) has string keys only."""
    if isinstance(value, dict):
        return all(isinstance(k, str) and _string_keys(v) for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return all(_string_keys(v) for v in value)
    return True


def digest(view: dict) -> str | None:
    """The digest of a mapping as the schema check sees it.

    Args:
        view: the mapping (schemacheck._schema_view).

    Returns:
        64 hex digits, or None where the mapping has no canonical JSON form.
    """
    if not _string_keys(view):
        return None
    try:
        text = json.dumps(view, sort_keys=True, allow_nan=True)
    except (TypeError, ValueError):
        return None
    return hashlib.sha256(f"{DRAFT}\n{_schema_text()}\n{text}".encode()).hexdigest()


def _path() -> Path:
    from vpcontact.cachepaths import cache_root
    return cache_root() / FILE


def _entries() -> list[str]:
    try:
        return _path().read_text().split()
    except (OSError, UnicodeDecodeError):
        return []


def passed(key: str | None) -> bool:
    """Whether the mapping of this digest passed the schema check before.

    Args:
        key: a digest (None: never).

    Returns:
        True if it is remembered.
    """
    return key is not None and key in _entries()


def remember(key: str | None) -> None:
    """Remember a digest whose mapping passed (atomically; nothing if the cache cannot be
    written).

    Args:
        key: the digest (None: nothing).
    """
    if key is None:
        return
    from vpcontact.io.files import atomic_write
    keys = [k for k in _entries() if k != key][-(MAX_ENTRIES - 1):] + [key]
    try:       # not synced: a memo lost in a crash only means one more check
        atomic_write(_path(), "\n".join(keys) + "\n", sync=False)
    except OSError:
        pass
