"""Command line: ``./vpcontact run CASE.yaml`` (the launcher; ``python -m app`` in the project's
environment, or its ``vpcontact`` console script, are the same).

Arguments of the form ``-snes_rtol 1e-12`` / ``-ksp_view`` (one leading dash) are PETSc
options: they are passed unchanged to PETSc under our prefix (``vpcontact_``) and override
the case file's ``petsc`` section.  Exit codes: 0 done, 1 solver failure, 2 bad input.
"""
from __future__ import annotations

import argparse
import dataclasses
import logging
import re
import sys
import time
from pathlib import Path

from app import __version__
from app.io.case import CaseError

log = logging.getLogger("vpcontact")
_PETSC_OPT = re.compile(r"^-[A-Za-z][A-Za-z0-9_]*$")
_NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def split_petsc_args(argv: list[str]) -> tuple[list[str], dict]:
    """Separate PETSc options (single dash, e.g. -snes_monitor, -snes_rtol 1e-12) from ours.

    A PETSc option takes the next token as its value unless that token is itself an option
    (a negative number counts as a value)."""
    ours, petsc = [], {}
    i = 0
    while i < len(argv):
        tok = argv[i]
        if _PETSC_OPT.match(tok) and tok not in ("-h",):
            value = None
            if i + 1 < len(argv) and (not argv[i + 1].startswith("-") or _NUMBER.match(argv[i + 1])):
                value = argv[i + 1]
                i += 1
            petsc[tok[1:]] = value
        else:
            ours.append(tok)
        i += 1
    return ours, petsc


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer (allowed: 1 or more)") \
            from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} (allowed: 1 or more)")
    return value


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    import math
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number (allowed: > 0)") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text} (allowed: a finite number > 0)")
    return value


def cells_and_steps(text: str) -> tuple[int, int]:
    """argparse type of bench --extra: 'n:N' with positive integers."""
    parts = text.split(":")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"{text!r} (allowed: n:N, cells per side and time "
                                         "steps, e.g. 256:32)")
    try:
        return positive_int(parts[0]), positive_int(parts[1])
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"{text!r}: {exc} (allowed: n:N, e.g. 256:32)") \
            from None


