"""Canonical JSON text of case data, for hashes (checkpoint fingerprints, run caches)."""
from __future__ import annotations

import json


def stable_json(data) -> str:
    """JSON text of nested data that is the same for equal data: mapping keys sorted as
    text (a case mixes names and group numbers as keys), anything else JSON cannot hold
    as its str().

    Args:
        data: dicts, lists and scalars.

    Returns:
        The JSON text.
    """
    def plain(x):
        if isinstance(x, dict):
            return {str(k): plain(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [plain(v) for v in x]
        return x
    return json.dumps(plain(data), sort_keys=True, default=str)
