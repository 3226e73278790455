"""The commands: ``cmd_<name>(args, ...)`` runs ``vpcontact <name>`` with the parsed command
line and returns its exit code (0 done, 1 failed, 2 bad input, 3 interrupted).

run, convergence and stability start alike (``start``: logging, the case and the PETSc
options validated, the output directory prepared) and take the PETSc options of the command
line, as check does (it reports what run would do); bench, plot and info take the parsed
arguments only (main refuses PETSc options given to them).
"""
from __future__ import annotations

import dataclasses
import time
from pathlib import Path

from vpcontact import __version__
from vpcontact.cli import ending
from vpcontact.cli import outdir as outdirs
from vpcontact.cli.logs import log, setup_logging
from vpcontact.cli.outdir import CONVERGENCE_FILES, STABILITY_FILES
from vpcontact.io.errors import CaseError
from vpcontact.io.messages import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_INTERRUPTED, error, interrupted
from vpcontact.startup import resume_collector


def start(args, subdir: str | None, files=None, check=None, petsc_cli=None):
    """The common start of run, convergence and stability.

    Sets up logging, reads and validates the case, checks the command line's PETSc options
    and the command's own ``check``, and prepares the output directory.

    Args:
        args: the parsed command line (case, overrides, out, overwrite, quiet, verbose).
        subdir: the default output directory's subdirectory of results/<case name>.
        files: the names the command writes (see outdir.prepare).
        check: called with the validated Case; raises CaseError to refuse it.
        petsc_cli: PETSc options given on the command line.

    Returns:
        (comm, raw case dict, Case, output directory), or (comm, None, None, None) after
        the error line was printed (exit code 2: bad input).
    """
    from mpi4py import MPI

    from vpcontact.case import load_raw, validate
    from vpcontact.model.lawmodule import prepare_law_module

    comm = MPI.COMM_WORLD
    setup_logging(comm, args.quiet, getattr(args, "verbose", False))
    try:
        raw = load_raw(args.case, args.overrides)
        case = validate(raw, args.case)
        prepare_law_module(case.raw, getattr(args, "law_module", None))
        check_command_line_petsc(case, petsc_cli)
        if check:
            check(case)
        outdir = Path(args.out) if args.out else \
            Path("results") / case.name / subdir if subdir else Path("results") / case.name
        outdirs.prepare(comm, outdir, args.overwrite, files)
    except CaseError as exc:
        error(str(exc), EXIT_BAD_INPUT)
        return comm, None, None, None
    return comm, raw, case, outdir


def check_command_line_petsc(case, petsc_cli: dict | None) -> None:
    """Check the command line's PETSc options on top of the case's, as PETSc and the step
    solvers would take them (app/solvers/optioncheck.py: the allow-list, the types, what
    the step problem needs); run, check and the studies call it alike.

    Args:
        case: the validated Case (``case.petsc``: its options and tolerance limits).
        petsc_cli: PETSc options given on the command line (name without '-' -> value).

    Returns:
        None.

    Raises:
        CaseError: naming the option (``-name``) and what is allowed.
    """
    if petsc_cli:
        from vpcontact.solvers.optioncheck import check_petsc_options
        check_petsc_options(petsc_cli, "command line", where="-", base=case.petsc)


def with_command_line_petsc(case, petsc_cli: dict):
    """The case with the command line's PETSc options over its own (what the step
    solvers read: run and check choose the step solver from the same options).

    Args:
        case: the validated Case.
        petsc_cli: PETSc options given on the command line (checked already).

    Returns:
        A copy of ``case`` whose ``petsc`` holds both, the command line's winning.
    """
    return dataclasses.replace(case, petsc={**case.petsc, **petsc_cli})


# ----------------------------------------------------------------------------- run
def _restart_check(args, loaded: dict):
    """The check of --restart (a ``start`` check): the checkpoint exists, is not in the
    output directory and belongs to the case; it is put into ``loaded["checkpoint"]``."""
    from vpcontact.io.checkpoint import Checkpoint, latest

    def check(case):
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

    return check


