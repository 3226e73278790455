"""`./vpcontact stability CASE.yaml`: a sweep of stiff and extreme variants of a case,
each on a coarse mesh, reported in stability.csv and stability.md.

The base is the case on a structured n x n mesh (built-in mesh, --n) or on its mesh.file
refined R times (--refine; the variant "h/2" runs on the next refinement, as the built-in
one doubles n), with N uniform steps.  Only the variants whose data the case has are run
(no stiff viscosity without a Perzyna law, no friction variants without friction, ...);
gap variants scale a gap expression, load variants scale every load (tractions, pressures,
body force, prescribed displacements, the rigid caps' loads and motions), and a case with
contact.direction also runs with the nodal normals of its contact boundary.

Per variant: the parameters changed, the history scheme, whether it converged (and why not),
the largest Newton count, the growth of ||sigma||_Q and ||u||_V over time (max over the run /
value at the first time point at or after the base's first step T/N, so that finer steps of a
load ramp are not measured against a tiny first step; "blow-up" when it exceeds 1e3 or is not
finite), the explicit stability indicator, the well-posedness margin of (2.6) and the wall
time.  Material scaling variants also report how far the solution is from the exactly scaled
baseline (u unchanged, sigma and kappa scaled).
"""
from __future__ import annotations

import copy
import dataclasses
import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from vpcontact.case import CaseError, validate
from vpcontact.io.files import atomic_write
from vpcontact.io.output import csv_text
from vpcontact.studies import variantsections as vs
from vpcontact.studies.interrupts import (
    SignalWatch,
    StudyInterrupted,
    caused_by_interrupt,
    check_run,
    signal_name,
)

log = logging.getLogger("vpcontact")
BLOWUP = 1e3


@dataclass
class Variant:
    """One variant of the sweep: changes to the base case.

    Args:
        group: the report's group (e.g. "stiff viscosity", "near-Signorini").
        name: the variant's name in the report.
        changes: dotted key (e.g. "contact.friction.b"), or a tuple of path parts (a
            material group's or a pair's, app/studies/variantsections.py) -> new value;
            None deletes the key, ("scale", f) multiplies every number under it by f.
        schemes: the history schemes to run it with ("explicit", "implicit").
        scale: the material scaling factor (compared with the exactly scaled baseline), or
            None.
    """

    group: str
    name: str
    changes: dict                      # dotted key -> value (None: delete the key)
    schemes: tuple = ("explicit", "implicit")
    scale: float | None = None         # material scaling factor (compare with the baseline)


@dataclass
class Outcome:
    """The result of one variant with one scheme (a row of stability.csv).

    Args:
        variant: the Variant.
        scheme: "explicit" or "implicit".
        status: the run's status, or "invalid" (the variant is no valid case) or "error"
            (an exception).
        reason: why it did not complete ("" if it did).
        steps: steps done.
        max_newton: the largest Newton count of a step.
        growth_sigma: max_n ||sigma_n||_Q / ||sigma_m||_Q, t_m the first time point at or
            after the base's first step T/N_base (NaN if undefined).
        growth_u: the same for ||u||_V.
        finite: whether every norm was finite.
        indicator: the explicit stability indicator k_max r_max.
        margin: the well-posedness margin of (2.6).
        scaling_error: for a scaling variant, the relative distance from the scaled
            baseline (u unchanged, sigma scaled), else None.
        wall_s: wall time [s].
        norms: the last step's u, sigma and kappa norms.
        dofs: the displacement dofs of the variant's mesh (0 if it did not start).
        watch: the run's SignalWatch (a signal at its end ends the sweep after this row).
    """

    variant: Variant
    scheme: str
    status: str
    reason: str = ""
    steps: int = 0
    max_newton: int = 0
    growth_sigma: float = math.nan
    growth_u: float = math.nan
    finite: bool = True
    indicator: float | None = None
    margin: float | None = None
    scaling_error: float | None = None
    wall_s: float = 0.0
    norms: dict = field(default_factory=dict, repr=False)
    dofs: int = 0
    watch: SignalWatch | None = field(default=None, repr=False)

    @property
    def bounded(self) -> bool:
        """Not diverged, finite, and both growths below BLOWUP."""
        return (self.status != "diverged" and self.finite and self.growth_sigma < BLOWUP
                and self.growth_u < BLOWUP)