def path_arg(text: str) -> str:
    """argparse type of a file or directory argument: not empty."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty path (allowed: a file or directory name)")
    return text


def _case_options(parser, what: str, default_out: str) -> None:
    """Options shared by the commands that read a case and write an output directory."""
    parser.add_argument("--out", metavar="DIR", type=path_arg, help=f"output directory (default: {default_out})")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE",
                        help="override a case key, e.g. --set mesh.n=32 --set time.N=32 "
                             "(repeatable)")
    parser.add_argument("--overwrite", action="store_true",
                        help=f"replace the outputs of an earlier {what} in the output directory")
    parser.add_argument("--quiet", action="store_true",
                        help="only warnings and errors (no progress bar)")
    parser.add_argument("--verbose", action="store_true",
                        help="one log line per step (norms, iterations, wall time) and the "
                             "PETSc monitors (-snes_monitor, -snes_converged_reason)")


class _Parser(argparse.ArgumentParser):
    """argparse with errors on one line (exit 2), like every other bad-input error."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="vpcontact",
        description="Quasistatic contact of a viscoplastic body with a foundation: normal "
                    "compliance, unilateral constraint u_nu <= g, nonmonotone friction "
                    "(Wang & Cheng 2021, scheme (3.2)-(3.4)), solved with dolfinx + PETSc.",
        epilog="PETSc options (e.g. -snes_monitor, -snes_rtol 1e-12, -pc_factor_mat_solver_type "
               "superlu_dist) may be added anywhere; they reach PETSc with the prefix "
               "vpcontact_. Run in parallel with: mpirun -n 2 ./vpcontact run CASE.yaml")
    p.add_argument("--version", action="version", version=f"vpcontact {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    run = sub.add_parser("run", help="run a case file",
                         description="Run a case: solve every time step, write "
                                     "solution.xdmf, summary.json and contact.csv.")
    run.add_argument("case", help="YAML case file (see cases/)")
    _case_options(run, "run", "results/<case name>")
    run.add_argument("--restart", metavar="DIR", type=path_arg,
                     help="continue from the newest DIR/checkpoint_*.npz (or a given "
                          "checkpoint file), written with output.checkpoint_every or when a "
                          "run is interrupted; the case must be the same (solver and output "
                          "settings may differ)")
    run.add_argument("--no-plots", action="store_true",
                     help="do not draw the figures at the end (see the plot command)")

    plot = sub.add_parser("plot", help="draw the figures of a results directory",
                          description="Draw fig3_deformed_contact.png, fig4_tangential.png, "
                                      "fig5_vm_kappa.png, fig2_laws.png and history.png "
                                      "(the paper's Figs. 2-5 and the run history) from "
                                      "the files of a run, headless (matplotlib, Agg).")
    plot.add_argument("results", metavar="RESULTS_DIR", help="output directory of a run")

    check = sub.add_parser("check", help="validate a case without solving (dry run)",
                           description="Validate a case and report what a run would do: "
                                       "mesh size, dofs, time steps, active and omitted "
                                       "terms, step solver, stability indicator and "
                                       "well-posedness margin. Nothing is solved or written.")
    check.add_argument("case", help="YAML case file")
    check.add_argument("--set", dest="overrides", action="append", default=[],
                       metavar="KEY=VALUE", help="override a case key (repeatable)")

    sub.add_parser("info", help="versions of dolfinx, PETSc, MPI, gmsh; JIT cache",
                   description="Print the versions of the numerical stack, PETSc's external "
                               "packages, the MPI library and where the JIT caches are.")

    conv = sub.add_parser(
        "convergence", help="convergence study: Error against h, k and wall time",
        description="Run a case at several resolutions and a reference, and report "
                    "Error = max_n (||sigma_n - sigma_n^ref||_Q + ||u_n - u_n^ref||_V + "
                    "||kappa_n - kappa_n^ref||_Y) per level with observed rates and wall times "
                    "(convergence.csv, convergence.md, convergence.png). Runs are cached.")
    conv.add_argument("case", help="YAML case file with a structured mesh")
    conv.add_argument("--levels", type=positive_int, nargs="+", default=[8, 16, 32, 64], metavar="L",
                      help="levels: 1/h and/or 1/k of each run (default: 8 16 32 64)")
    conv.add_argument("--reference", type=positive_int, default=128, metavar="R",
                      help="the reference run has n = N = R (default: 128)")
    conv.add_argument("--vary", choices=["both", "h", "k"], default="both",
                      help="refine h and k together, or one with the other at the reference")
    conv.add_argument("--deltas", type=positive_float, nargs="+", metavar="D",
                      help="friction regularisation widths to study (default: the case's); "
                           "the reference uses the smallest of these and the case's")
    _case_options(conv, "study", "results/<case name>/convergence")
    conv.add_argument("--cache-dir", metavar="DIR", type=path_arg,
                      help="run cache (default: $VPCONTACT_CACHE, else $XDG_CACHE_HOME/vpcontact, "
                           "else ~/.cache/vpcontact)")
    conv.add_argument("--no-cache", action="store_true", help="recompute every run")

    stab = sub.add_parser(
        "stability", help="sweep stiff and extreme variants of a case",
        description="Run stiff and extreme variants of a case (viscosity, near-Signorini "
                    "contact, friction, loads, material, time steps) with the explicit and "
                    "implicit history schemes on a coarse mesh, and report convergence, "
                    "growth, stability indicator and well-posedness margin "
                    "(stability.csv, stability.md).")
    stab.add_argument("case", help="YAML case file (2D)")
    _case_options(stab, "sweep", "results/<case name>/stability")
    stab.add_argument("--n", type=positive_int, default=8, help="cells per side of the coarse mesh")
    stab.add_argument("--steps", type=positive_int, default=8, help="time steps of the base variant")

    b = sub.add_parser("bench", help="time the step solvers on the paper case",
                       description="Whole-process timings of a case with each step solver, "
                                   "serial and under mpirun -n 2 (bench.json, bench.md).")
    b.add_argument("case", nargs="?", default="cases/wang_cheng_2021.yaml")
    b.add_argument("--levels", type=positive_int, nargs="+", default=[16, 32, 64, 128],
                   help="h = k = 1/L levels (default 16 32 64 128)")
    b.add_argument("--extra", type=cells_and_steps, nargs="*", default=[(256, 32)], metavar="n:N",
                   help="extra (cells per side : steps) runs (default 256:32)")
    b.add_argument("--memory-steps", type=positive_int, nargs="*", default=[64, 256, 1024, 4096],
                   metavar="N", help="step counts of the memory-term cost runs "
                                     "(recursion vs direct sum; none: skip)")
    b.add_argument("--ranks", type=positive_int, nargs="+", default=[1, 2])
    b.add_argument("--repeat", type=positive_int, default=3, metavar="R",
                   help="measured runs per configuration, every solver alike; the fastest "
                        "is reported, all are kept (default 3; the --extra levels run once)")
    b.add_argument("--out", default="results/bench", type=path_arg, help="output directory")
    return p