def cmd_run(args, petsc_cli: dict) -> int:
    """``vpcontact run``: a Simulation with the command line's observers (solution.xdmf,
    checkpoints, progress bar, per-step log, contact.csv and summary.json), then the figures.

    Args:
        args: the parsed command line.
        petsc_cli: PETSc options given on the command line.

    Returns:
        The exit code (see report_run; 2: bad input).
    """
    loaded = {}
    comm, raw, case, outdir = start(args, None, check=_run_check(args, loaded),
                                    petsc_cli=petsc_cli)
    if case is None:
        return EXIT_BAD_INPUT

    from vpcontact import threads
    from vpcontact.cli.progress import ProgressBar, ReaderWatch
    from vpcontact.observers import (
        Checkpointer,
        CollectorAfterSetUp,
        ContactOutput,
        FieldOutput,
        HistoryOutput,
        RunFiles,
        StepLog,
        written_files,
    )
    from vpcontact.simulation import run

    if args.verbose:
        petsc_cli = {"snes_monitor": None, "snes_converged_reason": None, **petsc_cli}
    case = with_command_line_petsc(case, petsc_cli)
    log.info("vpcontact %s: case %s -> %s (%d MPI rank%s)", __version__, args.case, outdir,
             comm.size, "s" if comm.size > 1 else "")
    bar = not args.quiet and not args.verbose

    def make_observers():
        return [CollectorAfterSetUp(), FieldOutput(), ContactOutput(), HistoryOutput(),
                Checkpointer(), *([ProgressBar()] if bar else []), ReaderWatch(), StepLog(),
                RunFiles()]

    observers = make_observers()
    threads.request(args.threads)
    painter = _early_painter(comm, args.no_plots)
    try:
        if args.tol is not None:             # passes to a tolerance: app/studies/tolerance.py
            result, files, met = _run_to_tolerance(args, comm, raw, case, outdir,
                                                   make_observers)
        else:
            result = run(case, comm, observers, outdir=outdir,
                         restart=loaded.get("checkpoint"))
            files = written_files(observers)
        ending.run_ended(result.status, outdir)    # a signal from now on: app/cli/ending.py
        s = result.summary
        if result.status == "completed" and not args.no_plots and comm.rank == 0 and s["steps"]:
            if plots(outdir, painter=painter, drawn=files) == "interrupted":
                return EXIT_INTERRUPTED
    finally:
        resume_collector()             # also where the run stopped before its start
        if painter is not None:
            painter.cancel()
    code = report_run(comm, s, outdir, files)
    return EXIT_FAILED if code == 0 and args.tol is not None and not met else code


def _run_check(args, loaded: dict):
    """The checks of run: --restart's, and --tol's (app/studies/tolerance.py)."""
    restart = _restart_check(args, loaded)

    def check(case):
        if args.tol is not None:
            from vpcontact.studies.tolerance import check_tolerance_case
            if args.restart:
                raise CaseError("--tol: every pass starts at t = 0; it cannot continue "
                                "from --restart")
            check_tolerance_case(case, case.raw)
        restart(case)

    return check


def _run_to_tolerance(args, comm, raw: dict, case, outdir: Path, make_observers):
    """run --tol: the passes, passes.csv/json, the final table; the final pass's files
    moved into outdir.

    Returns:
        (the last pass's RunResult, the files in outdir, whether the tolerance was met).
    """
    from vpcontact.case import validate
    from vpcontact.studies import tolerance

    passes, met, result = tolerance.run_passes(raw, case, comm, args.tol, args.max_passes,
                                               outdir, make_observers, validate)
    tolerance.log_table(passes, args.tol)
    if not met:
        log.warning("run --tol %g: not reached after %d passes (est_max / scale = %.3g; "
                    "exit code 1, the outputs are the last pass's); raise --max-passes or "
                    "the tolerance", args.tol, len(passes), passes[-1].relative or float("nan"))
    files = tolerance.promote_final(outdir, passes[-1].index) if comm.rank == 0 else []
    comm.barrier()
    return result, files + [outdir / "passes.csv", outdir / "passes.json"], met


