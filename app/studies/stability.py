"""`./vpcontact stability CASE.yaml`: a sweep of stiff and extreme variants of a case,
each on a coarse mesh, reported in stability.csv and stability.md.

Per variant: the parameters changed, the history scheme, whether it converged (and why not),
the largest Newton count, the growth of ||sigma||_Q and ||u||_V over time (max over the run /
value at the first step; "blow-up" when it exceeds 1e3 or is not finite), the explicit
stability indicator, the well-posedness margin of (2.6) and the wall time.  Material scaling
variants also report how far the solution is from the exactly scaled baseline (u unchanged,
sigma and kappa scaled).
"""
from __future__ import annotations

import copy
import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from app.io.case import CaseError, validate
from app.io.output import atomic_write, csv_text

log = logging.getLogger("vpcontact")
BLOWUP = 1e3


@dataclass
class Variant:
    """One variant of the sweep: changes to the base case.

    Args:
        group: the report's group (e.g. "stiff viscosity", "near-Signorini").
        name: the variant's name in the report.
        changes: dotted key (e.g. "contact.friction.b") -> new value; None deletes the key,
            ("scale", f) multiplies every number under it by f.
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
        growth_sigma: max_n ||sigma_n||_Q / ||sigma_1||_Q (NaN if undefined).
        growth_u: max_n ||u_n||_V / ||u_1||_V (NaN if undefined).
        finite: whether every norm was finite.
        indicator: the explicit stability indicator k_max r_max.
        margin: the well-posedness margin of (2.6).
        scaling_error: for a scaling variant, the relative distance from the scaled
            baseline (u unchanged, sigma scaled), else None.
        wall_s: wall time [s].
        norms: the last step's u, sigma and kappa norms.
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

    @property
    def bounded(self) -> bool:
        """Not diverged, finite, and both growths below BLOWUP."""
        return (self.status != "diverged" and self.finite and self.growth_sigma < BLOWUP
                and self.growth_u < BLOWUP)


def _scaled(factor: float) -> dict:
    """E, loads, c_nu, b, c1, c2, lambda1 times factor: u is unchanged, stresses scale."""
    return {"material.E": ("scale", factor), "material.viscoplastic.lambda1": ("scale", factor),
            "contact.normal_compliance.c_nu": ("scale", factor),
            "contact.friction.b": ("scale", factor), "contact.friction.c1": ("scale", factor),
            "contact.friction.c2": ("scale", factor), "loads.traction": ("scale", factor)}


def default_variants(raw: dict) -> list[Variant]:
    """The standard sweep: stiff viscosity (lambda1 with two steps), near-Signorini contact
    (large c_nu of (4.1), small and large gaps g), friction (4.2) (all stick, frictionless,
    violating (2.6)), tiny, large and pulling loads, extreme Poisson ratios, material
    scaling, and very large and small time steps.

    Args:
        raw: the base case (unused: the variants are the same for every case).

    Returns:
        The Variants, the baseline first.
    """
    V = Variant
    out = [V("baseline", "baseline", {})]
    for lam in (100.0, 1.0, 0.01):
        for N in (16, 128):
            out.append(V("stiff viscosity", f"lambda1={lam:g}, k=1/{N}",
                         {"material.viscoplastic.lambda1": lam, "time.N": N}))
    for c in (1e4, 1e6):
        out.append(V("near-Signorini", f"c_nu={c:g}", {"contact.normal_compliance.c_nu": c}))
    for g in (1e-6, 1e-3, 1.0):
        out.append(V("near-Signorini", f"g={g:g}", {"contact.g": g}))
    out += [V("friction", "b=30 (all stick)", {"contact.friction.b": 30.0}),
            V("friction", "frictionless", {"contact.friction": None}),
            V("friction", "c1=300, b=3 (violates (2.6))",
              {"contact.friction.c1": 300.0, "contact.friction.b": 3.0}),
            V("loads", "tiny (x1e-6)", {"loads.traction": ("scale", 1e-6)}),
            V("loads", "large (x100)", {"loads.traction": ("scale", 100.0)}),
            V("loads", "pulling away (top +8)", {"loads.traction.top": [0.0, 8.0]}),
            V("material", "nu=0", {"material.nu": 0.0}),
            V("material", "nu=0.499", {"material.nu": 0.499}),
            V("material", "E scaled x1e-5 (E = 1e-2)", _scaled(1e-5), scale=1e-5),
            V("material", "E scaled x1e6 (E = 1e9)", _scaled(1e6), scale=1e6)]
    for N in (2, 1024):
        out.append(V("time step", f"k=1/{N}", {"time.N": N}))
    return out


def apply_changes(raw: dict, changes: dict) -> dict:
    """A copy of a case with a variant's changes.

    Args:
        raw: the case as read (not modified).
        changes: dotted key -> value, None (delete) or ("scale", f) (see Variant).

    Returns:
        The changed copy (missing sections are created).

    Raises:
        CaseError: ("scale", f) met something other than numbers.
    """
    raw = copy.deepcopy(raw)
    for key, value in changes.items():
        *path, last = key.split(".")
        node = raw
        for p in path:
            node = node.setdefault(p, {})
        if value is None:
            node.pop(last, None)
        elif isinstance(value, tuple) and value[0] == "scale":
            node[last] = _scale(node.get(last), value[1])
        else:
            node[last] = value
    return raw


def _scale(v, f):
    if isinstance(v, dict):
        return {k: _scale(x, f) for k, x in v.items()}
    if isinstance(v, list):
        return [_scale(x, f) for x in v]
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return v * f
    raise CaseError(f"cannot scale {v!r} (only numbers)")


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
    """
    import dataclasses

    from app.simulation import run

    r = apply_changes(raw, variant.changes)
    r.setdefault("time", {})["scheme"] = scheme
    t0 = time.perf_counter()
    try:
        case = validate(r, f"variant '{variant.name}'")
    except CaseError as exc:
        return Outcome(variant, scheme, "invalid", str(exc))
    case = dataclasses.replace(case, petsc={**case.petsc, **petsc_cli})
    level = log.level
    log.setLevel(logging.CRITICAL)
    try:
        res = run(case, comm)
    except CaseError as exc:   # found while setting up
        return Outcome(variant, scheme, "invalid", str(exc), wall_s=time.perf_counter() - t0)
    except Exception as exc:   # report, do not stop the sweep: every variant gets a row
        return Outcome(variant, scheme, "error", f"{type(exc).__name__}: {exc}",
                       wall_s=time.perf_counter() - t0, finite=False)
    finally:
        log.setLevel(level)
    s = res.summary
    steps = s["steps"]
    out = Outcome(variant, scheme, s["status"], s.get("failure", {}).get("reason", ""),
                  len(steps), max((st["newton_iterations"] for st in steps), default=0),
                  wall_s=time.perf_counter() - t0)
    d = s["diagnostics"]
    out.indicator, out.margin = d["stability_indicator"], d["wellposedness_margin"]
    if steps:
        sig = np.array([st["norm_sigma_Q"] for st in steps])
        uu = np.array([st["norm_u_V"] for st in steps])
        out.finite = bool(np.all(np.isfinite(sig)) and np.all(np.isfinite(uu)))
        out.growth_sigma = float(sig.max() / sig[0]) if sig[0] > 0 else math.nan
        out.growth_u = float(uu.max() / uu[0]) if uu[0] > 0 else math.nan
        out.norms = {"u": float(uu[-1]), "sigma": float(sig[-1]),
                     "kappa": float(steps[-1]["norm_kappa_Y"])}
    if out.status != "completed" and not out.finite:
        out.reason = out.reason or "non-finite solution"
    return out