def _scaled(raw: dict, factor: float) -> tuple[dict, list[str]]:
    """Every stress-like datum times factor, in every material section and set of contact
    laws (app/studies/variantsections.py: E and the viscoplastic law's stresses, c_nu, b,
    c1, c2, the memory's b0), and the tractions, pressures, body force and initial stress:
    u is unchanged (prescribed displacements and gaps too), stresses scale.  Returns the
    changes and why a material's law cannot be scaled (then the variant is left out)."""
    changes, why = {}, []
    for label, prefix, m in vs.material_sections(raw):
        out, reason = vs.scaled_material(prefix, m, factor)
        changes.update(out)
        if reason:
            why.append(f"{label}: {reason}")
    for _, prefix, c in vs.contact_sections(raw):
        changes.update(vs.scaled_contact(prefix, c, factor))
    changes.update({k: ("scale", factor) for k in ("loads.traction", "loads.pressure",
                                                    "loads.f0", "initial.sigma0")
                    if _has(raw, k)})
    changes.update(_caps_scaled(raw, factor, ("force", "moment")))
    return changes, why


def _caps_scaled(raw: dict, factor: float, keys: tuple) -> dict:
    """The rigid caps' data of ``keys`` (force, moment, displacement, rotation; never the
    reference point) times factor: key paths as tuples (a group's name may hold a dot)."""
    caps = (raw.get("loads") or {}).get("rigid") or {}
    return {("loads", "rigid", group, k): ("scale", factor)
            for group, spec in caps.items() for k in keys if k in (spec or {})}


def _has(raw: dict, key) -> bool:
    """Whether the case has the key (a dotted string or a tuple of path parts)."""
    node = raw
    for part in vs.path(key):
        if isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            node = node[part]
        elif isinstance(node, dict) and part in node:
            node = node[part]
        else:
            return False
    return True


def _loads_scaled(raw: dict, factor: float) -> dict:
    """Every load (tractions, pressures, body force, prescribed displacements, the rigid
    caps' forces, moments, displacements and rotations) times factor."""
    return {**{f"loads.{k}": ("scale", factor)
               for k in ("traction", "pressure", "f0", "displacement")
               if _has(raw, f"loads.{k}")},
            **_caps_scaled(raw, factor, ("force", "moment", "displacement", "rotation"))}


def not_applicable(raw: dict) -> list[str]:
    """The groups of the standard sweep that a case leaves out, or that leave out some of
    its material sections or contact laws, each with the reason (their data are absent,
    or the law has no such datum: app/studies/variantsections.py).

    Args:
        raw: the sweep's base case.

    Returns:
        One "group: why" line per group (or part of a group) left out.
    """
    out = []
    on, why = vs.viscosity_plan(raw)
    out += _left_out("stiff viscosity", on, why, "material.viscoplastic")
    on, why = vs.compliance_plan(raw)
    out += _left_out("near-Signorini c_nu", on, why, "contact.normal_compliance")
    if not vs.gap_plan(raw):
        out.append("near-Signorini g: the case has no contact.g")
    every, law42, why = vs.friction_plan(raw)
    if not every:
        out.append("friction: the case has no contact.friction")
    out += _left_out("friction b=30, c1=300", law42, why, "")
    on, why = vs.elastic_plan(raw)
    out += _left_out("material nu, E scaled", on, why, "material")
    if on and not why:
        out += [f"material E scaled: {w}" for w in _scaled(raw, 1.0)[1]]
    return out


def _left_out(group: str, on: list, why: list[str], absent: str) -> list[str]:
    """The lines of a group that acts on the sections ``on``: none if it acts on all;
    "group: why" if on none (the reasons, or that the case has no ``absent``); else
    "group: not on ..." for the sections it leaves out."""
    if not why:
        return [] if on or not absent else [f"{group}: the case has no {absent}"]
    return [f"{group}: {'not on ' if on else ''}{', '.join(why)}"]