def _early_painter(comm, no_plots: bool):
    """The pictures' process of a serial run, started before the run so that its start-up
    (pyvista, OpenGL; docs/performance.md, section 9) overlaps the computation; None under
    mpirun (every core has a rank) or without figures."""
    if no_plots or comm.size > 1:
        return None
    from vpcontact.post.plot import Painter
    try:
        return Painter()
    except OSError as exc:             # cannot start a process: the figures start their own
        log.debug("no early pictures process: %s", exc)
        return None


def _small_case_note(comm, s: dict) -> None:
    """Under mpirun on few dofs per rank: the run log's line on where the time went
    (app/cli/ranknote.py)."""
    from vpcontact.cli.ranknote import small_case_note
    from vpcontact.startup import STARTED
    startup = time.perf_counter() - STARTED - s["wall_s"]
    note = small_case_note(comm.size, s["mesh"]["dofs"], startup, s["setup_s"], s["loop_s"])
    if note:
        log.info("%s", note)


def report_run(comm, s: dict, outdir: Path, files: list[Path]) -> int:
    """The closing lines of a run and its exit code.

    Args:
        comm: the MPI communicator.
        s: the run's summary (summary.json's content).
        outdir: the output directory.
        files: every file the run wrote there (the observers' ``written_files`` and the
            figures), named by the closing ``outputs:`` line.

    Returns:
        0 completed, 1 failed or diverged, 3 interrupted.
    """
    status = s["status"]
    if status == "completed":
        log.info("done: %d steps, %d Newton iterations, wall %.2f s (set-up %.2f s, steps %.2f s)",
                 len(s["steps"]), s["newton_iterations_total"], s["wall_s"], s["setup_s"],
                 s["loop_s"])
        if "phases" in s:
            from vpcontact.post.phases import phase_lines  # PETSc: imported by the run
            for line in phase_lines(s["phases"]):
                log.info("%s", line)
        _small_case_note(comm, s)
        g3 = s["solver"].get("gamma3")
        if g3:
            log.info("Gamma3 problem (%d dofs): %d dense factorisations, %d CG iterations with "
                     "a kept factor; BLAS threads for factorisations of >= 1000 dofs: %d",
                     g3["dofs"], g3["factorisations"], g3["cg_iterations"], g3["threads"])
        amg = s["solver"].get("amg")
        if amg:
            log.info("CG + GAMG: %d set-ups (%d building the interpolation, the others "
                     "keeping it), the PC kept in %d Newton iterations", amg["setups"],
                     amg["interpolations"], amg["kept"])
        if "contact_states" in s:
            states = dict(s["contact_states"])
            pairs = states.pop("pairs", [])         # several contact pairs: each one
            log.info("Gamma3 nodes at T: %s", states)
            for i, counts in enumerate(pairs):
                log.info("  contact pair %d: %s", i, counts)
        log.info("outputs: %s/{%s}", outdir, ", ".join(Path(f).name for f in files))
        return 0
    f = s["failure"]
    if comm.rank != 0:
        return EXIT_INTERRUPTED if status == "interrupted" else EXIT_FAILED
    if status == "interrupted":
        return interrupted(f"{f['reason']} after step {f['step']} (t = {f['t']:g}); outputs up "
                           f"to that step are in {outdir}; {f['hint']}")
    what = "the run diverged" if status == "diverged" else "the run failed"
    return error(f"{what} at step {f['step']} (t = {f['t']:g}): {f['reason']}; outputs up to "
                 f"step {s['last_good_step']} are in {outdir}. Hint: {f['hint']}", EXIT_FAILED,
                 rank=comm.rank)


