"""Convergence study and work-precision view (the paper's Table 1 and beyond it).

Error = max_n ( ||sigma_n - sigma_n^ref||_Q + ||u_n - u_n^ref||_V + ||kappa_n - kappa_n^ref||_Y )
over the time points t_n of the coarse run (all of them are reference time points), with the
coarse fields prolonged exactly to the reference mesh (app/studies/grid.py) and the norms integrated
there (the paper's Table 1).  ``vary``: "both" refines h = L/n and k = T/N together (n = N =
level), "h" keeps k at the reference, "k" keeps h at the reference.

Wall time of a run = the sum of its steps' times (history update, SNES solve, stress update),
measured with time.perf_counter around each step; mesh generation, JIT compilation, form and
matrix set-up, outputs and the sampling for this study are excluded (reported apart as
set-up).  A cached run reports the times measured when it was computed.
"""
from __future__ import annotations

import copy
import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.io.case import CaseError, validate
from app.io.output import atomic_write, csv_text
from app.observers import Observer
from app.studies import runcache
from app.studies.grid import Grid, GridSampler, cell_l2_norm, prolong_dg0, prolong_p1, strain_norm

log = logging.getLogger("vpcontact")

# Wang & Cheng (2021), Table 1: h = k = 1/8 .. 1/64 against h = k = 1/128.
PAPER_TABLE1 = {8: 23.1363, 16: 19.6575, 32: 13.2976, 64: 6.1820}
PAPER_RATES = {16: 0.2351, 32: 0.5639, 64: 1.1050}
PAPER_DATA = {  # the paper's Section 4
    ("mesh", "L1"): 1.0, ("mesh", "L2"): 1.0, ("time", "T"): 1.0,
    ("material", "E"): 1000.0, ("material", "nu"): 0.4,
}


@dataclass
class RunRecord:
    """One run of the study.

    Args:
        n: cells per side of the mesh (h = L1 / n).
        N: time steps (k = T / N).
        delta: the regularisation width of the run.
        grid: the structured grid of its mesh.
        dofs: the number of displacement dofs.
        times: t_0, ..., t_N, shape (N + 1,).
        solve_s: wall time of the steps [s].
        setup_s: wall time of the set-up [s].
        newton: Newton iterations of all steps.
        cached: whether it came from the run cache.
        snaps: the grid fields (u, sigma, kappa) per time point; only on rank 0.
    """

    n: int
    N: int
    delta: float
    grid: Grid
    dofs: int
    times: np.ndarray
    solve_s: float
    setup_s: float
    newton: int
    cached: bool
    snaps: list = field(default_factory=list, repr=False)


def plan_runs(levels: list[int], reference: int, vary: str, case=None,
              deltas: list[float] | None = None) -> list[tuple[int, int]]:
    """The resolutions of the study's levels, checking that meshes and time grids nest in the
    reference (and, given the case, that its mesh is structured and that the case is valid at
    every level and the reference with every delta).

    Args:
        levels: the levels (n = N = level for vary "both"), strictly increasing, each a
            divisor of ``reference``.
        reference: the reference level (h = k = 1/128 for Table 1).
        vary: "both" (h and k together), "h" (k at the reference) or "k" (h at the
            reference).
        case: the validated Case, or None to check the numbers only.
        deltas: the regularisation widths to run (None: the case's).

    Returns:
        (n, N) of each level: cells per side and time steps.

    Raises:
        CaseError: naming the option and the allowed values.
    """
    if case is not None and case.mesh.kind != "structured":
        raise CaseError(f"{case.source}: mesh.kind: the convergence study needs nested meshes "
                        "(structured); got 'unstructured'")
    if case is not None and case.dim != 2:
        raise CaseError(f"{case.source}: mesh.dim: the convergence study is for 2D cases "
                        "(nested structured rectangles)")
    if case is not None and ("times" in case.raw["time"] or "grading" in case.raw["time"]):
        raise CaseError(f"{case.source}: time: the convergence study refines uniform steps; "
                        "give time.T and time.N")
    if vary not in ("both", "h", "k"):
        raise CaseError(f"--vary: {vary!r} is not allowed (allowed: both, h, k)")
    if not levels or any(L < 1 for L in levels) or reference < 1:
        raise CaseError("--levels and --reference must be positive integers")
    if sorted(set(levels)) != list(levels):
        raise CaseError(f"--levels must increase strictly, got {levels}")
    bad = [L for L in levels if reference % L or L >= reference]
    if bad:
        raise CaseError(f"--levels {bad}: every level must divide the reference {reference} and "
                        "be smaller (nested meshes and common time points)")
    if deltas is not None and (not deltas or not all(
            isinstance(d, (int, float)) and math.isfinite(d) and d > 0 for d in deltas)):
        raise CaseError(f"--deltas {deltas}: not allowed (allowed: one or more finite "
                        "numbers > 0)")
    if deltas and len(set(deltas)) != len(deltas):
        raise CaseError(f"--deltas {deltas}: a delta is repeated (allowed: distinct finite "
                        "numbers > 0)")
    plan = [(L, L) if vary == "both" else (L, reference) if vary == "h" else (reference, L)
            for L in levels]
    if case is not None:
        ds = list(deltas) if deltas else [case.numerics.delta]
        ref_delta = min([case.numerics.delta, *ds])
        _case_at(case.raw, reference, reference, ref_delta, case.source)
        for n, N in plan:
            for delta in ds:
                _case_at(case.raw, n, N, delta, case.source)
    return plan