def default_variants(raw: dict, finer: dict | None = None) -> list[Variant]:
    """The standard sweep, of the variants that apply to the case: stiff viscosity
    (lambda1 with two steps), near-Signorini contact (large c_nu of (4.1), small and large
    gaps g: given values for a number, factors on an expression), friction (4.2) (all
    stick, frictionless, violating (2.6)), tiny, large and reversed loads, extreme Poisson
    ratios, material scaling, a finer mesh, nodal normals instead of contact.direction, and
    very large and small time steps.

    Args:
        raw: the base case (a dict; see base_case).
        finer: the changes that halve h (mesh.n doubled, or the next refinement of a
            mesh.file), or None to leave that variant out.

    Returns:
        The Variants, the baseline first.
    """
    V = Variant
    out = [V("baseline", "baseline", {})]
    on, _ = vs.viscosity_plan(raw)
    for lam in (100.0, 1.0, 0.01) if on else ():
        for N in (16, 128):
            out.append(V("stiff viscosity", f"lambda1={lam:g}, k={_k(raw, N)}",
                         {**_every(on, "viscoplastic.lambda1", lam), "time.N": N}))
    on, _ = vs.compliance_plan(raw)
    for c in (1e4, 1e6) if on else ():
        out.append(V("near-Signorini", f"c_nu={c:g}", _every(on, "normal_compliance.c_nu", c)))
    out += _gap_variants(vs.gap_plan(raw))
    out += _friction_variants(raw)
    out += [V("loads", "tiny (x1e-6)", _loads_scaled(raw, 1e-6)),
            V("loads", "large (x100)", _loads_scaled(raw, 100.0)),
            _pulling(raw)]
    out += _material_variants(raw)
    if finer:
        out.append(V("mesh", "h/2", dict(finer)))
    if _has(raw, "contact.direction"):
        out.append(V("contact normal", "nodal normals (no contact.direction)",
                     {"contact.direction": None}))
    for N in (2, 1024):
        out.append(V("time step", f"k={_k(raw, N)}", {"time.N": N}))
    return out


def _short(v: float) -> str:
    return f"{v:g}".replace("e+0", "e").replace("e-0", "e-").replace("e+", "e")


def _k(raw: dict, N: int) -> str:
    T = raw.get("time", {}).get("T", 1.0)
    return f"1/{N}" if T == 1.0 else f"T/{N}"


def _every(prefixes: list, rest: str, value) -> dict:
    """The changes that set ``rest`` to value in each section of ``prefixes``."""
    return {vs.key(p, rest): value for p in prefixes}


def _gap_variants(gaps: list) -> list[Variant]:
    """Small and large gaps, in every section with a gap g ((prefix, g) of
    ``variantsections.gap_plan``): the values 1e-6, 1e-3, 1 for a number; an expression of
    x, y, z times 1e-3, 0.1, 10 (its shape kept)."""
    out = []
    for v, f in zip((1e-6, 1e-3, 1.0), (1e-3, 0.1, 10.0)):
        changes = {vs.key(p, "g"): ("scale", f) if isinstance(g, str) else v for p, g in gaps}
        kinds = {isinstance(g, str) for _, g in gaps}
        name = {frozenset({True}): f"g x{f:g}", frozenset({False}): f"g={v:g}"}.get(
            frozenset(kinds), f"g={v:g} (expressions x{f:g})")
        if gaps:
            out.append(Variant("near-Signorini", name, changes))
    return out


def _friction_variants(raw: dict) -> list[Variant]:
    """Frictionless on every friction law; all stick (b = 30) and violating (2.6) (c1 =
    300, b = 3) on every law (4.2) (``variantsections.friction_plan``)."""
    every, law42, _ = vs.friction_plan(raw)
    out = [Variant("friction", "b=30 (all stick)", _every(law42, "friction.b", 30.0))] \
        if law42 else []
    if every:
        out.append(Variant("friction", "frictionless", _every(every, "friction", None)))
    if law42:
        out.append(Variant("friction", "c1=300, b=3 (violates (2.6))",
                           {**_every(law42, "friction.c1", 300.0),
                            **_every(law42, "friction.b", 3.0)}))
    return out


