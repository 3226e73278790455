"""``run --tol``: runs to a tolerance on the a posteriori estimate (app/post/estimators.py).

A pass is a whole run from t = 0 on the current mesh and time grid, so no history is carried
from one mesh to another in the middle of a run.  After pass i:

- stop if est_max <= tol * scale, the scale being max_n (||sigma_n||_Q + ||u_n||_V +
  ||kappa_n||_Y) of that pass (the size of the solution in the error measure's norms);
- else refine by the estimate's parts at the step of est_max (summary.json's
  ``error_estimate``): the mesh if the space part is at least half the time part, the time
  grid if the time part is at least half the space part (both when they are comparable).
  Space: Doerfler marking (theta = 0.5) of the cell indicators eta_K^2 = eta_Q,K^2 +
  eta_V,K^2 + eta_Y,K^2 at the step of est_max (``PeakIndicators``), whose cells are
  refined by ``meshes.adapt.refine_cells``.  Time: each step split into m_n equal parts,
  m_n from the time error the step made (est_time_local, ``split_counts``), so that the
  time part falls to its share of the tolerance (``time_ratio``): the grid grades itself
  to where the history changes fast (the paper case: the load applied at t = 0+).  With
  ``time.adaptive``: k halved (N twice as large) and its max_change halved.

The stop is also reached after ``max_passes`` passes or when the next mesh would exceed
``MAX_CELLS``, with a line saying that the tolerance was not met.
"""
from __future__ import annotations

import copy
import json
import logging
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from vpcontact.io.errors import CaseError
from vpcontact.observers import Observer

log = logging.getLogger("vpcontact")

THETA = 0.5                 # Doerfler's bulk fraction
MAX_CELLS = 2_000_000       # the largest mesh a pass may refine to
MAX_SPLIT = 16              # the most parts a time step is split into in one pass (2^4)
SAFETY = 0.8                # the share of the time part's budget aimed at


@dataclass
class Pass:
    """One pass of a run to a tolerance (a row of passes.csv)."""

    index: int
    cells: int
    dofs: int
    steps: int
    status: str
    est_max: float | None
    est_time: float | None
    est_space: float | None
    scale: float
    relative: float | None
    wall_s: float
    next: str                  # what the next pass refines: "h", "k", "h+k" or "stop"


def check_tolerance_case(case, raw: dict) -> None:
    """Refuse a case ``run --tol`` cannot refine (before any computation).

    Args:
        case: the validated Case.
        raw: its raw dict.

    Raises:
        CaseError: one line naming the file, the key and what --tol allows.
    """
    t = raw.get("time", {})
    if "adaptive" in t and "times" in t:
        raise CaseError(f"{case.source}: time.times: run --tol with time.adaptive halves a "
                        "grid of T with N or k (allowed: N, k, grading; or times without "
                        "adaptive)")


def doerfler(eta2: np.ndarray, theta: float = THETA) -> float:
    """Doerfler's threshold: the cells with eta_K^2 >= it hold at least theta of the sum.

    Args:
        eta2: every cell's eta_K^2 (all ranks).
        theta: the bulk fraction.

    Returns:
        The threshold (ties at it are all marked, so the marking does not depend on the
        order of the cells or on the ranks).
    """
    desc = np.sort(eta2)[::-1]
    cum = np.cumsum(desc)
    return float(desc[min(int(np.searchsorted(cum, theta * cum[-1])), len(desc) - 1)])


class PeakIndicators(Observer):
    """The cell indicators eta_K^2 (owned cells) at the step of est_max: recomputed by the
    run's ErrorEstimate's SpaceIndicators after each step that raises est_max (collective;
    est_max is global, so every rank recomputes at the same steps)."""

    def __init__(self):
        self.space, self.eta2 = None, None

    def start(self, sim) -> None:
        """Find the run's ErrorEstimate (Simulation.setup adds it).

        Args:
            sim: the Simulation, set up.
        """
        from vpcontact.post.estimators import ErrorEstimate
        est = next(o for o in sim.observers if isinstance(o, ErrorEstimate))
        self.space = est.space

    def step(self, sim, record: dict) -> None:
        """Keep eta_K^2 if step n raised est_max.

        Args:
            sim: the Simulation.
            record: step n's record (with est_total and est_max).
        """
        if record.get("est_total") is not None and record["est_total"] == record["est_max"]:
            self.eta2 = self.space.update().sum(axis=1)

    def marked(self, comm) -> np.ndarray:
        """The cells Doerfler marks (theta = THETA) over all ranks (collective).

        Args:
            comm: the MPI communicator.

        Returns:
            This rank's marked local cells.
        """
        if self.eta2 is None:
            return np.zeros(0, dtype=np.int32)
        everything = np.concatenate(comm.allgather(self.eta2))
        return np.flatnonzero(self.eta2 >= doerfler(everything)).astype(np.int32)