def quiet_jit_log() -> None:
    """FFCx installs a root log handler (logging.basicConfig) and cffi's distutils build
    lowers the root level to log every compiler call; keep those lines out of the run log."""
    import ffcx  # noqa: F401  (installs the handler on import)

    for handler in logging.getLogger().handlers:
        handler.setLevel(logging.WARNING)


def take_signals() -> None:
    """Signals as the CLI wants them, after PETSc has installed its handlers (it does when
    first imported): SIGPIPE ignored (PETSc would turn it into an MPI_Abort of the run; a
    write to a closed pipe then fails and app/cli/streams.py drops the stream), SIGINT and
    SIGTERM end the start-up with KeyboardInterrupt, caught by main (the time loop installs
    its own handler for both)."""
    import signal

    from petsc4py import PETSc  # noqa: F401  (PETSc installs its handlers when initialised)
    signal.signal(signal.SIGPIPE, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _terminate)
    signal.signal(signal.SIGINT, signal.default_int_handler)


def _terminate(signum, frame):
    raise KeyboardInterrupt


def _setup_logging(comm, quiet: bool, verbose: bool = False) -> None:
    level = logging.WARNING if quiet else logging.DEBUG if verbose else logging.INFO
    if comm.rank != 0:
        level = logging.CRITICAL     # collective messages: rank 0 says them once
    handler = logging.StreamHandler(sys.stdout)
    handler.setFormatter(logging.Formatter("[vpcontact] %(message)s"))
    log.handlers[:] = [handler]
    quiet_jit_log()
    log.setLevel(level)
    log.propagate = False


_LOCKS = []      # the output directories' lock files, held open until the process ends


def _lock_outdir(outdir: Path) -> str | None:
    """Create ``outdir`` and take its lock (rank 0); the reason if either is impossible.
    The lock (flock on outdir/.vpcontact.lock) is released by the kernel when the process
    ends, however it ends, so it never goes stale."""
    import fcntl
    if outdir.exists() and not outdir.is_dir():
        return f"--out {outdir}: exists and is not a directory (give a directory)"
    if outdir.is_dir():
        foreign = foreign_files(outdir)
        if foreign:
            shown = ", ".join(foreign[:5]) + (", ..." if len(foreign) > 5 else "")
            return (f"--out {outdir}: holds files that are not vpcontact outputs ({shown}); "
                    "give a new or empty directory, or one of an earlier run")
    try:
        outdir.mkdir(parents=True, exist_ok=True)
        fh = open(outdir / ".vpcontact.lock", "a+")
    except OSError as exc:
        return f"--out {outdir}: cannot write there: {exc.strerror}"
    try:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        fh.close()
        return (f"--out {outdir}: another vpcontact process is writing into this directory; "
                "wait for it to end or choose another --out")
    _LOCKS.append(fh)
    return None


# besides the files of each command: a run's directory holds its convergence/ and
# stability/ studies; checkpoints, figures, the lock and temporary files of atomic writes
OUR_DIRECTORIES = ("convergence", "stability", "bench")
OUR_PATTERNS = ("checkpoint_*.npz", "*.png", ".vpcontact.lock", ".solution.work.*", ".*.tmp*")


def foreign_files(outdir: Path) -> list[str]:
    """Names in ``outdir`` that no vpcontact command writes (sorted)."""
    from app.io.output import OUTPUT_FILES
    ours = {*OUTPUT_FILES, *CONVERGENCE_FILES, *STABILITY_FILES, *BENCH_FILES,
            *OUR_DIRECTORIES}
    return sorted(p.name for p in outdir.iterdir() if p.name not in ours
                  and not any(p.match(pattern) for pattern in OUR_PATTERNS))