def _material_variants(raw: dict) -> list[Variant]:
    """nu = 0 and 0.499 in every material with numbers E and nu; E and every stress datum
    scaled by 1e-5 and 1e6 (``_scaled``) if every material's can be."""
    on, why = vs.elastic_plan(raw)
    if not on:
        return []
    out = [Variant("material", f"nu={nu:g}", _every(on, "nu", nu)) for nu in (0.0, 0.499)]
    sections = vs.material_sections(raw)
    for f in (1e-5, 1e6):
        changes, bad = _scaled(raw, f)
        if why or bad:
            continue
        E = f"E = {_short(sections[0][2]['E'] * f)}" if len(sections) == 1 else \
            "every material"
        out.append(Variant("material", f"E scaled x{_short(f)} ({E})", changes, scale=f))
    return out


def _pulling(raw: dict) -> Variant:
    """Loads pulling the body off the foundation: 2D built-in, top traction up; else all x -1."""
    if "file" not in raw["mesh"] and raw["mesh"].get("dim", 2) == 2:
        return Variant("loads", "pulling away (top +8)", {"loads.traction.top": [0.0, 8.0]})
    return Variant("loads", "pulling away (loads x-1)", _loads_scaled(raw, -1.0))


def apply_changes(raw: dict, changes: dict) -> dict:
    """A copy of a case with a variant's changes.

    Args:
        raw: the case as read (not modified).
        changes: key (dotted, or a tuple of path parts with list indices: see
            app/studies/variantsections.py) -> value, None (delete) or ("scale", f) (see
            Variant); a scale of an absent key changes nothing.

    Returns:
        The changed copy (missing sections are created).

    Raises:
        CaseError: ("scale", f) met something other than numbers, expressions, tables and
            null components.
    """
    raw = copy.deepcopy(raw)
    for key, value in changes.items():
        *path, last = vs.path(key)
        scale = isinstance(value, tuple) and value[0] == "scale"
        if scale and not _has(raw, key):
            continue
        node = raw
        for p in path:
            node = node[p] if isinstance(node, list) else node.setdefault(p, {})
        if value is None:
            node.pop(last, None)
        elif scale:
            node[last] = _scale(node.get(last), value[1])
        else:
            node[last] = value
    return raw


def _scale(v, f):
    if v is None:                     # a free displacement component stays free
        return None
    if isinstance(v, dict) and set(v) == {"table"} and isinstance(v["table"], list):
        return {"table": [[row[0], _scale(row[1], f)] for row in v["table"]]}
    if isinstance(v, dict):
        return {k: _scale(x, f) for k, x in v.items()}
    if isinstance(v, list):
        return [_scale(x, f) for x in v]
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return v * f
    if isinstance(v, str):            # an expression: its value times f
        return f"({v})*({f!r})"
    raise CaseError(f"cannot scale {v!r} (only numbers, expressions and tables)")


def run_variant(raw: dict, variant: Variant, scheme: str, comm, petsc_cli: dict) -> Outcome:
    """Run one variant with one history scheme (collective); never raises for a bad
    variant: an invalid case or an exception becomes its Outcome.

    Args:
        raw: the sweep's base case (a dict).
        variant: the Variant.
        scheme: "explicit" or "implicit".
        comm: the MPI communicator.
        petsc_cli: PETSc options from the command line.

    Returns:
        The Outcome (status, Newton counts, growth of the norms, diagnostics, wall time).

    Raises:
        KeyboardInterrupt: SIGINT or SIGTERM (StudyInterrupted if it stopped the run).
    """
    from vpcontact.simulation import run

    r = apply_changes(raw, variant.changes)
    r.setdefault("time", {})["scheme"] = scheme
    t0 = time.perf_counter()
    try:
        case = validate(r, f"variant '{variant.name}'")
    except CaseError as exc:
        return Outcome(variant, scheme, "invalid", str(exc))
    case = dataclasses.replace(case, petsc={**case.petsc, **petsc_cli})
    level, watch = log.level, SignalWatch()
    log.setLevel(logging.CRITICAL)
    try:
        res = run(case, comm, [watch])
    except CaseError as exc:   # found while setting up
        return Outcome(variant, scheme, "invalid", str(exc), wall_s=time.perf_counter() - t0)
    except Exception as exc:   # report, do not stop the sweep: every variant gets a row
        signal = caused_by_interrupt(exc)     # a signal inside a C extension: ends the sweep
        if signal is not None:
            raise signal from None
        return Outcome(variant, scheme, "error", f"{type(exc).__name__}: {exc}",
                       wall_s=time.perf_counter() - t0, finite=False)
    finally:
        log.setLevel(level)
    s = res.summary
    check_run(s, f"the variant '{variant.name}' ({scheme})")   # a signal ends the sweep
    steps = s["steps"]
    out = Outcome(variant, scheme, s["status"], s.get("failure", {}).get("reason", ""),
                  len(steps), max((st["newton_iterations"] for st in steps), default=0),
                  wall_s=time.perf_counter() - t0, dofs=s.get("mesh", {}).get("dofs", 0))
    d = s["diagnostics"]
    out.indicator, out.margin = d["stability_indicator"], d["wellposedness_margin"]
    if steps:
        sig = np.array([st["norm_sigma_Q"] for st in steps])
        uu = np.array([st["norm_u_V"] for st in steps])
        out.finite = bool(np.all(np.isfinite(sig)) and np.all(np.isfinite(uu)))
        i = _reference_step(raw, steps)
        out.growth_sigma = float(sig.max() / sig[i]) if sig[i] > 0 else math.nan
        out.growth_u = float(uu.max() / uu[i]) if uu[i] > 0 else math.nan
        out.norms = {"u": float(uu[-1]), "sigma": float(sig[-1]),
                     "kappa": float(steps[-1]["norm_kappa_Y"])}
    if out.status != "completed" and not out.finite:
        out.reason = out.reason or "non-finite solution"
    out.watch = watch
    return out