class LocalTimeErrors(Observer):
    """Each step's (t, k, est_time_local): the time error made in that step alone
    (app/post/estimators.py), by which ``graded_times`` splits the steps."""

    def __init__(self):
        self.steps = []

    def step(self, sim, record: dict) -> None:
        """Keep step n's time error.

        Args:
            sim: the Simulation.
            record: step n's record.
        """
        self.steps.append((record["t"], record["k"], record.get("est_time_local")))


def split_counts(local: np.ndarray, ratio: float, cap: int = MAX_SPLIT) -> np.ndarray:
    """Into how many equal parts each step is split so that the time error falls by ratio.

    A step's error, l_n, falls as l_n / m when it is split into m (the first order of the
    scheme: m parts of a smooth step each make l_n / m^2; a jump of the data is met by the
    first part alone, with l_n / m).  The time part is the propagated sum of the l_n, damped
    by a relaxing history (app/post/estimators.py): the steps are made to equidistribute
    their error below max_n l_n / ratio, m_n >= ratio l_n / max_j l_j (a uniform l_n gives
    m_n = ratio, a jump in step 1 alone m_1 = ratio), rounded up to a power of 2, at most
    ``cap``: the grids of the passes are nested, as the meshes are, and a grid refined from
    h = k = 1/L keeps its points on a dyadic reference's (``convergence --adaptive``
    measures the true Error there).

    Args:
        local: l_n of every step (a step without one, NaN, counts as the largest).
        ratio: the factor by which the time error is to fall (> 1).
        cap: the most parts of one step in one pass.

    Returns:
        m_n per step (integers).
    """
    lam = np.asarray(local, dtype=float)
    finite = np.isfinite(lam)
    top = lam[finite].max() if finite.any() else 0.0
    want = np.full(len(lam), float(ratio))
    if top > 0.0:
        want = ratio * np.where(finite, lam, top).clip(min=0.0) / top
    powers = np.ceil(np.log2(np.maximum(want, 1.0)) * (1.0 - 1e-12))
    return np.minimum(2 ** powers.astype(int), cap)


def graded_times(times, local, ratio: float) -> list[float]:
    """The next pass's time points: step n of the grid split into m_n equal parts
    (``split_counts``).

    Args:
        times: the time points t_0..t_N of the pass.
        local: l_n, n = 1..N (est_time_local of each step).
        ratio: the factor by which the time error is to fall.

    Returns:
        The new time points (t_0..t_N kept).
    """
    times = np.asarray(times, dtype=float)
    out = [times[:1]]
    for a, b, m in zip(times[:-1], times[1:], split_counts(local, ratio)):
        out.append(np.append(a + (b - a) * np.arange(1, m) / m, b))   # b itself, exactly
    return [float(t) for t in np.concatenate(out)]


def time_ratio(estimate: dict, tol: float) -> float:
    """The factor by which the next pass's time part is to fall: to its budget, the
    tolerance less the space part, at most half the tolerance when the space part is refined
    too, times SAFETY; at least 2 (a pass refining k halves it at least).

    Args:
        estimate: the pass's summary error_estimate ("time", "space", "scale").
        tol: the relative tolerance.

    Returns:
        time / budget, at least 2.
    """
    allowed = tol * estimate["scale"]
    space = estimate["space"] or 0.0
    budget = SAFETY * (allowed - space if space < 0.5 * allowed else 0.5 * allowed)
    return max(2.0, (estimate["time"] or 0.0) / budget)


def finer_in_time(raw: dict, local: list | None = None, ratio: float = 2.0) -> dict:
    """The next pass's time grid.

    Args:
        raw: the case's raw dict (not modified).
        local: (t_n, k_n, est_time_local_n) of the pass's steps; None, or a case with
            ``time.adaptive``: the uniform refinement.
        ratio: the factor by which the time error is to fall (``time_ratio``).

    Returns:
        A copy with the steps split by ``graded_times`` (time.times); with time.adaptive,
        N doubled (k halved) and its max_change halved.
    """
    raw = copy.deepcopy(raw)
    t = raw["time"]
    if local is not None and "adaptive" not in t:
        times = [0.0] + [row[0] for row in local]
        raw["time"] = {key: v for key, v in t.items()
                       if key not in ("T", "N", "k", "grading", "times")}
        raw["time"]["times"] = graded_times(times, [row[2] for row in local], ratio)
        return raw
    t["N"] = 2 * (t["N"] if "N" in t else int(round(float(t["T"]) / float(t.pop("k")))))
    if isinstance(t.get("adaptive"), dict):
        t["adaptive"]["max_change"] = 0.5 * float(t["adaptive"].get("max_change", 0.2))
    return raw


def what_next(estimate: dict) -> str:
    """What the next pass refines.

    Args:
        estimate: the pass's summary error_estimate ("space", "time").

    Returns:
        "h", "k" or "h+k": the part(s) within a factor 2 of the larger (module docstring).
    """
    space, tpart = estimate["space"] or 0.0, estimate["time"] or 0.0
    parts = [p for p, a, b in (("h", space, tpart), ("k", tpart, space)) if a >= 0.5 * b]
    return "+".join(parts)