def check_cache_dir(cache_dir: Path | None, comm) -> None:
    """Check the run cache directory (collective; tested on rank 0, which writes the cache).

    Args:
        cache_dir: the run cache directory, or None (no cache: nothing to check).
        comm: the MPI communicator.

    Raises:
        CaseError: on every rank, unless ``cache_dir`` is (or can be made) a writable
            directory.
    """
    if cache_dir is None:
        return
    from app.io.cachedirs import unusable
    why = comm.bcast(unusable(Path(cache_dir)) if comm.rank == 0 else None, root=0)
    if why:
        raise CaseError(f"--cache-dir {cache_dir}: not a writable directory ({why})")


def _case_at(raw: dict, n: int, N: int, delta: float, source: str):
    raw = copy.deepcopy(raw)
    raw["mesh"]["n"], raw["time"]["N"] = n, N
    raw["time"].pop("k", None)
    raw.setdefault("solver", {})["delta"] = delta
    return validate(raw, source)


class GridSamples(Observer):
    """Samples u_n, sigma_n, kappa_n on the study's grid at t_0 and after every step (an
    observer of the run); ``snaps`` (one dict per time point) on rank 0 only.

    Args:
        grid: the structured grid of the run's mesh.
    """

    def __init__(self, grid: Grid):
        self.grid, self.snaps, self.sampler = grid, [], None

    def start(self, sim) -> None:
        """Sample the start state (t_0) (collective).

        Args:
            sim: the Simulation, set up.
        """
        self._sample(sim)

    def step(self, sim, record: dict) -> None:
        """Sample u_n, sigma_n, kappa_n after step n (collective).

        Args:
            sim: the Simulation after step n was accepted.
            record: the step's record (unused).
        """
        self._sample(sim)

    def _sample(self, sim) -> None:
        if self.sampler is None:
            self.sampler = GridSampler(sim.problem, self.grid)
        snap = self.sampler.sample(sim.problem, sim.history)     # collective
        if sim.comm.rank == 0:
            self.snaps.append(snap)


def _from_cache(path: Path | None, case, grid: Grid):
    """(times, snaps, meta) of the cached run at ``path``, or None: not cached, or an entry
    that is damaged or does not fit the run (a warning; the run is computed again)."""
    if path is None or not path.exists():
        return None
    n = grid.n
    shapes = {"u": (n + 1, n + 1, 2), "sigma": (n, n, 2, 2, 2), "kappa": (n, n, 2)}
    try:
        return runcache.load(path, case.time.times, shapes)
    except runcache.Unreadable as exc:
        log.warning("run cache entry %s is not usable (%s): computing the run again", path, exc)
        return None