def _reference_step(base: dict, steps: list[dict]) -> int:
    """The growth's first step: the first at t >= the base's T/N (not a ramp's tiny step), or 0."""
    t_ref = base["time"]["T"] / base["time"]["N"]
    reached = [i for i, st in enumerate(steps) if st["t"] >= t_ref * (1 - 1e-9)]
    return reached[0] if reached else 0


def base_case(raw: dict, n: int | None, N: int, source: str = "case",
              refine: int | None = None) -> dict:
    """The sweep's base: the case on a structured n x n mesh (built-in mesh) or on its
    mesh.file (refined ``refine`` times by ``sweep``) with N uniform steps.

    Args:
        raw: the case as read (not modified).
        n: cells per side (--n; None: 8); not with a mesh.file.
        N: time steps (--steps).
        source: the case file, for messages.
        refine: refinements of a mesh.file (--refine; None: 0); not with a built-in mesh.

    Returns:
        The base case as a dict (a mesh.file as an absolute path).

    Raises:
        CaseError: naming --n, --refine or --steps and the allowed values, or if the base
            is not a valid case with either history scheme.
    """
    file = "file" in raw.get("mesh", {})
    if file and n is not None:
        raise CaseError("--n: not used with mesh.file (allowed: --refine R, the base is the "
                        "case's mesh refined R times)")
    if not file and refine is not None:
        raise CaseError("--refine: only with mesh.file (allowed: --n for the built-in mesh)")
    n = 8 if n is None and not file else n
    for option, v, least in (("--n", n, 1), ("--steps", N, 1), ("--refine", refine, 0)):
        if v is not None and (not isinstance(v, int) or isinstance(v, bool) or v < least):
            raise CaseError(f"{option}: {v!r} is not allowed (allowed: "
                            f"{'positive integers' if least else 'integers >= 0'})")
    base = copy.deepcopy(raw)
    if file:
        case = validate(raw, source)
        base["mesh"] = {"file": case.mesh.file, "dim": case.dim}
        if case.mesh.file.lower().endswith(".geo"):
            base["mesh"]["size"] = case.mesh.size
        base["time"] = {"T": case.time.T, "N": N}
    else:
        base["mesh"]["n"], base["time"] = n, {"T": base["time"].get("T", 1.0), "N": N}
        base["mesh"].pop("h", None)
        base["mesh"]["kind"] = "structured"
    errors = []
    for scheme in ("explicit", "implicit"):
        r = copy.deepcopy(base)
        r["time"]["scheme"] = scheme
        where = f"--refine {refine or 0}" if file else f"--n {n}"
        try:
            validate(r, f"{source} (stability base: {where}, --steps {N}, {scheme} scheme)")
        except CaseError as exc:
            errors.append(exc)
    if len(errors) == 2:
        raise errors[0]
    return base


