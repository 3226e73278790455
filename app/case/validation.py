"""Validation of a case: the mapping as read (app/case/reading.py) becomes a Case
(app/case/model.py), each rule applied once, in this order: the data's size and numbers,
the schema (each key alone), the keys that do not apply and the mesh file, the defaults,
the built-in mesh's size, the cross-key rules, the time grid, the data values at sample
points, the PETSc options on top of the solvers' defaults scaled to the case
(app/solvers/options.py), the name, and the step solver's eligibility (app/solvers).  The
first rule broken is reported, in one line naming the file, the key path and its line.
The rules that need the mesh run once more on the loaded mesh (``rescale_for_length``,
values.check_values_on_mesh).
"""
from __future__ import annotations

import copy
import dataclasses
from pathlib import Path

from vpcontact.case.caprules import check_rigid_caps
from vpcontact.case.materialrules import check_material_keys, check_planes
from vpcontact.case.meshrules import (
    MAX_LENGTH,
    MIN_LENGTH,
    check_file_dimension,
    check_given,
    check_mesh,
    settle_defaults,
)
from vpcontact.case.model import Case, build_case
from vpcontact.case.pairrules import as_written, fill_pair_defaults, settle_pairs
from vpcontact.case.reading import MAX_CASE_SIZE, check_data, load_raw, with_lines
from vpcontact.case.rules import check_name, check_structure
from vpcontact.case.schemacheck import check_schema, fill_defaults
from vpcontact.case.timegrid import check_adaptive, time_grid
from vpcontact.case.values import body_length, check_values
from vpcontact.io.errors import CaseError
from vpcontact.solvers.choice import condensed_eligible
from vpcontact.solvers.optioncheck import PetscOptions, check_petsc_options
from vpcontact.solvers.options import case_defaults


def validate(data: dict, source: str = "<case>") -> Case:
    """Validate a raw case mapping.

    Args:
        data: the case mapping (a RawCase from load_raw, or a dict built in code).
        source: the file name for messages.

    Returns:
        The Case.

    Raises:
        CaseError: one line naming the file, the key path and (for a file read by
            load_raw) its line.
    """
    moved = {}                        # laws settled out of the pairs: where they were written
    try:
        return _validate(data, source, moved)
    except CaseError as exc:          # one line, with the YAML lines of the keys named
        text = as_written(str(exc), moved).replace("\r", "\\r").replace("\n", "\\n")
        raise CaseError(with_lines(text, getattr(data, "lines", {}),
                                   getattr(data, "overrides", {}))) from None
    except RecursionError:
        raise CaseError(f"{source}: the case is nested too deeply") from None


def _validate(data: dict, source: str, moved: dict) -> Case:
    """The rules in their order (see the module's docstring); raises CaseError.  ``moved``
    receives where the pairs' laws settled into the contact section were written."""
    check_data(data, "", source, [MAX_CASE_SIZE])      # dicts built in code, not by load_raw
    data = copy.deepcopy(dict(data))
    check_schema(data, source)
    check_material_keys(data, source)
    dim_given = "dim" in data["mesh"]
    mesh_file = check_given(data, source)
    moved.update(settle_pairs(data, source))
    fill_defaults(data)
    fill_pair_defaults(data, source)
    settle_defaults(data, mesh_file)
    check_planes(data, source)
    if mesh_file is None:
        check_mesh(data["mesh"], source)
    try:
        check_structure(data, source)
        check_rigid_caps(data, source)
    except CaseError:       # vectors of the other dimension: is mesh.dim the cause?
        if mesh_file is not None and dim_given:
            check_file_dimension(data["mesh"]["dim"], mesh_file, source)
        raise
    grid = dataclasses.replace(time_grid(data["time"], source), scheme=data["time"]["scheme"],
                               adaptive=data["time"].get("adaptive"))
    check_adaptive(grid.adaptive, grid.times, source)
    case = build_case(data, source, grid, {})
    stress = check_values(case)
    defaults, limits = case_defaults(case, stress, body_length(data))
    check_petsc_options(data.get("petsc", {}), source, base=defaults, limits=limits)
    check_name(data, source)
    petsc = PetscOptions({**defaults, **data.get("petsc", {})}, limits)
    case = dataclasses.replace(case, petsc=petsc, data_stress=stress, petsc_defaults=defaults,
                               laws_written=dict(moved))
    ok, why = condensed_eligible(case)
    if case.numerics.method == "condensed" and not ok:
        raise CaseError(f"{source}: solver.method: {data['solver']['method']!r} is not "
                        f"possible here: {why} (allowed: snes_vi, auto)")
    return case


def rescale_for_length(case: Case, length: float, stress: float | None = None) -> Case:
    """The case with its PETSc defaults scaled to the body's size ``length`` (known once a
    mesh.file is loaded; validation takes 1): the scaled absolute tolerances that were not
    given (in the case file or on the command line) are recomputed, and every given option
    is checked again against the new limits.

    Args:
        case: the validated case.
        length: the body's size L [m] (e.g. the largest side of the mesh's bounding box).
        stress: the stress scale of the loads and initial data, if measured on the mesh
            (default: as validation finds it, with E |u| / length for the initial and
            prescribed displacements).

    Returns:
        The case with the new petsc options, petsc_defaults and data_stress.

    Raises:
        CaseError: if a given absolute tolerance is too large for the new scales, or the
            length is not a positive finite number.
    """
    if not MIN_LENGTH <= length <= MAX_LENGTH:
        raise CaseError(f"{case.source}: mesh.file: the body's size {length:g} m is degenerate "
                        f"(allowed: {MIN_LENGTH:g} to {MAX_LENGTH:g})")
    stress = check_values(case, length) if stress is None else float(stress)
    defaults, limits = case_defaults(case, stress, length)
    in_file = case.raw.get("petsc", {})
    missing = object()
    given = {k: v for k, v in case.petsc.items()
             if k in in_file or case.petsc_defaults.get(k, missing) != v}
    check_petsc_options(given, case.source, base=defaults, limits=limits)
    petsc = PetscOptions({**defaults, **given}, limits)
    return dataclasses.replace(case, petsc=petsc, data_stress=stress, petsc_defaults=defaults)


def load_case(path: str | Path, overrides: list[str] = ()) -> Case:
    """Read, override and validate a case file.

    Args:
        path: the case file.
        overrides: 'section.key=value' strings (``--set``).

    Returns:
        The Case.

    Raises:
        CaseError: for any problem, in one line naming the file and key.
    """
    return validate(load_raw(path, overrides), str(path))
