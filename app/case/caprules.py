"""The rules of ``loads.rigid`` (rigid caps) on the data as given: a known group that no
other role takes (clamped, prescribed displacement, contact), the lengths of force,
displacement, moment and rotation (d, and 1 in 2D or 3 in 3D), no amplitude both loaded and
prescribed, expressions in t only, a reference point of d coordinates.  The rules that need
the mesh (nodes shared with a contact group, a clamped group or another cap) are in
app/model/rigidcap.py."""
from __future__ import annotations

import numpy as np

from vpcontact.case import expressions
from vpcontact.case.rules import _check_component, _check_group, _group_name
from vpcontact.io.errors import CaseError

MOVES = (("force", "displacement"), ("moment", "rotation"))


def check_rigid_caps(data: dict, source: str) -> None:
    """Every ``loads.rigid`` group and its keys (module docstring).

    Args:
        data: the default-filled, settled case mapping.
        source: the case file, for messages.

    Raises:
        CaseError: one line naming the key and what is allowed.
    """
    builtin, dim = "file" not in data["mesh"], data["mesh"]["dim"]
    bounds, loads = data["boundaries"], data["loads"]
    taken = dict.fromkeys(bounds["clamped"], "boundaries.clamped")
    taken.update(dict.fromkeys(loads.get("displacement", {}), "loads.displacement"))
    if data.get("contact"):
        taken.update(dict.fromkeys(bounds["contact"], "boundaries.contact"))
        for i, p in enumerate(data["contact"].get("pairs") or []):
            taken.update({p[r]: f"contact.pairs[{i}].{r}" for r in ("surface", "target")})
    for ref, cap in loads.get("rigid", {}).items():
        path = f"loads.rigid.{ref}"
        _check_group(ref, path, builtin, dim, source, named=False)
        if ref in taken:
            raise CaseError(f"{source}: {path}: {_group_name(ref, builtin)} is also in "
                            f"{taken[ref]} (a group is a rigid cap or has that role, not "
                            "both)")
        _check_cap(cap, path, dim, source)


def _check_cap(cap: dict, path: str, dim: int, source: str) -> None:
    """The lengths, one of load or prescription per amplitude, the expressions in t."""
    turns = 1 if dim == 2 else 3
    for keys, n in zip(MOVES, (dim, turns)):
        given = []
        for key in keys:
            value = cap.get(key)
            items = value if isinstance(value, list) else [value]
            if value is not None and (len(items) != n or (n == 1) != (not isinstance(value,
                                                                                 list))):
                want = f"a list of {n} components" if n > 1 else "one component (not a list)"
                raise CaseError(f"{source}: {path}.{key}: expected {want} in {dim}D, got "
                                f"{len(items) if isinstance(value, list) else 'one'}")
            given.append(items if value is not None else [None] * n)
            for i, c in enumerate(items):
                if c is not None:
                    where = f"{path}.{key}[{i}]" if isinstance(value, list) else f"{path}.{key}"
                    _check_component(c, where, ("t",), source)
        for i, (load, fixed) in enumerate(zip(*given)):
            if load is not None and fixed is not None:
                raise CaseError(f"{source}: {path}: {keys[0]}[{i}] and {keys[1]}[{i}] are both "
                                "given (an amplitude is either loaded or prescribed: give one, "
                                "null the other)")
    ref = cap.get("reference")
    if ref is not None and len(ref) != dim:
        raise CaseError(f"{source}: {path}.reference: expected {dim} coordinates (the mesh "
                        f"dimension), got {len(ref)}")


def component_value(c, t: float) -> float:
    """A load component's value at t (a number, an expression in t or a table).

    Args:
        c: the component as the case gives it (not None).
        t: the time.

    Returns:
        The value (NaN or inf where the expression is not finite).
    """
    if isinstance(c, (int, float)):
        return float(c)
    if isinstance(c, dict):
        pts = np.asarray(c["table"], dtype=float)
        return float(np.interp(t, pts[:, 0], pts[:, 1]))
    return float(expressions.evaluate(expressions.parse(c, ("t",)), {"t": np.float64(t)}))


def cap_stress(rigid: dict, dim: int, times, length: float, E: float, source: str) -> float:
    """The stress scale of the caps' data, every component finite at every time point:
    |F| / L^(d-1), |M| / L^d, E |U| / L and E |theta|.

    Args:
        rigid: the case's ``loads.rigid``.
        dim: the mesh dimension d.
        times: the time points t_0..t_N.
        length: the body's size L.
        E: the largest Young's modulus.
        source: the case file, for messages.

    Returns:
        The largest of these over the caps and times (0 without caps).

    Raises:
        CaseError: a component that is not finite at some time, naming the key and t.
    """
    factors = {"force": length ** (1 - dim), "moment": length ** -dim,
               "displacement": E / length, "rotation": E}
    scale = 0.0
    for ref, cap in rigid.items():
        for key, factor in factors.items():
            value = cap.get(key)
            items = value if isinstance(value, list) else [value]
            for i, c in enumerate(items):
                if c is None:
                    continue
                v = np.array([component_value(c, t) for t in times])
                if not np.isfinite(v).all():
                    where = f"{key}[{i}]" if isinstance(value, list) else key
                    raise CaseError(f"{source}: loads.rigid.{ref}.{where}: not finite at "
                                    f"t = {times[int(np.argmin(np.isfinite(v)))]:g}")
                scale = max(scale, factor * float(np.abs(v).max()))
    return scale