def base_case(raw: dict, n: int, N: int, source: str = "case") -> dict:
    """The sweep's base: the case on a structured n x n mesh with N uniform steps.

    Args:
        raw: the case as read (not modified).
        n: cells per side (--n).
        N: time steps (--steps).
        source: the case file, for messages.

    Returns:
        The base case as a dict.

    Raises:
        CaseError: naming --n or --steps and the allowed values, or if the base is not a
            valid case with either history scheme.
    """
    for option, v in (("--n", n), ("--steps", N)):
        if not isinstance(v, int) or isinstance(v, bool) or v < 1:
            raise CaseError(f"{option}: {v!r} is not allowed (allowed: positive integers)")
    base = copy.deepcopy(raw)
    base["mesh"]["n"], base["time"] = n, {"T": base["time"].get("T", 1.0), "N": N}
    base["mesh"].pop("h", None)
    base["mesh"]["kind"] = "structured"
    errors = []
    for scheme in ("explicit", "implicit"):
        r = copy.deepcopy(base)
        r["time"]["scheme"] = scheme
        try:
            validate(r, f"{source} (stability base: --n {n}, --steps {N}, {scheme} scheme)")
        except CaseError as exc:
            errors.append(exc)
    if len(errors) == 2:
        raise errors[0]
    return base


def sweep(raw: dict, comm, petsc_cli: dict, n: int = 8, N: int = 8,
          variants: list[Variant] | None = None, source: str = "case") -> list[Outcome]:
    """Run every variant with each of its schemes (collective), then compare the scaling
    variants with the baseline.

    Args:
        raw: the case as read.
        comm: the MPI communicator.
        petsc_cli: PETSc options from the command line.
        n: cells per side of the base mesh.
        N: time steps of the base.
        variants: the variants (None: default_variants).
        source: the case file, for messages.

    Returns:
        One Outcome per (variant, scheme), in order.

    Raises:
        CaseError: before anything runs if the base case is not valid, and after the sweep
            if no variant was valid input.
    """
    base = base_case(raw, n, N, source)
    outcomes = []
    for v in variants or default_variants(base):
        for scheme in v.schemes:
            o = run_variant(base, v, scheme, comm, petsc_cli)
            outcomes.append(o)
            log.info("  %-16s %-34s %-8s %-9s steps %4d  max newton %3d  growth sigma %-9.3g "
                     "%s (%.2f s)", v.group, v.name, scheme, o.status, o.steps, o.max_newton,
                     o.growth_sigma, "bounded" if o.bounded else "BLOW-UP", o.wall_s)
    if outcomes and all(o.status == "invalid" for o in outcomes):
        raise CaseError(f"no variant of the stability sweep is a valid case: "
                        f"{outcomes[0].reason}")
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


def write_markdown(path, outcomes, case_name: str, n: int, N: int) -> None:
    """Write stability.md: a table of the Outcomes and a summary (runs completed, explicit
    blow-ups where the implicit scheme stays bounded), atomically.

    Args:
        path: the Markdown file.
        outcomes: the Outcomes of ``sweep``.
        case_name: the case's name, for the title.
        n: cells per side of the base mesh.
        N: time steps of the base.
    """
    lines = [f"# Stability report: {case_name}", "",
             f"Each variant runs on a structured {n} x {n} mesh with k = T/{N} unless it sets "
             "k itself, with the explicit (paper) and the implicit (right-end-point) history "
             "scheme. growth = max over the run / value at the first step; bounded = finite "
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
    atomic_write(path, "\n".join(lines) + "\n")