def obtain_run(raw: dict, n: int, N: int, delta: float, source: str, petsc_cli: dict, comm,
               cache_dir: Path | None) -> RunRecord:
    """Run (or load from the cache) the case at resolution (n, N) with regularisation delta
    (collective); a computed run is added to the cache.

    Args:
        raw: the case as read (a dict).
        n: cells per side.
        N: time steps.
        delta: the regularisation width.
        source: the case file, for messages.
        petsc_cli: PETSc options from the command line (over the case's).
        comm: the MPI communicator.
        cache_dir: the run cache directory, or None.

    Returns:
        The RunRecord (with its grid samples on rank 0).

    Raises:
        RuntimeError: the run did not complete.
    """
    import dataclasses

    from app.simulation import run

    case = _case_at(raw, n, N, delta, source)
    case = dataclasses.replace(case, petsc={**case.petsc, **petsc_cli})
    grid = Grid(n, case.mesh.L1, case.mesh.L2, case.mesh.diagonal)
    path = cache_dir / f"run-{runcache.cache_key(case)}.h5" if cache_dir else None
    cached = _from_cache(path, case, grid) if comm.rank == 0 else None
    if comm.bcast(cached is not None, root=0):
        times, snaps, meta = cached if comm.rank == 0 else (None, [], None)
        meta = comm.bcast(meta, root=0)
        times = comm.bcast(times, root=0)
        log.info("  n = %4d, N = %4d, delta = %g: from the cache (%s)", n, N, delta, path.name)
        return RunRecord(n, N, delta, grid, meta["dofs"], np.asarray(times), meta["solve_s"],
                         meta["setup_s"], meta["newton"], True, snaps)

    sampler = GridSamples(grid)
    level = log.level
    log.setLevel(max(level, logging.WARNING))   # one line per run, not per step
    try:
        result = run(case, comm, [sampler])
    finally:
        log.setLevel(level)
    snaps = sampler.snaps
    s = result.summary
    if result.status != "completed":
        raise RuntimeError(f"run n = {n}, N = {N}, delta = {delta:g} failed: "
                           f"{s['failure']['reason']} at step {s['failure']['step']}")
    rec = RunRecord(n, N, delta, grid, s["mesh"]["dofs"], np.array(case.time.times),
                    s["solve_s"], s["setup_s"], s["newton_iterations_total"], False, snaps)
    log.info("  n = %4d, N = %4d, delta = %g: %d dofs, %.2f s (+ set-up %.2f s), "
             "%d Newton iterations", n, N, delta, rec.dofs, rec.solve_s, rec.setup_s, rec.newton)
    if path and comm.rank == 0:
        try:
            runcache.save(path, case.time.times, snaps,
                          {"dofs": rec.dofs, "solve_s": rec.solve_s, "setup_s": rec.setup_s,
                           "newton": rec.newton, "n": n, "N": N, "delta": delta})
        except OSError as exc:        # e.g. a full disk: the study goes on without the entry
            log.warning("run not cached (%s: %s)", path, exc.strerror or exc)
    return rec


def run_error(level: RunRecord, ref: RunRecord) -> dict:
    """The Error of the paper's Table 1 of a level against the reference (on rank 0):
    max over the level's time points t_n of
    ||sigma_n - sigma_n^ref||_Q + ||u_n - u_n^ref||_V + ||kappa_n - kappa_n^ref||_Y,
    the level's fields prolonged exactly to the reference grid.

    Args:
        level: the level's run (with snaps).
        ref: the reference run (with snaps).

    Returns:
        {"error", "e_sigma", "e_u", "e_kappa", "n_max", "t_max"}: the Error, its three
        parts at the maximising time point, and that point's index and time.

    Raises:
        ValueError: a time point of the level is not a reference time point.
    """
    best = None
    for i, t in enumerate(level.times):
        m = int(np.argmin(np.abs(ref.times - t)))
        if abs(ref.times[m] - t) > 1e-12 * max(1.0, abs(t)):
            raise ValueError(f"time {t} of the level is not a reference time point")
        a, b = level.snaps[i], ref.snaps[m]
        e_u = strain_norm(prolong_p1(a["u"], level.grid, ref.grid) - b["u"], ref.grid)
        e_s = cell_l2_norm(prolong_dg0(a["sigma"], level.grid, ref.grid) - b["sigma"], ref.grid)
        e_k = cell_l2_norm(prolong_dg0(a["kappa"], level.grid, ref.grid) - b["kappa"], ref.grid)
        total = e_s + e_u + e_k
        if best is None or total > best["error"]:
            best = {"error": total, "e_sigma": e_s, "e_u": e_u, "e_kappa": e_k, "n_max": i,
                    "t_max": float(t)}
    return best


def observed_rates(x: list[float], err: list[float]) -> list[float | None]:
    """The observed convergence rates between consecutive levels (Table 1's rates).

    Args:
        x: the mesh size (or step) of each level.
        err: the Error of each level.

    Returns:
        rate_i = log(E_{i-1} / E_i) / log(x_{i-1} / x_i); None for the first level.
    """
    return [None] + [math.log(err[i - 1] / err[i]) / math.log(x[i - 1] / x[i])
                     for i in range(1, len(err))]