def plots(outdir: Path, animate: bool = False, painter=None, drawn: list | None = None) -> str:
    """Draw the figures of a run (call on rank 0).

    Args:
        outdir: the run's output directory.
        animate: also write animation.gif.
        painter: the pictures' process started ahead (app/post/plot.Painter), or None.
        drawn: a list the figures written are appended to (also those of a failed
            pictures' process: its line figures), or None.

    Returns:
        "drawn", "failed" (a plotting problem is a warning, not a failure of the run) or
        "interrupted" (Ctrl-C stops the drawing only: the run's files are complete and its
        summary stays as written).
    """
    from vpcontact.post.plot import PicturesError, plot_all
    t0 = time.perf_counter()
    try:
        files = plot_all(outdir, log=log.info, animate=animate, painter=painter)
    except PicturesError as exc:
        if drawn is not None:
            drawn.extend(exc.written)
        log.warning("pictures (pyvista) not drawn: %s; the line figures are (%s); "
                    "./vpcontact plot %s retries", exc, ", ".join(f.name for f in exc.written),
                    outdir)
        return "failed"
    except KeyboardInterrupt:
        interrupted(f"interrupted while drawing the figures; the run itself is complete "
                    f"(see {outdir}/summary.json); ./vpcontact plot {outdir} draws them")
        return "interrupted"
    except Exception as exc:       # noqa: BLE001 (the run itself succeeded)
        log.warning("figures not drawn: %s: %s (./vpcontact plot %s retries)",
                    type(exc).__name__, exc, outdir)
        return "failed"
    log.info("figures (%.1f s): %s", time.perf_counter() - t0,
             ", ".join(f.name for f in files))
    if drawn is not None:
        drawn.extend(files)
    return "drawn"


# ----------------------------------------------------------------------------- studies
def cmd_convergence(args, petsc_cli: dict) -> int:
    """``vpcontact convergence``: the convergence study (convergence.csv, .md, .png).

    Args:
        args: the parsed command line.
        petsc_cli: PETSc options given on the command line.

    Returns:
        The exit code: 0 done, 1 a run failed, 2 bad input, 3 interrupted (SIGINT, SIGTERM:
        the runs that finished stay in the run cache).
    """
    from mpi4py import MPI

    from vpcontact.studies import convergence as cv
    from vpcontact.studies import errorwall
    from vpcontact.studies.runcache import default_cache_dir

    cache_dir = None if args.no_cache else Path(args.cache_dir or default_cache_dir())
    chosen = {}

    def check(c):                     # every option, before anything is computed
        levels, reference = cv.resolve_levels(c, args.levels, args.reference)
        if reference >= 1:            # a mesh.file's finest level within the size limit
            cv.check_level_sizes(c, MPI.COMM_WORLD, "--reference", reference)
        errorwall.check_adaptive(c, args.adaptive, levels, args.vary)
        cv.plan_runs(levels, reference, args.vary, c, args.deltas)
        cv.check_cache_dir(cache_dir, MPI.COMM_WORLD)
        chosen.update(levels=levels, reference=reference)

    comm, raw, case, outdir = start(args, "convergence", CONVERGENCE_FILES, check=check,
                                    petsc_cli=petsc_cli)
    if case is None:
        return EXIT_BAD_INPUT
    log.info("vpcontact %s: convergence study of %s -> %s (cache: %s, %d MPI rank%s)",
             __version__, args.case, outdir, cache_dir or "off", comm.size,
             "s" if comm.size > 1 else "")
    t0 = time.perf_counter()
    try:
        res = cv.study(raw, args.case, chosen["levels"], chosen["reference"], args.vary,
                       args.deltas, comm, cache_dir, petsc_cli)
        if comm.rank == 0:
            cv.write_csv(outdir / "convergence.csv", res)
            cv.write_markdown(outdir / "convergence.md", res, case.name)
            cv.write_plot(outdir / "convergence.png", res)
        failed = _error_vs_wall(args, comm, raw, res, outdir, petsc_cli) if args.adaptive \
            else None
    except CaseError as exc:
        return error(str(exc), EXIT_BAD_INPUT)
    except RuntimeError as exc:
        return error(str(exc), EXIT_FAILED)
    except KeyboardInterrupt as exc:
        return interrupted(_convergence_interrupted(exc, cache_dir, outdir))
    except errorwall.PassesInterrupted as exc:
        return interrupted(f"convergence --adaptive: a signal stopped {exc}; the study's "
                           f"report is written (convergence.csv, .md, .png in {outdir}), "
                           "error_vs_wall.csv and .png are not")
    if comm.rank == 0:
        for r in res["rows"]:
            log.info("delta %-8g h %-9.5g k %-9.5g Error %.6g  rate %s  effectivity %s  wall "
                     "%.3f s%s", r["delta"], r["h"], r["k"], r["error"],
                     "-" if r["rate"] is None else f"{r['rate']:.3f}",
                     "-" if r["effectivity"] is None else f"{r['effectivity']:.3f}",
                     r["solve_s"], " (cached)" if r["cached"] else "")
        written = CONVERGENCE_FILES if args.adaptive else CONVERGENCE_FILES[:3]
        log.info("done in %.1f s: %s/{%s}", time.perf_counter() - t0, outdir,
                 ", ".join(written))
    comm.barrier()
    return error(failed, EXIT_FAILED, rank=comm.rank) if failed else 0


