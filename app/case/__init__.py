"""The case layer: a case file read (``reading``), validated rule by rule (``validation``,
with the schema's checks in ``schemacheck``, the cross-key rules in ``rules`` and
``meshrules``, the time grid in ``timegrid``, the data values at points of the body in
``values`` and ``datacheck``) into the typed model of a case (``model``).

Adding a key: its entry in ``schema.SCHEMA``, its field in ``model`` (and its line in
``model.build_case``), and its rule, if the schema's is not enough, in ``rules``.

    from vpcontact.case import load_case
    case = load_case("cases/wang_cheng_2021.yaml", ["mesh.n=8"])
"""
from vpcontact.case.model import Case
from vpcontact.case.reading import load_raw
from vpcontact.case.validation import load_case, rescale_for_length, validate
from vpcontact.io.errors import CaseError

__all__ = ["Case", "CaseError", "load_case", "load_raw", "rescale_for_length", "validate"]