def matches_paper(raw: dict) -> bool:
    """Whether a case carries the paper's Section 4 data (so Table 1 applies).

    Args:
        raw: the case as read (a dict).

    Returns:
        True if it validates and has the paper's geometry, material, contact, friction (4.2)
        and loads; False otherwise.
    """
    try:
        c = validate(raw, "paper-check")
    except CaseError:
        return False
    fr = c.contact.friction
    vp = c.material.viscoplastic
    return (c.mesh.kind == "structured" and c.mesh.L1 == 1.0 and c.mesh.L2 == 1.0
            and c.time.T == 1.0 and (c.material.E, c.material.nu) == (1000.0, 0.4)
            and vp is not None and (vp.lambda1, vp.lambda2, vp.kappa0) == (100.0, 100.0, 0.0)
            and (c.contact.g, c.contact.c_nu) == (0.012, 100.0) and fr is not None
            and (fr.b, fr.c1, fr.c2, fr.u1) == (1.0, 60.0, 60.0, 0.01)
            and c.loads.traction == {"top": (0.0, -8.0), "right": (-3.2, 0.0)}
            and not any(c.loads.f0))


COLUMNS = ["delta", "level", "h", "k", "n", "N", "dofs", "steps", "error", "e_sigma", "e_u",
           "e_kappa", "n_max", "t_max", "rate", "solve_s", "setup_s", "newton_total", "cached"]


def study(raw: dict, source: str, levels: list[int], reference: int, vary: str,
          deltas: list[float], comm, cache_dir: Path | None, petsc_cli: dict) -> dict:
    """Run the convergence study (collective): the reference run, then every level with
    every delta, and the Error of Table 1 of each against the reference.

    Args:
        raw: the case as read (a dict).
        source: the case file, for messages.
        levels: the levels, strictly increasing, each dividing ``reference``.
        reference: the reference level.
        vary: "both", "h" or "k" (see plan_runs).
        deltas: the regularisation widths (empty: the case's).
        comm: the MPI communicator.
        cache_dir: the run cache directory, or None.
        petsc_cli: PETSc options from the command line.

    Returns:
        {"rows": one dict per (delta, level) with the COLUMNS, "reference": its RunRecord,
        "ref_norms": the reference's max_n norms, "vary", "levels", "reference_level",
        "deltas", "ref_delta", "paper": whether Table 1 applies, "total_s"}, on every rank.

    Raises:
        CaseError: the study's options or the case do not fit (see plan_runs).
    """
    base = validate(raw, source)
    plan = plan_runs(levels, reference, vary, base, deltas)
    check_cache_dir(cache_dir, comm)
    deltas = list(deltas) if deltas else [base.numerics.delta]
    ref_delta = min([base.numerics.delta, *deltas])
    T, L1 = base.time.T, base.mesh.L1
    t0 = time.perf_counter()
    log.info("reference run n = N = %d (delta = %g)", reference, ref_delta)
    ref = obtain_run(raw, reference, reference, ref_delta, source, petsc_cli, comm, cache_dir)
    rows = []
    for delta in deltas:
        log.info("levels %s (vary %s, delta = %g)", levels, vary, delta)
        recs = [obtain_run(raw, n, N, delta, source, petsc_cli, comm, cache_dir) for n, N in plan]
        errs = [run_error(r, ref) if comm.rank == 0 else None for r in recs]
        errs = comm.bcast(errs, root=0)
        xs = [L1 / r.n if vary != "k" else T / r.N for r in recs]
        printed = [float(f"{e['error']:.10g}") for e in errs]
        rates = observed_rates(xs, printed)
        for L, r, e, p, rate in zip(levels, recs, errs, printed, rates):
            rows.append({"delta": delta, "level": L, "h": L1 / r.n, "k": T / r.N, "n": r.n,
                         "N": r.N, "dofs": r.dofs, "steps": r.N, "error": p,
                         "e_sigma": e["e_sigma"], "e_u": e["e_u"], "e_kappa": e["e_kappa"],
                         "n_max": e["n_max"], "t_max": e["t_max"], "rate": rate,
                         "solve_s": r.solve_s, "setup_s": r.setup_s, "newton_total": r.newton,
                         "cached": r.cached})
    ref_norms = None
    if comm.rank == 0:
        ref_norms = {
            "sigma_Q": max(cell_l2_norm(sn["sigma"], ref.grid) for sn in ref.snaps),
            "u_V": max(strain_norm(sn["u"], ref.grid) for sn in ref.snaps),
            "kappa_Y": max(cell_l2_norm(sn["kappa"], ref.grid) for sn in ref.snaps)}
    ref_norms = comm.bcast(ref_norms, root=0)
    return {"rows": rows, "reference": ref, "ref_norms": ref_norms, "vary": vary,
            "levels": levels,
            "reference_level": reference, "deltas": deltas, "ref_delta": ref_delta,
            "paper": matches_paper(raw) and vary == "both" and reference == 128,
            "total_s": time.perf_counter() - t0}