def _error_vs_wall(args, comm, raw: dict, res: dict, outdir: Path,
                   petsc_cli: dict) -> str | None:
    """convergence --adaptive: the passes of each tolerance, error_vs_wall.csv and .png
    (app/studies/errorwall.py); collective.

    Returns:
        None, or the error line of a pass that failed (its rows are in the files).
    """
    from vpcontact.studies import errorwall
    rows = errorwall.study_rows(res, args.adaptive, outdir, comm, raw, args.case, petsc_cli,
                                args.max_passes)
    bad = [r for r in rows or [] if r.get("status") not in (None, "completed")]
    failed = comm.bcast(f"convergence --adaptive {bad[0]['tol']:g}: pass {bad[0]['pass']} "
                        f"{bad[0]['status']} (see {errorwall.tol_dir(outdir, bad[0]['tol'])}"
                        "/passes.json); error_vs_wall.csv and .png show the passes up to it"
                        if bad else None, root=0)
    if comm.rank == 0:
        errorwall.write_csv(outdir / "error_vs_wall.csv", rows)
        errorwall.write_plot(outdir / "error_vs_wall.png", rows, args.adaptive, res["file"])
        for r in rows:
            if r["kind"] == "adaptive":
                log.info("run --tol %g pass %d: %d cells, %d steps, estimate / scale %.3g, "
                         "cumulative wall %.2f s (steps %.2f s)", r["tol"], r["pass"],
                         r["cells"], r["steps"], r["relative"] or float("nan"), r["wall_s"],
                         r["steps_s"])
            if r["kind"] == "adaptive" and r["met"] is False:
                log.warning("run --tol %g: not reached after %d passes (raise --max-passes)",
                            r["tol"], r["pass"])
    return failed


def _convergence_interrupted(exc: KeyboardInterrupt, cache_dir: Path | None,
                             outdir: Path) -> str:
    """The line of a convergence study ended by a signal: where, and what is kept."""
    from vpcontact.studies.interrupts import StudyInterrupted, signal_name
    if not isinstance(exc, StudyInterrupted):           # while writing the report
        return (f"convergence study interrupted by {signal_name(exc)} while writing its "
                f"report to {outdir}; every run is done" + (
                    f" and in the run cache {cache_dir}: the same command writes the report "
                    "from it" if cache_dir else ""))
    kept = (f"the {exc.finished} run(s) that finished are in the run cache {cache_dir} (the "
            "same command continues from them)" if cache_dir else
            f"{exc.finished} run(s) had finished (not kept: --no-cache)")
    return (f"convergence study interrupted by {exc.signal} during {exc.where}; {kept}; "
            f"no report was written to {outdir}")


def cmd_stability(args, petsc_cli: dict) -> int:
    """``vpcontact stability``: the sweep of stiff and extreme variants of a case on a coarse
    built-in mesh or its own mesh.file (stability.csv, stability.md).

    Args:
        args: the parsed command line.
        petsc_cli: PETSc options given on the command line.

    Returns:
        The exit code: 0 done, 2 bad input, 3 interrupted (SIGINT, SIGTERM: the report
        holds the runs that finished, marked incomplete).
    """
    from mpi4py import MPI

    from vpcontact.studies import stability as st
    from vpcontact.studies.convergence import check_level_sizes

    def check(c):
        st.base_case(c.raw, args.n, args.steps, args.case, args.refine)
        # the variant "h/2" runs on the next refinement
        check_level_sizes(c, MPI.COMM_WORLD, "--refine", args.refine or 0, extra=1)

    comm, raw, case, outdir = start(args, "stability", STABILITY_FILES, check,
                                    petsc_cli=petsc_cli)
    if case is None:
        return EXIT_BAD_INPUT
    log.info("vpcontact %s: stability sweep of %s -> %s", __version__, args.case, outdir)
    t0 = time.perf_counter()
    try:
        outcomes = st.sweep(raw, comm, petsc_cli, args.n, args.steps, source=args.case,
                            refine=args.refine)
        _stability_report(comm, args, case, raw, outdir, outcomes)
    except CaseError as exc:
        return error(str(exc), EXIT_BAD_INPUT)
    except KeyboardInterrupt as exc:
        return interrupted(_stability_interrupted(comm, args, case, raw, outdir, exc))
    log.info("done in %.1f s: %s/{%s}", time.perf_counter() - t0, outdir,
             ", ".join(STABILITY_FILES))
    comm.barrier()
    return 0


