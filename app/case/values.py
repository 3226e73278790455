"""The case's data values at sample points of the body and times (app/case/datacheck.py):
before the mesh is built (the built-in mesh's own points, or what does not depend on the
position of a mesh.file), and once more on the loaded mesh's points.  The same pass gives
the stress scale of the data, which the PETSc defaults are scaled with
(app/solvers/options.py)."""
from __future__ import annotations

import math

from vpcontact.case import datacheck
from vpcontact.case.caprules import cap_stress
from vpcontact.case.materialrules import material_sections, section_errors
from vpcontact.case.meshrules import DEFAULT_BOUNDARIES
from vpcontact.case.model import Case
from vpcontact.io.errors import CaseError
from vpcontact.model.contactregistry import NORMALS, field_keys


def check_values(case: Case, length: float | None = None, samples=None) -> float:
    """The data values at sample points of the body and times: finite, initial values in
    the model's set.

    The body of a mesh.file is unknown before it is loaded: only what does not depend on
    the position is sampled then (the mesh's nodes are checked when it is loaded), and L is
    1.  The geometric checks of u0 (zero on Gamma1, u_nu <= g on Gamma3) need the built-in
    mesh with the default boundaries; g >= 0 is sampled on the built-in mesh's contact
    sides.

    Args:
        case: the case (its data as given in ``raw``, the gap g, E, the time grid).
        length: the body's size L (default: body_length(case.raw)).
        samples: the sample points of the loaded mesh (datacheck.PointSamples; default:
            as above).

    Returns:
        The stress scale of the data: loads, sigma0 and the stress E |u| / L of the
        initial and prescribed displacements.

    Raises:
        CaseError: for a value that is not finite, out of range or outside the model's
            set, naming the key and the point (x, t).
    """
    data, time_grid, g = case.raw, case.time, case.contact.g
    mesh, bounds = data["mesh"], data["boundaries"]
    adaptive = time_grid.adaptive is not None
    if samples is None and "file" in mesh:
        samples = datacheck.Samples.unknown(mesh["dim"], time_grid.times, adaptive)
    elif samples is None:
        lengths = [mesh["L1"], mesh["L2"], mesh["L3"]][:mesh["dim"]]
        cells = [mesh["n"] if mesh["kind"] == "structured" else math.ceil(L / mesh["h"])
                 for L in lengths]
        samples = datacheck.Samples(lengths, cells, time_grid.times, adaptive)
    geometric = "file" not in mesh and bounds == DEFAULT_BOUNDARIES
    try:
        loads = datacheck.check_loads(data["loads"], samples)
        moved = datacheck.check_displacement(data["loads"].get("displacement", {}), samples)
        datacheck.check_gap(g, bounds["contact"], samples)
        contact = data.get("contact", {})
        sections = [("contact", contact)] + [(f"contact.pairs[{i}]", p) for i, p in
                                             enumerate(contact.get("pairs") or [])]
        for path, section in sections:       # the contact section, a pair's own laws
            for key, what in field_keys(NORMALS).items():    # c_nu(x) >= 0, ...
                datacheck.check_gap(section.get("normal_compliance", {}).get(key),
                                    bounds["contact"], samples,
                                    f"{path}.normal_compliance.{key}", what)
            datacheck.check_gap((section.get("memory") or {}).get("b0"), bounds["contact"],
                                samples, f"{path}.memory.b0", "the memory kernel's amplitude")
        u0, sigma0 = datacheck.check_initial(data.get("initial", {}), None, g, samples,
                                             data.get("contact", {}).get("direction"),
                                             geometric)
        moduli = []                                       # E (or M_E) of each material
        for path, section in material_sections(data):    # kappa0 of each material
            vp = section.get("viscoplastic")
            with section_errors(path, datacheck.DataError):
                datacheck.check_initial({}, vp["kappa0"] if vp else None, None, samples)
                moduli.append(datacheck.check_elasticity(section, samples))
    except datacheck.DataError as exc:
        raise CaseError(f"{case.source}: {exc}") from None
    length = body_length(data) if length is None else length
    E = max(moduli)
    caps = cap_stress(data["loads"].get("rigid", {}), mesh["dim"], time_grid.times, length, E,
                      case.source)
    return max(loads, sigma0, E * max(u0, moved) / length, caps)


def check_values_on_mesh(case: Case, samples, length: float) -> float:
    """The checks of validation (``check_values``) on the points of the loaded mesh.

    Args:
        case: the validated case.
        samples: the mesh's sample points and the times (datacheck.PointSamples).
        length: the body's size L [m].

    Returns:
        The stress scale of the data on these points (as validation's).

    Raises:
        CaseError: for a value that is not finite, out of range or outside the model's set,
            naming the key and the point (x, t).
    """
    return check_values(case, length, samples)


def body_length(data: dict) -> float:
    """The body's length scale known before the mesh is built.

    Args:
        data: the default-filled case mapping.

    Returns:
        The longest side of the built-in mesh; 1 for a mesh.file (see rescale_for_length).
    """
    mesh = data["mesh"]
    if "file" in mesh:
        return 1.0
    return max([mesh["L1"], mesh["L2"], mesh["L3"]][:mesh["dim"]])