def sweep(raw: dict, comm, petsc_cli: dict, n: int | None = None, N: int = 8,
          variants: list[Variant] | None = None, source: str = "case",
          refine: int | None = None, select=None) -> list[Outcome]:
    """Run every variant with each of its schemes (collective), then compare the scaling
    variants with the baseline.

    Args:
        raw: the case as read.
        comm: the MPI communicator.
        petsc_cli: PETSc options from the command line.
        n: cells per side of the base mesh (built-in mesh; None: 8).
        N: time steps of the base.
        variants: the variants (None: default_variants).
        source: the case file, for messages.
        refine: refinements of a mesh.file for the base (None: 0); the variant "h/2" runs
            on the next refinement.
        select: Variant -> True (run it), False (leave it out) or a tuple of the schemes
            to run it with (None: every variant with its schemes).

    Returns:
        One Outcome per (variant, scheme), in order.

    Raises:
        CaseError: before anything runs if the base case is not valid (or its mesh.file
            cannot be refined), and after the sweep if no variant was valid input.
        StudyInterrupted: SIGINT or SIGTERM ended the sweep (its ``results``: the
            Outcomes of the runs that finished).
    """
    base = base_case(raw, n, N, source, refine)

    def chosen(base, finer):
        out = []
        for v in variants or default_variants(base, finer):
            pick = True if select is None else select(v)
            if pick:
                out.append(v if pick is True else dataclasses.replace(v, schemes=tuple(pick)))
        return out

    if "file" not in base["mesh"]:
        return _sweep(base, comm, petsc_cli, chosen(base, {"mesh.n": 2 * base["mesh"]["n"]}))
    from vpcontact.studies.convergence import level_meshes

    r = refine or 0
    try:
        with level_meshes(validate(base, source), r + 1, comm) as levels:
            base["mesh"] = {"file": str(levels[r].path), "dim": base["mesh"]["dim"]}
            return _sweep(base, comm, petsc_cli,
                          chosen(base, {"mesh.file": str(levels[r + 1].path)}))
    except KeyboardInterrupt as exc:
        if isinstance(exc, StudyInterrupted):
            raise
        raise StudyInterrupted(signal_name(exc), f"the refinement of {base['mesh']['file']}") \
            from None


def _sweep(base: dict, comm, petsc_cli: dict, variants: list[Variant]) -> list[Outcome]:
    """sweep on its base case."""
    outcomes, where = [], "its start"
    try:
        for v in variants:
            for scheme in v.schemes:
                where = f"the variant '{v.name}' ({scheme})"
                o = run_variant(base, v, scheme, comm, petsc_cli)
                outcomes.append(o)
                log.info("  %-16s %-34s %-8s %-9s steps %4d  max newton %3d  growth sigma "
                         "%-9.3g %s (%.2f s)", v.group, v.name, scheme, o.status, o.steps,
                         o.max_newton, o.growth_sigma, "bounded" if o.bounded else "BLOW-UP",
                         o.wall_s)
                if o.watch is not None:
                    o.watch.stop_if_signalled(where)    # a signal at its end: kept, then stop
    except KeyboardInterrupt as exc:      # the sweep ends; the finished variants are kept
        where = exc.where if isinstance(exc, StudyInterrupted) else where
        raise StudyInterrupted(signal_name(exc), where, len(outcomes),
                               _compared(outcomes)) from None
    if outcomes and all(o.status == "invalid" for o in outcomes):
        raise CaseError(f"no variant of the stability sweep is a valid case: "
                        f"{outcomes[0].reason}")
    return _compared(outcomes)


def _compared(outcomes: list[Outcome]) -> list[Outcome]:
    """The outcomes with the scaling variants compared with the baseline."""
    baseline = {o.scheme: o for o in outcomes if o.variant.name == "baseline"}
    for o in outcomes:
        if o.variant.scale and o.norms and o.scheme in baseline and baseline[o.scheme].norms:
            b, f = baseline[o.scheme].norms, o.variant.scale
            o.scaling_error = max(abs(o.norms["u"] - b["u"]) / b["u"],
                                  abs(o.norms["sigma"] / f - b["sigma"]) / b["sigma"])
    return outcomes