def _stability_report(comm, args, case, raw, outdir: Path, outcomes, interrupted=None):
    """stability.csv and stability.md (rank 0); ``interrupted`` says by what and where if
    the outcomes are those of an interrupted sweep."""
    from vpcontact.studies import stability as st
    if comm.rank == 0:
        st.write_csv(outdir / "stability.csv", outcomes)
        file = case.mesh.file is not None
        st.write_markdown(outdir / "stability.md", outcomes, case.name,
                          None if file else args.n or 8, args.steps, args.refine,
                          st.not_applicable(raw), interrupted)


def _stability_interrupted(comm, args, case, raw, outdir: Path, exc) -> str:
    """The line of a sweep ended by a signal, after the report of the runs that finished
    (the signals held back while it is written)."""
    from vpcontact.studies.interrupts import StudyInterrupted, signal_name, signals_held
    if not isinstance(exc, StudyInterrupted):           # while writing the report
        return (f"stability sweep interrupted by {signal_name(exc)} while writing its report "
                f"to {outdir}; every variant had run")
    if not exc.results:
        return (f"stability sweep interrupted by {exc.signal} during {exc.where}; no variant "
                "had finished, no report written")
    try:
        with signals_held():
            _stability_report(comm, args, case, raw, outdir, exc.results,
                              f"{exc.signal} during {exc.where}")
    except KeyboardInterrupt:
        pass                          # a second signal: the report is written, then we stop
    return (f"stability sweep interrupted by {exc.signal} during {exc.where}; the "
            f"{exc.finished} run(s) that finished are in {outdir}/stability.csv and "
            "stability.md (marked incomplete)")


def cmd_bench(args) -> int:
    """``vpcontact bench``: whole-process timings of each step solver (bench.json, bench.md).

    Args:
        args: the parsed command line.

    Returns:
        The exit code: 0 done, 1 a configuration failed, 2 bad input, 3 interrupted.
    """
    from vpcontact.cachepaths import unusable
    from vpcontact.studies import bench as bm
    from vpcontact.studies.benchref import References
    from vpcontact.studies.benchrun import run_overrides
    from vpcontact.studies.scenebench import scene_rows

    extra = list(args.extra)          # (n, N) pairs, parsed by cells_and_steps
    outdir = Path(args.out)
    try:                              # every argument and the case, before anything runs
        bm.check_arguments(args.case, args.levels, extra, args.ranks, args.repeat,
                           args.memory_steps or [], box3d_levels=args.box3d_levels or [])
        why = unusable(outdir)
        if why:
            raise CaseError(f"--out {outdir}: not a writable directory ({why})")
    except CaseError as exc:
        return error(str(exc), EXIT_BAD_INPUT)
    print(f"vpcontact bench: {args.case}, levels {args.levels}, extra {extra}, ranks {args.ranks}")
    t0 = time.perf_counter()
    refs = References()               # one reference solve per mesh of the whole bench
    try:
        rows = bm.bench(args.case, outdir, args.levels, nprocs=args.ranks, extra=extra,
                        repeat=args.repeat, references=refs)
        memory = bm.memory_rows(outdir, steps=args.memory_steps, references=refs) \
            if args.memory_steps else []
        scene = scene_rows(Path(args.case), outdir, args.scene_n, 64, run_overrides,
                           args.repeat, references=refs) if args.scene_n else []
        box3d = _box3d_rows(outdir, args.box3d_levels, refs)
    except RuntimeError as exc:
        return error(str(exc), EXIT_FAILED)
    except KeyboardInterrupt as exc:     # the run in progress was stopped with the bench
        from vpcontact.studies.interrupts import signal_name
        return interrupted(f"bench interrupted by {signal_name(exc)}; its run was stopped, "
                           f"no bench.json or bench.md written to {outdir}")
    bm.write(outdir, rows, memory, scene, box3d)
    failed = bm.failures(rows, memory, scene, box3d)
    if failed:
        return error(f"{len(failed)} bench configuration(s) failed: {'; '.join(failed)} "
                     f"(reasons in {outdir}/bench.md)", EXIT_FAILED)
    print(f"done in {time.perf_counter() - t0:.0f} s: {outdir}/bench.json, {outdir}/bench.md")
    return 0