# ----------------------------------------------------------------------------- reports
def _fmt(v, digits=4):
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def write_csv(path: Path, res: dict) -> None:
    """Write the study's rows as CSV (the COLUMNS; floats at full precision), atomically.

    Args:
        path: the CSV file.
        res: the result of ``study``.
    """
    atomic_write(path, csv_text(COLUMNS, res["rows"]))


def paper_sentence(rows: list[dict]) -> str:
    """Compare the study's Errors and rates with the paper's Table 1.

    Args:
        rows: the study's rows of one delta.

    Returns:
        One sentence: the range of our/paper Error ratios, whether they agree to 10%, and
        the observed rates beside the paper's; "" if no level is one of the paper's.
    """
    ours = {r["level"]: r for r in rows}
    common = [L for L in PAPER_TABLE1 if L in ours]
    if not common:
        return ""
    ratio = [ours[L]["error"] / PAPER_TABLE1[L] for L in common]
    rates = [(L, ours[L]["rate"], PAPER_RATES[L]) for L in common if L in PAPER_RATES
             and ours[L]["rate"] is not None]
    agree = all(abs(r - 1) < 0.1 for r in ratio)
    text = (f"Our errors are {min(ratio):.3g} to {max(ratio):.3g} times the paper's "
            f"({'they agree to 10%' if agree else 'they do not agree in magnitude'}); observed "
            "rates ours/paper: " + ", ".join(f"h = 1/{L}: {a:.3f}/{b:.4f}" for L, a, b in rates))
    return text + "."


def write_markdown(path: Path, res: dict, case_name: str) -> None:
    """Write the study's report (the Error definition, a table per delta, the paper's
    Table 1 beside it when it applies, and ``explain``), atomically.

    Args:
        path: the Markdown file.
        res: the result of ``study``.
        case_name: the case's name, for the title.
    """
    ref = res["reference"]
    var = "h = k" if res["vary"] == "both" else res["vary"]
    lines = [f"# Convergence study: {case_name}", "",
             f"Refined: {var} (`--vary {res['vary']}`); reference n = N = "
             f"{res['reference_level']} ({ref.dofs} dofs, {ref.N} steps, delta = "
             f"{res['ref_delta']:g}, solve time {ref.solve_s:.2f} s"
             f"{', cached' if ref.cached else ''}).", "",
             "Error = max_n (||sigma_n - sigma_n^ref||_Q + ||u_n - u_n^ref||_V + "
             "||kappa_n - kappa_n^ref||_Y) over the level's time points; the level's fields "
             "are prolonged exactly to the reference mesh and the norms integrated there "
             "(||v||_V = ||eps(v)||_L2, Frobenius). Parts are given at the maximising step "
             "n_max.", "",
             "Wall time = sum over the steps of the time spent in the history update, the SNES "
             "solve and the stress update (time.perf_counter); mesh generation, JIT "
             "compilation, set-up, outputs and sampling are excluded (set-up column). Cached "
             "runs show the times measured when they were computed.", ""]
    for delta in res["deltas"]:
        rows = [r for r in res["rows"] if r["delta"] == delta]
        paper = res["paper"]
        head = ["h", "k", "dofs", "steps", "Error", "sigma part", "u part", "kappa part",
                "n_max", "rate", "wall s", "set-up s", "Newton"]
        if paper:
            head += ["paper Error", "paper rate"]
        lines += [f"## delta = {delta:g}", "", "| " + " | ".join(head) + " |",
                  "|" + "---|" * len(head)]
        for r in rows:
            cells = [f"1/{round(1 / r['h'])}" if abs(1 / r["h"] - round(1 / r["h"])) < 1e-9
                     else _fmt(r["h"]),
                     f"1/{round(1 / r['k'])}" if abs(1 / r["k"] - round(1 / r["k"])) < 1e-9
                     else _fmt(r["k"]),
                     r["dofs"], r["steps"], f"{r['error']:.6g}", _fmt(r["e_sigma"]),
                     _fmt(r["e_u"]), _fmt(r["e_kappa"]), r["n_max"], _fmt(r["rate"]),
                     f"{r['solve_s']:.3f}", f"{r['setup_s']:.2f}", r["newton_total"]]
            if paper:
                cells += [_fmt(PAPER_TABLE1.get(r["level"])), _fmt(PAPER_RATES.get(r["level"]))]
            lines.append("| " + " | ".join(map(str, cells)) + " |")
        lines.append("")
        if paper:
            lines += [paper_sentence(rows), ""]
    lines += explain(res)
    atomic_write(path, "\n".join(lines) + "\n")