COLUMNS = ["group", "variant", "scheme", "status", "reason", "steps", "max_newton",
           "growth_sigma", "growth_u", "bounded", "finite", "stability_indicator",
           "wellposedness_margin", "scaling_error", "wall_s"]


def _row(o: Outcome) -> dict:
    return {"group": o.variant.group, "variant": o.variant.name, "scheme": o.scheme,
            "status": o.status, "reason": o.reason, "steps": o.steps,
            "max_newton": o.max_newton, "growth_sigma": o.growth_sigma, "growth_u": o.growth_u,
            "bounded": o.bounded, "finite": o.finite, "stability_indicator": o.indicator,
            "wellposedness_margin": o.margin, "scaling_error": o.scaling_error,
            "wall_s": o.wall_s}


def write_csv(path, outcomes) -> None:
    """Write stability.csv (the COLUMNS, one row per Outcome), atomically.

    Args:
        path: the CSV file.
        outcomes: the Outcomes of ``sweep``.
    """
    atomic_write(path, csv_text(COLUMNS, [_row(o) for o in outcomes]))


def _g(v, d=3):
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.{d}g}"


def write_markdown(path, outcomes, case_name: str, n: int | None, N: int,
                   refine: int | None = None, left_out: list[str] | None = None,
                   interrupted: str | None = None) -> None:
    """Write stability.md: a table of the Outcomes and a summary (runs completed, explicit
    blow-ups where the implicit scheme stays bounded), atomically.

    Args:
        path: the Markdown file.
        outcomes: the Outcomes of ``sweep``.
        case_name: the case's name, for the title.
        n: cells per side of the base mesh, or None for a mesh.file.
        N: time steps of the base.
        refine: the refinements of a mesh.file's base (with n None).
        left_out: the groups the case leaves out (not_applicable), listed in the summary.
        interrupted: what interrupted the sweep and where (the report then holds the runs
            that finished before), or None.
    """
    mesh = (f"a structured {n} x {n} mesh" if n is not None else
            f"the case's mesh.file refined {refine or 0} times")
    lines = [f"# Stability report: {case_name}", ""]
    if interrupted:
        lines += [f"**Incomplete: the sweep was interrupted** by {interrupted}; the "
                  f"{len(outcomes)} runs below finished before it, the other variants were "
                  "not run.", ""]
    lines += [f"Each variant runs on {mesh} with k = T/{N} unless it sets "
              "k itself, with the explicit (paper) and the implicit (right-end-point) history "
              "scheme. growth = max over the run / value at the first time point at or after "
              f"T/{N} (the base's first step); bounded = finite "
              f"and growth < {BLOWUP:g}. Indicator = k_max r_max (explicit limit 2); margin = "
              "the well-posedness margin of (2.6) (> 0: unique solution guaranteed).", "",
              "| group | variant | scheme | status | steps | max Newton | growth sigma | "
              "growth u | bounded | indicator | margin | scaling error | wall s | reason |",
              "|" + "---|" * 14]
    for o in outcomes:
        lines.append("| " + " | ".join([
            o.variant.group, o.variant.name, o.scheme, o.status, str(o.steps),
            str(o.max_newton), _g(o.growth_sigma), _g(o.growth_u),
            "yes" if o.bounded else "**no**", _g(o.indicator), _g(o.margin),
            _g(o.scaling_error, 2), f"{o.wall_s:.2f}",
            o.reason.replace("|", "/")[:120]]) + " |")
    both = {}
    for o in outcomes:
        both.setdefault(o.variant.name, {})[o.scheme] = o
    blow = [name for name, d in both.items() if "explicit" in d and not d["explicit"].bounded
            and "implicit" in d and d["implicit"].bounded]
    failed = [f"{o.variant.name} ({o.scheme})" for o in outcomes if o.status != "completed"]
    lines += ["", "## Summary", "",
              f"- {sum(o.status == 'completed' for o in outcomes)} of {len(outcomes)} runs "
              "completed; " + (f"stopped with a reason: {', '.join(failed)}." if failed
                               else "none stopped."),
              "- Explicit scheme unbounded where the implicit one stays bounded: "
              + (", ".join(blow) if blow else "none") + "."]
    if left_out:
        lines.append("- Left out (not applicable): " + "; ".join(left_out) + ".")
    atomic_write(path, "\n".join(lines) + "\n")