def _box3d_rows(outdir: Path, levels: list[int], references) -> list[dict]:
    """The bench's 3D rows (app/studies/bench3d.py) and their plot bench3d.png; none if no
    levels are asked for."""
    from vpcontact.studies import bench3d
    if not levels:
        return []
    print(f"3D rows: box3d at n = {' '.join(map(str, levels))}")
    small = [n for n in levels if n <= 16]            # SNES VI with a direct LU: small only
    rows = bench3d.box3d_rows(outdir, levels, snes_levels=small,
                              target=(32, 32) if 32 in levels else None,
                              mpi_level=32 if 32 in levels else max(levels),
                              references=references)
    bench3d.plot(rows, outdir / "bench3d.png")
    return rows


# ----------------------------------------------------------------------------- plot, check, info
def cmd_plot(args) -> int:
    """``vpcontact plot``: draw the figures of a results directory.

    Args:
        args: the parsed command line.

    Returns:
        The exit code: 0 drawn, 1 drawing failed, 2 not a results directory, 3 interrupted.
    """
    from mpi4py import MPI
    setup_logging(MPI.COMM_WORLD, False)
    outdir = Path(args.results)
    missing = [f for f in ("summary.json", "solution.xdmf", "solution.h5")
               if not (outdir / f).is_file()]
    if missing:
        killed = "; a run killed before its end writes no summary.json" \
            if missing == ["summary.json"] else ""
        return error(f"{outdir}: not a results directory (missing {', '.join(missing)})"
                     f"{killed}", EXIT_BAD_INPUT)
    from vpcontact.post.results import ResultsError, check_results
    try:
        check_results(outdir)                  # a damaged file: one line naming it
    except ResultsError as exc:
        return error(str(exc), EXIT_BAD_INPUT)
    if MPI.COMM_WORLD.rank == 0:
        status = plots(outdir, animate=args.animate)
        return {"drawn": 0, "failed": EXIT_FAILED, "interrupted": EXIT_INTERRUPTED}[status]
    return 0


def cmd_check(args, petsc_cli: dict) -> int:
    """``vpcontact check``: the dry run: validate, build the mesh and spaces, report; no
    solve, no output.  The command line's PETSc options are checked and taken as ``run``
    takes them (the step solver reported is the one ``run`` would use).

    Args:
        args: the parsed command line.
        petsc_cli: PETSc options given on the command line.

    Returns:
        The exit code: 0 valid, 2 bad input.
    """
    from mpi4py import MPI

    from vpcontact.case import load_raw, validate
    from vpcontact.cli.checkrun import report
    from vpcontact.model.lawmodule import prepare_law_module
    comm = MPI.COMM_WORLD
    setup_logging(comm, False)
    try:
        case = validate(load_raw(args.case, args.overrides), args.case)
        prepare_law_module(case.raw, args.law_module)
        check_command_line_petsc(case, petsc_cli)
    except CaseError as exc:
        return error(str(exc), EXIT_BAD_INPUT)
    for line in report(with_command_line_petsc(case, petsc_cli), comm):
        if comm.rank == 0:
            print(line)
    return 0


def cmd_info(args) -> int:
    """``vpcontact info``: versions of the numerical stack and where the caches are.

    Args:
        args: the parsed command line (no options).

    Returns:
        0.
    """
    from vpcontact.cli.checkrun import info
    for line in info():
        print(line)
    return 0