def _prepare_outdir(comm, outdir: Path, overwrite: bool, files=None) -> None:
    """Create and lock the output directory; refuse to overwrite an earlier run unless
    asked, then remove its files (collective; CaseError on every rank if impossible)."""
    from app.io.output import OUTPUT_FILES

    why = None
    if comm.rank == 0:
        why = _lock_outdir(outdir)
    why = comm.bcast(why, root=0)
    if why:
        raise CaseError(why)
    existing = [f for f in (files or OUTPUT_FILES) if (outdir / f).exists()]
    if files is None:       # a run's checkpoints and figures belong to it as well
        from app.post.plot import FIGURES
        existing += sorted(p.name for p in outdir.glob("checkpoint_*.npz"))
        existing += [f for f in FIGURES if (outdir / f).exists()]
    if existing and not overwrite:
        raise CaseError(f"{outdir}: holds the outputs of an earlier run ({', '.join(existing)}); "
                        "pass --overwrite to replace them or --out DIR for another directory")
    comm.barrier()
    if comm.rank == 0:
        for f in existing:
            (outdir / f).unlink()
    comm.barrier()


def _start(args, subdir: str | None, files=None, check=None, petsc_cli=None):
    """Common start of the commands: logging, read and validate the case, the PETSc options
    of the command line and the command's own ``check``, prepare the output directory.
    Returns (comm, raw, case, outdir), or (comm, None, None, None) after printing the error
    (exit code 2: bad input)."""
    from mpi4py import MPI

    from app.io.case import load_raw, validate

    comm = MPI.COMM_WORLD
    _setup_logging(comm, args.quiet, getattr(args, "verbose", False))
    try:
        raw = load_raw(args.case, args.overrides)
        case = validate(raw, args.case)
        if petsc_cli:
            from app.io.petscopts import check_petsc_options
            check_petsc_options(petsc_cli, "command line", where="-", base=case.petsc)
        if check:
            check(case)
        outdir = Path(args.out) if args.out else \
            Path("results") / case.name / subdir if subdir else Path("results") / case.name
        _prepare_outdir(comm, outdir, args.overwrite, files)
    except CaseError as exc:
        _error(str(exc), 2)
        return comm, None, None, None
    return comm, raw, case, outdir


def cmd_run(args, petsc_cli: dict) -> int:
    """``vpcontact run``: a Simulation with the command line's observers (solution.xdmf,
    checkpoints, progress bar, per-step log, contact.csv and summary.json), then the figures.

    Args:
        args: the parsed command line.
        petsc_cli: PETSc options given on the command line.

    Returns:
        The exit code (see _report_run; 2: bad input).
    """
    from app.io.case import CaseError
    from app.io.checkpoint import Checkpoint, latest

    loaded = {}

    def check_restart(case):
        if not args.restart:
            return
        path = Path(args.restart)
        if path.is_dir():
            path = latest(path)
            if path is None:
                raise CaseError(f"--restart {args.restart}: no checkpoint_*.npz in that "
                                "directory (set output.checkpoint_every)")
        elif not path.is_file():
            raise CaseError(f"--restart {args.restart}: no such checkpoint file or directory")
        out = Path(args.out) if args.out else Path("results") / case.name
        if out.resolve() == path.parent.resolve():
            raise CaseError(f"--restart {args.restart}: --out {out} is the directory of the "
                            "checkpoint; give another --out (the new run would replace the "
                            "files it continues from)")
        loaded["checkpoint"] = Checkpoint(path)   # CheckpointError (a CaseError) if damaged
        why = loaded["checkpoint"].check(case)
        if why:
            raise CaseError(f"--restart: {why}")

    comm, _, case, outdir = _start(args, None, check=check_restart, petsc_cli=petsc_cli)
    if case is None:
        return 2

    from app.observers import Checkpointer, FieldOutput, ProgressBar, RunFiles, StepLog
    from app.simulation import run

    if args.verbose:
        petsc_cli = {"snes_monitor": None, "snes_converged_reason": None, **petsc_cli}
    case = dataclasses.replace(case, petsc={**case.petsc, **petsc_cli})
    log.info("vpcontact %s: case %s -> %s (%d MPI rank%s)", __version__, args.case, outdir,
             comm.size, "s" if comm.size > 1 else "")
    progress = [ProgressBar()] if not args.quiet and not args.verbose else []
    observers = [FieldOutput(), Checkpointer(), *progress, StepLog(), RunFiles()]
    result = run(case, comm, observers, outdir=outdir, restart=loaded.get("checkpoint"))
    s = result.summary
    if result.status == "completed" and not args.no_plots and comm.rank == 0 and s["steps"]:
        if _plots(outdir) == "interrupted":
            return EXIT_INTERRUPTED
    return _report_run(comm, s, outdir, args.no_plots)