def explain(res: dict) -> list[str]:
    """Facts that explain where the Error comes from (and, for Table 1, the differences).

    Args:
        res: the result of ``study``.

    Returns:
        Markdown lines (a section with bullet points), or [] if there are no rows.
    """
    rows = [r for r in res["rows"] if r["delta"] == res["deltas"][0]]
    if not rows:
        return []
    fin = rows[-1]
    nr = res["ref_norms"]
    share = fin["e_sigma"] / fin["error"]
    out = ["## Where the error comes from", "",
           f"- At the finest level the stress part is {100 * share:.1f}% of the Error "
           f"(sigma {fin['e_sigma']:.4g}, u {fin['e_u']:.4g}, kappa {fin['e_kappa']:.4g}); the "
           "maximum over n is reached at step(s) n_max = "
           + ", ".join(str(r["n_max"]) for r in rows) + " (t = "
           + ", ".join(f"{r['t_max']:.4g}" for r in rows) + ").",
           f"- Size of the reference solution: max_n ||sigma_n||_Q = {nr['sigma_Q']:.4g}, "
           f"max_n ||u_n||_V = {nr['u_V']:.4g}, max_n ||kappa_n||_Y = {nr['kappa_Y']:.4g}.",
           "- The observed rate at the finest level is measured against a reference only "
           f"{res['reference_level'] // rows[-1]['level']}x finer; the reference's own error is "
           "then not negligible and this last rate is biased (for an error C h^p it "
           "overestimates p)."]
    if res["paper"]:
        big = max(PAPER_TABLE1.values())
        out.append(f"- The paper's Errors ({big} at h = 1/8) exceed the size of the solution "
                   f"itself (max_n ||sigma_n||_Q = {nr['sigma_Q']:.3g}); an error of that size "
                   "cannot be this Error in these norms for this solution, so the paper's norms "
                   "(or their scaling) must differ from the Error defined above; the paper does "
                   "not say how they were computed. Compare the rates, not the magnitudes.")
    return out + [""]


def write_plot(path: Path, res: dict) -> None:
    """Plot Error against h (or k) and against wall time (work-precision), with the
    paper's Table 1 when it applies, to a PNG (atomically).

    Args:
        path: the PNG file.
        res: the result of ``study``.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xkey = "k" if res["vary"] == "k" else "h"
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.5))
    for delta in res["deltas"]:
        rows = [r for r in res["rows"] if r["delta"] == delta]
        x = [r[xkey] for r in rows]
        e = [r["error"] for r in rows]
        ax1.loglog(x, e, "o-", label=f"delta = {delta:g}")
        ax2.loglog([max(r["solve_s"], 1e-4) for r in rows], e, "s-", label=f"delta = {delta:g}")
    rows = [r for r in res["rows"] if r["delta"] == res["deltas"][0]]
    if rows:
        x0, e0 = rows[-1][xkey], rows[-1]["error"]
        xs = np.array([r[xkey] for r in rows])
        ax1.loglog(xs, e0 * xs / x0, "k--", lw=1, label="slope 1")
    if res["paper"]:
        ax1.loglog([1 / L for L in PAPER_TABLE1], list(PAPER_TABLE1.values()), "x:",
                   color="grey", label="paper Table 1")
    ticks = sorted({r[xkey] for r in res["rows"]})
    ax1.set_xticks(ticks)
    ax1.set_xticklabels([f"1/{round(1 / x)}" if abs(1 / x - round(1 / x)) < 1e-9 else f"{x:g}"
                         for x in ticks])
    ax1.minorticks_off()
    ax1.set_xlabel(xkey if res["vary"] != "both" else "h = k")
    ax1.set_ylabel("Error")
    ax1.set_title(f"Error against {xkey} (reference 1/{res['reference_level']})")
    ax2.set_xlabel("wall time of the run [s] (steps only, no JIT)")
    ax2.set_ylabel("Error")
    ax2.set_title("work-precision")
    for ax in (ax1, ax2):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.tight_layout()
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    tmp.replace(path)
