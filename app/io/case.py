"""Moved to the package vpcontact.case (app/case/); these names stay until the imports are
updated."""
# ruff: noqa: F401
from vpcontact.case.meshrules import MAX_VERTICES  # moved: temporary re-export
from vpcontact.case.model import (  # moved: temporary re-export
    Boundaries,
    Case,
    Contact,
    Friction,
    Initial,
    Loads,
    Material,
    Memory,
    MeshSpec,
    Numerics,
    OutputSpec,
    Slip,
    TimeGrid,
    Viscoplastic,
)
from vpcontact.case.reading import (  # moved: temporary re-export
    MAX_FILE_BYTES,
    RawCase,
    key_lines,
    load_raw,
    parse_override,
    read_text,
    safe_load,
    with_lines,
)
from vpcontact.case.timegrid import MAX_STEPS  # moved: temporary re-export
from vpcontact.case.validation import (  # moved: temporary re-export
    fast_eligible,
    load_case,
    rescale_for_length,
    validate,
)
from vpcontact.case.values import body_length, check_values_on_mesh  # moved: temporary re-export
from vpcontact.io.errors import CaseError  # moved: temporary re-export