def _report_run(comm, s: dict, outdir: Path, no_plots: bool) -> int:
    """The closing lines of a run and its exit code.

    Args:
        comm: the MPI communicator.
        s: the run's summary (summary.json's content).
        outdir: the output directory.
        no_plots: --no-plots was given.

    Returns:
        0 completed, 1 failed or diverged, 3 interrupted.
    """
    status = s["status"]
    if status == "completed":
        log.info("done: %d steps, %d Newton iterations, wall %.2f s (set-up %.2f s, steps %.2f s)",
                 len(s["steps"]), s["newton_iterations_total"], s["wall_s"], s["setup_s"],
                 s["loop_s"])
        if "contact_states" in s:
            log.info("Gamma3 nodes at T: %s", s["contact_states"])
        log.info("outputs: %s/{solution.xdmf, summary.json, contact.csv%s}", outdir,
                 "" if no_plots else ", *.png")
        return 0
    f = s["failure"]
    if comm.rank != 0:
        return EXIT_INTERRUPTED if status == "interrupted" else 1
    if status == "interrupted":
        print(f"vpcontact: {f['reason']} after step {f['step']} (t = {f['t']:g}); outputs up to "
              f"that step are in {outdir}; {f['hint']}", file=sys.stderr)
        return EXIT_INTERRUPTED
    what = "the run diverged" if status == "diverged" else "the run failed"
    print(f"vpcontact: error: {what} at step {f['step']} (t = {f['t']:g}): {f['reason']}; "
          f"outputs up to step {s['last_good_step']} are in {outdir}. Hint: {f['hint']}",
          file=sys.stderr)
    return 1


CONVERGENCE_FILES = ("convergence.csv", "convergence.md", "convergence.png")


def cmd_convergence(args, petsc_cli: dict) -> int:
    from mpi4py import MPI

    from app.studies import convergence as cv
    from app.studies.runcache import default_cache_dir

    cache_dir = None if args.no_cache else Path(args.cache_dir or default_cache_dir())

    def check(c):                     # every option, before anything is computed
        cv.plan_runs(args.levels, args.reference, args.vary, c, args.deltas)
        cv.check_cache_dir(cache_dir, MPI.COMM_WORLD)

    comm, raw, case, outdir = _start(args, "convergence", CONVERGENCE_FILES, check=check,
                                     petsc_cli=petsc_cli)
    if case is None:
        return 2
    log.info("vpcontact %s: convergence study of %s -> %s (cache: %s, %d MPI rank%s)",
             __version__, args.case, outdir, cache_dir or "off", comm.size,
             "s" if comm.size > 1 else "")
    try:
        res = cv.study(raw, args.case, args.levels, args.reference, args.vary, args.deltas,
                       comm, cache_dir, petsc_cli)
    except CaseError as exc:
        return _error(str(exc), 2)
    except RuntimeError as exc:
        return _error(str(exc), 1)
    if comm.rank == 0:
        cv.write_csv(outdir / "convergence.csv", res)
        cv.write_markdown(outdir / "convergence.md", res, case.name)
        cv.write_plot(outdir / "convergence.png", res)
        for r in res["rows"]:
            log.info("delta %-8g h %-9.5g k %-9.5g Error %.6g  rate %s  wall %.3f s%s",
                     r["delta"], r["h"], r["k"], r["error"],
                     "-" if r["rate"] is None else f"{r['rate']:.3f}", r["solve_s"],
                     " (cached)" if r["cached"] else "")
        log.info("done in %.1f s: %s/{%s}", res["total_s"], outdir, ", ".join(CONVERGENCE_FILES))
    comm.barrier()
    return 0


STABILITY_FILES = ("stability.csv", "stability.md")
BENCH_FILES = ("bench.json", "bench.md")