def write_passes(outdir: Path, passes: list[Pass], tol: float, met: bool) -> None:
    """passes.csv and passes.json (rank 0).

    Args:
        outdir: the run's output directory.
        passes: the passes so far.
        tol: the tolerance.
        met: whether the last pass met it.
    """
    rows = [asdict(p) for p in passes]
    cols = list(rows[0]) if rows else []
    lines = [",".join(cols)] + [",".join("" if r[c] is None else str(r[c]) for c in cols)
                                for r in rows]
    (outdir / "passes.csv").write_text("\n".join(lines) + "\n")
    (outdir / "passes.json").write_text(json.dumps(
        {"tol": tol, "met": met, "theta": THETA, "passes": rows}, indent=1) + "\n")


def log_table(passes: list[Pass], tol: float) -> None:
    """The final table of the passes, in the log.

    Args:
        passes: the passes.
        tol: the tolerance.
    """
    log.info("pass  cells    dofs  steps  est_max (time, space)       relative  wall_s")
    for p in passes:
        log.info("%4d %6d %7d %6d  %.4g (%.3g, %.3g)  %.3g  %.2f", p.index, p.cells, p.dofs,
                 p.steps, p.est_max or float("nan"), p.est_time or float("nan"),
                 p.est_space or float("nan"), p.relative or float("nan"), p.wall_s)
    log.info("tolerance %g, total wall %.2f s", tol, sum(p.wall_s for p in passes))


def run_passes(raw: dict, case, comm, tol: float, max_passes: int, outdir: Path,
               observers, validate) -> tuple[list[Pass], bool, object]:
    """The passes (module docstring).

    Args:
        raw: the case's raw dict.
        case: the validated Case.
        comm: the MPI communicator.
        tol: the relative tolerance.
        max_passes: the most passes.
        outdir: the output directory; pass i writes into outdir/pass_<i>.
        observers: called with no argument, the observers of one pass (new ones each time).
        validate: (raw, source) -> Case.

    Returns:
        (passes, met, the last pass's RunResult).
    """
    from vpcontact.meshes.adapt import refine_cells
    from vpcontact.simulation import build_mesh, run

    passes, domain, result, met = [], None, None, False
    for i in range(1, max_passes + 1):
        wall = time.perf_counter()
        domain = domain if domain is not None else build_mesh(case, comm)
        peak, steps, where = PeakIndicators(), LocalTimeErrors(), outdir / f"pass_{i}"
        if comm.rank == 0:
            where.mkdir(parents=True, exist_ok=True)
        comm.barrier()
        result = run(case, comm, [peak, steps, *observers()], outdir=where, mesh=domain)
        s, est = result.summary, result.summary.get("error_estimate") or {}
        scale = est.get("scale", 0.0)                  # estimators.scale_of of the pass
        rel = est.get("relative")
        met = result.status == "completed" and rel is not None and rel <= tol
        nxt = "stop" if met or result.status != "completed" or not est else what_next(est)
        if nxt != "stop" and i < max_passes:
            if "h" in nxt:
                domain = refine_cells(domain, peak.marked(comm))
            if "k" in nxt:
                raw = finer_in_time(raw, steps.steps, time_ratio(est, tol))
                case = validate(raw, case.source)
        row = Pass(i, s["mesh"]["cells"], s["mesh"]["dofs"], s["time"]["N"], result.status,
                   est.get("estimate"), est.get("time"), est.get("space"), scale, rel,
                   time.perf_counter() - wall, nxt if i < max_passes else "stop")
        passes.append(row)
        log.info("pass %d: %d cells, %d dofs, %d steps: estimate %.4g (time %.4g, space "
                 "%.4g), %.3g of the scale %.4g (tol %g), wall %.2f s; next: %s", i, row.cells,
                 row.dofs, row.steps, row.est_max or float("nan"), row.est_time or float("nan"),
                 row.est_space or float("nan"), rel or float("nan"), scale, tol, row.wall_s,
                 row.next)
        if comm.rank == 0:
            write_passes(outdir, passes, tol, met)
        if row.next == "stop" or _too_large(domain, comm):
            break
    return passes, met, result


def _too_large(domain, comm) -> bool:
    """The next mesh exceeds MAX_CELLS (said in the log)."""
    cells = comm.allreduce(domain.mesh.topology.index_map(domain.mesh.topology.dim).size_local)
    if cells > MAX_CELLS:
        log.warning("run --tol: the next mesh would have %d cells (more than %d): stopped",
                    cells, MAX_CELLS)
        return True
    return False


def promote_final(outdir: Path, index: int) -> list[Path]:
    """Move the final pass's files from outdir/pass_<index> into outdir (rank 0).

    Args:
        outdir: the run's output directory.
        index: the final pass.

    Returns:
        The files' new paths.
    """
    src, moved = outdir / f"pass_{index}", []
    for f in sorted(src.iterdir()):
        target = outdir / f.name
        f.replace(target)
        moved.append(target)
    src.rmdir()
    return moved