def _two_dimensional(case) -> None:
    if case.dim != 2:
        raise CaseError(f"{case.source}: mesh.dim: the stability sweep is for 2D cases")


def cmd_stability(args, petsc_cli: dict) -> int:
    from app.studies import stability as st

    def check(c):
        _two_dimensional(c)
        st.base_case(c.raw, args.n, args.steps, args.case)

    comm, raw, case, outdir = _start(args, "stability", STABILITY_FILES, check,
                                     petsc_cli=petsc_cli)
    if case is None:
        return 2
    log.info("vpcontact %s: stability sweep of %s -> %s", __version__, args.case, outdir)
    t0 = time.perf_counter()
    outcomes = st.sweep(raw, comm, petsc_cli, args.n, args.steps, source=args.case)
    if comm.rank == 0:
        st.write_csv(outdir / "stability.csv", outcomes)
        st.write_markdown(outdir / "stability.md", outcomes, case.name, args.n, args.steps)
    log.info("done in %.1f s: %s/{%s}", time.perf_counter() - t0, outdir,
             ", ".join(STABILITY_FILES))
    comm.barrier()
    return 0


def cmd_bench(args) -> int:
    from app.studies import bench as bm
    from app.io.cachedirs import unusable

    extra = list(args.extra)          # (n, N) pairs, parsed by cells_and_steps
    outdir = Path(args.out)
    try:                              # every argument and the case, before anything runs
        bm.check_arguments(args.case, args.levels, extra, args.ranks, args.repeat,
                           args.memory_steps or [])
        why = unusable(outdir)
        if why:
            raise CaseError(f"--out {outdir}: not a writable directory ({why})")
    except CaseError as exc:
        return _error(str(exc), 2)
    print(f"vpcontact bench: {args.case}, levels {args.levels}, extra {extra}, ranks {args.ranks}")
    t0 = time.perf_counter()
    try:
        rows = bm.bench(args.case, outdir, args.levels, nprocs=args.ranks, extra=extra,
                        repeat=args.repeat)
        memory = bm.memory_rows(outdir, steps=args.memory_steps) if args.memory_steps else []
    except RuntimeError as exc:
        return _error(str(exc), 1)
    bm.write(outdir, rows, memory)
    failed = bm.failures(rows, memory)
    if failed:
        return _error(f"{len(failed)} bench configuration(s) failed: {'; '.join(failed)} "
                      f"(reasons in {outdir}/bench.md)", 1)
    print(f"done in {time.perf_counter() - t0:.0f} s: {outdir}/bench.json, {outdir}/bench.md")
    return 0


EXIT_INTERRUPTED = 3


def _plots(outdir: Path) -> str:
    """Draw the figures of a run (rank 0): "drawn", "failed" (a plotting problem is a
    warning, not a failure of the run) or "interrupted" (Ctrl-C stops the drawing only: the
    run's files are complete and its summary stays as written)."""
    from app.post.plot import plot_all
    t0 = time.perf_counter()
    try:
        files = plot_all(outdir, log=log.info)
    except KeyboardInterrupt:
        print(f"vpcontact: interrupted while drawing the figures; the run itself is complete "
              f"(see {outdir}/summary.json); ./vpcontact plot {outdir} draws them",
              file=sys.stderr)
        return "interrupted"
    except Exception as exc:       # noqa: BLE001 (the run itself succeeded)
        log.warning("figures not drawn: %s: %s (./vpcontact plot %s retries)",
                    type(exc).__name__, exc, outdir)
        return "failed"
    log.info("figures (%.1f s): %s", time.perf_counter() - t0,
             ", ".join(f.name for f in files))
    return "drawn"


def cmd_plot(args) -> int:
    from mpi4py import MPI
    _setup_logging(MPI.COMM_WORLD, False)
    outdir = Path(args.results)
    missing = [f for f in ("summary.json", "solution.xdmf", "solution.h5")
               if not (outdir / f).is_file()]
    if missing:
        print(f"vpcontact: error: {outdir}: not a results directory (missing "
              f"{', '.join(missing)})", file=sys.stderr)
        return 2
    if MPI.COMM_WORLD.rank == 0:
        return {"drawn": 0, "failed": 1, "interrupted": EXIT_INTERRUPTED}[_plots(outdir)]
    return 0


def cmd_check(args) -> int:
    """Dry run: validate, build the mesh and spaces, report; no solve, no output."""
    from mpi4py import MPI

    from app.io.case import CaseError, load_raw, validate
    comm = MPI.COMM_WORLD
    _setup_logging(comm, False)
    try:
        case = validate(load_raw(args.case, args.overrides), args.case)
    except CaseError as exc:
        return _error(str(exc), 2)
    from app.cli.checkrun import report
    for line in report(case, comm):
        if comm.rank == 0:
            print(line)
    return 0


def cmd_info(args) -> int:
    from app.cli.checkrun import info
    for line in info():
        print(line)
    return 0


def console() -> None:
    """The ``vpcontact`` console script: as ``python -m app`` (app/__main__.py)."""
    from app.cli.startup import quick_exit
    from app.cli.streams import repair_std_streams
    repair_std_streams()
    quick_exit(main())


def main(argv: list[str] | None = None) -> int:
    """Exit codes: 0 done, 1 a step failed (or an environmental fault), 2 bad input,
    3 interrupted (SIGINT/SIGTERM)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    ours, petsc_cli = split_petsc_args(argv)
    try:
        args = _parser().parse_args(ours)
        take_signals()
        return _dispatch(args, petsc_cli)
    except KeyboardInterrupt:
        print("vpcontact: interrupted before the time loop started", file=sys.stderr)
        return EXIT_INTERRUPTED
    except CaseError as exc:            # bad input found late (e.g. while building the problem)
        return _error(str(exc), 2)
    except MemoryError:
        return _error("out of memory: the case is too large for this machine (try a coarser "
                      "mesh, mesh.n or mesh.h)", 1)
    except OSError as exc:              # environmental: disk full, read-only, permissions
        from app.io.output import describe_os_error
        return _error(describe_os_error(exc), 1)
    except Exception as exc:
        if _caused_by_interrupt(exc):     # a signal inside a C extension's import or call
            print("vpcontact: interrupted before the time loop started", file=sys.stderr)
            return EXIT_INTERRUPTED
        from petsc4py import PETSc
        if isinstance(exc, PETSc.Error):  # PETSc refused an option or a matrix: not our bug
            from app.solvers.snesvi import describe_petsc_error
            return _error(f"{describe_petsc_error(exc)} (check the PETSc options; -help "
                          "lists them)", 1)
        return _internal_error(exc)


MAX_MESSAGE = 1000      # characters of an error line; a longer one echoes a huge input


def _caused_by_interrupt(exc: BaseException) -> bool:
    """True if a KeyboardInterrupt (Ctrl-C, SIGTERM) is among the exception's causes, as
    when it arrives while a C extension initialises (ImportError 'initialization failed')."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _error(message: str, code: int) -> int:
    """One line on stderr (from rank 0 only: every rank has the same error); returns code."""
    from mpi4py import MPI
    message = " ".join(message.split("\n"))
    if len(message) > MAX_MESSAGE:
        cut = len(message) - 800
        message = f"{message[:700]} ... ({cut} characters left out) ... {message[-100:]}"
    if MPI.COMM_WORLD.rank == 0:
        print(f"vpcontact: error: {message}", file=sys.stderr)
    return code


def _internal_error(exc: Exception):
    """A bug in vpcontact (or a PETSc error we do not translate): the traceback and a line
    asking for a report.  An error on one rank must not leave the others waiting in a
    collective: report it and abort the whole MPI job."""
    import traceback

    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    traceback.print_exc()
    print(f"vpcontact: internal error on rank {comm.rank}: {type(exc).__name__}: {exc}\n"
          "vpcontact: this is a bug; please report it with the command line and the case file",
          file=sys.stderr)
    sys.stderr.flush()
    if comm.size > 1:
        comm.Abort(1)
    return 1


def _dispatch(args, petsc_cli: dict) -> int:
    if args.command == "plot":
        return cmd_plot(args)
    if args.command == "check":
        return cmd_check(args)
    if args.command == "info":
        return cmd_info(args)
    if args.command == "run":
        return cmd_run(args, petsc_cli)
    if args.command == "convergence":
        return cmd_convergence(args, petsc_cli)
    if args.command == "stability":
        return cmd_stability(args, petsc_cli)
    if args.command == "bench":
        return cmd_bench(args)
    return 2  # pragma: no cover (argparse enforces a command)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
