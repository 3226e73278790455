"""The command line's grammar: ``build_parser`` (argparse, one helper per command), the
argument types that refuse bad numbers and paths in one line, and ``split_petsc_args``, which
takes the PETSc options (one leading dash) out of the command line first."""
from __future__ import annotations

import argparse
import math
import re

from vpcontact import __version__
from vpcontact.cachepaths import CACHE_SEARCH
from vpcontact.io.messages import EXIT_BAD_INPUT, error_line

_PETSC_OPT = re.compile(r"^-[A-Za-z][A-Za-z0-9_]*$")
_NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def split_petsc_args(argv: list[str]) -> tuple[list[str], dict]:
    """Separate PETSc options (single dash, e.g. -snes_monitor, -snes_rtol 1e-12) from ours.

    A PETSc option takes the next token as its value unless that token is itself an option
    (a negative number counts as a value).

    Args:
        argv: the command line, without the program name.

    Returns:
        (our arguments in their order, {PETSc option without its dash: value or None}).
    """
    ours, petsc = [], {}
    i = 0
    while i < len(argv):
        tok = argv[i]
        if _PETSC_OPT.match(tok) and tok not in ("-h",):
            value = None
            if i + 1 < len(argv) and (not argv[i + 1].startswith("-")
                                      or _NUMBER.match(argv[i + 1])):
                value = argv[i + 1]
                i += 1
            petsc[tok[1:]] = value
        else:
            ours.append(tok)
        i += 1
    return ours, petsc


# ----------------------------------------------------------------------------- argument types
# The largest value of each integer option (a larger one is refused in one line, exit 2,
# before anything runs; a huge number reached range() and 2 ** r as an "internal error" or
# kept the process counting refinements for ever):
MAX_CELLS = 4096         # cells per side of a built-in mesh (app/case/schema.py, mesh.n)
MAX_STEPS = 1_000_000    # time steps (app/case/timegrid.py MAX_STEPS, time.N)
MAX_REFINEMENTS = 30     # a mesh.file refined r times has >= 4^r cells: 30 is beyond any
                         # mesh within app/case/meshrules.py's MAX_VERTICES = 1e8
MAX_THREADS = 1024       # BLAS threads of run --threads
MAX_RANKS = 4096         # bench --ranks (bench refuses more than the machine's cores)
MAX_REPEAT = 100         # bench --repeat (app/studies/bench.py MAX_REPEAT)
MAX_PASSES = 32          # run --tol and convergence --adaptive: --max-passes
DEFAULT_PASSES = 16      # a pass that refines the mesh about doubles its cells
_INTEGER = re.compile(r"^\s*[-+]?[0-9]+\s*$")


def _int_within(text: str, low: int, high: int) -> int:
    """An integer argument from low to high, or argparse's error naming what is allowed."""
    allowed = f"allowed: {low} to {high}"
    if not _INTEGER.match(text):
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer ({allowed})")
    digits = text.strip().lstrip("+-")
    if len(digits.lstrip("0")) > len(str(high)):      # int() of 5000 digits fails: no int
        raise argparse.ArgumentTypeError(f"{text.strip()} is out of range ({allowed})")
    value = int(text)
    if not low <= value <= high:
        raise argparse.ArgumentTypeError(f"{value} is out of range ({allowed})")
    return value


def int_range(low: int, high: int):
    """An argparse type: an integer from ``low`` to ``high`` (both included).

    Args:
        low: the smallest value allowed.
        high: the largest value allowed.

    Returns:
        The type function: text -> int, raising argparse.ArgumentTypeError (one line naming
        the allowed range) for anything else.
    """
    def parse(text: str) -> int:
        return _int_within(text, low, high)
    parse.__name__ = f"integer from {low} to {high}"
    return parse


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0.

    Args:
        text: the argument.

    Returns:
        Its value.

    Raises:
        argparse.ArgumentTypeError: if it is not a finite number > 0.
    """
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number (allowed: > 0)") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text} (allowed: a finite number > 0)")
    return value


def cells_and_steps(text: str) -> tuple[int, int]:
    """argparse type of bench --extra: 'n:N' with positive integers.

    Args:
        text: the argument, e.g. "256:32".

    Returns:
        (cells per side, time steps).

    Raises:
        argparse.ArgumentTypeError: if it is not two positive integers joined by ':'.
    """
    parts = text.split(":")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"{text!r} (allowed: n:N, cells per side and time "
                                         "steps, e.g. 256:32)")
    try:
        return _int_within(parts[0], 1, MAX_CELLS), _int_within(parts[1], 1, MAX_STEPS)
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"{text!r}: {exc}; n:N, e.g. 256:32") \
            from None


def _path_arg(text: str) -> str:
    """argparse type of a file or directory argument: refused if empty or blank."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty path (allowed: a file or directory name)")
    return text


# ----------------------------------------------------------------------------- the parser
class _Parser(argparse.ArgumentParser):
    """argparse with errors on one line (exit 2), like every other bad-input error."""

    def error(self, message):
        self.exit(EXIT_BAD_INPUT,
                  error_line(f"{message} (see {self.prog} --help)", prog=self.prog) + "\n")


def _case_options(parser, what: str, default_out: str) -> None:
    """Options shared by the commands that read a case and write an output directory."""
    parser.add_argument("--out", metavar="DIR", type=_path_arg,
                        help=f"output directory (default: {default_out})")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE",
                        help="override a case key, e.g. --set mesh.n=32 --set time.N=32, "
                             "a list entry by name[i]: --set contact.pairs[1].g=0.01 "
                             "(repeatable)")
    parser.add_argument("--overwrite", action="store_true",
                        help=f"replace the outputs of an earlier {what} in the output directory")
    parser.add_argument("--quiet", action="store_true",
                        help="only warnings and errors (no progress bar)")
    parser.add_argument("--verbose", action="store_true",
                        help="one log line per step (norms, iterations, wall time) and the "
                             "PETSc monitors (-snes_monitor, -snes_converged_reason)")


def _law_module_option(parser) -> None:
    """--law-module: the Python module of a law written by the user (run, check and the
    studies)."""
    parser.add_argument("--law-module", metavar="FILE.py", type=_path_arg,
                        help="import FILE.py (on every MPI rank) for a case with a python "
                             "law (law: python in material.viscoplastic, "
                             "contact.normal_compliance or contact.friction): the class the "
                             "case names (class:) is the law; without this option such a "
                             "case is refused (a case file alone never runs code)")


def _add_run(sub) -> None:
    run = sub.add_parser("run", help="run a case file",
                         description="Run a case: solve every time step, write "
                                     "solution.xdmf, summary.json and contact.csv.")
    run.add_argument("case", help="YAML case file (see cases/)")
    _case_options(run, "run", "results/<case name>")
    _law_module_option(run)
    run.add_argument("--restart", metavar="DIR", type=_path_arg,
                     help="continue from the newest DIR/checkpoint_*.npz (or a given "
                          "checkpoint file), written with output.checkpoint_every or when a "
                          "run is interrupted; the case must be the same (solver and output "
                          "settings may differ)")
    run.add_argument("--no-plots", action="store_true",
                     help="do not draw the figures at the end (see the plot command)")
    run.add_argument("--threads", type=int_range(1, MAX_THREADS), metavar="N",
                     help="BLAS threads of the large dense operations (the fast solver's "
                          "3D set-up and Gamma3 problem; default: the cores this process may "
                          "use; under mpirun: of rank 0, which solves the Gamma3 problem, "
                          "at most the cores of the ranks on its node, the others 1)")
    run.add_argument("--tol", type=positive_float, metavar="TOL",
                     help="run in passes from t = 0 until the error estimate est_max is at "
                          "most TOL times the solution's scale max_n (||sigma_n||_Q + "
                          "||u_n||_V + ||kappa_n||_Y): after each pass the built-in mesh is "
                          "refined where the space indicator is large and/or the time steps "
                          "split where the step's time error is large, by the estimate's "
                          "parts; passes.csv and passes.json, the final "
                          "pass's outputs in DIR, the others in DIR/pass_<i>")
    _max_passes_option(run, "--tol")


def _max_passes_option(parser, with_option: str) -> None:
    """--max-passes of run --tol and convergence --adaptive (app/studies/tolerance.py)."""
    parser.add_argument("--max-passes", type=int_range(1, MAX_PASSES), default=DEFAULT_PASSES,
                        metavar="N", help=f"with {with_option}: the most passes (default "
                                          f"{DEFAULT_PASSES}; a pass that refines the mesh about "
                                          "doubles its cells)")


def _add_plot_check_info(sub) -> None:
    plot = sub.add_parser("plot", help="draw the figures of a results directory",
                          description="Draw the figures of a run from its files, headless: "
                                      "fig3_deformed_contact.png, fig4_tangential.png, "
                                      "fig2_laws.png, history.png and forces.png (the "
                                      "paper's Figs. 2-4 and the run history, matplotlib), "
                                      "body.png (the deformed body coloured by von Mises "
                                      "stress, Gamma3 marked), fig5_vm_kappa.png (Fig. 5) "
                                      "and in 3D contact_pressure.png (pyvista, off-screen); "
                                      "the contact figures only where the scene has a "
                                      "contact boundary (fig2) and a node in contact "
                                      "(fig3, fig4, contact_pressure.png).")
    plot.add_argument("results", metavar="RESULTS_DIR", help="output directory of a run")
    plot.add_argument("--animate", action="store_true",
                      help="also write animation.gif: the deformed body coloured by von "
                           "Mises stress, one frame per time in solution.xdmf")

    check = sub.add_parser("check", help="validate a case without solving (dry run)",
                           description="Validate a case and report what a run would do: "
                                       "mesh size, dofs, time steps, active and omitted "
                                       "terms, step solver, stability indicator and "
                                       "well-posedness margin. Nothing is solved or written.")
    check.add_argument("case", help="YAML case file")
    check.add_argument("--set", dest="overrides", action="append", default=[],
                       metavar="KEY=VALUE", help="override a case key (repeatable; a list "
                                                 "entry by name[i], e.g. contact.pairs[1].g)")
    _law_module_option(check)

    sub.add_parser("info", help="versions of dolfinx, PETSc, MPI, gmsh; JIT cache",
                   description="Print the versions of the numerical stack, PETSc's external "
                               "packages, the MPI library and where the JIT caches are.")


def _add_convergence(sub) -> None:
    conv = sub.add_parser(
        "convergence", help="convergence study: Error against h, k and wall time",
        description="Run a case at several resolutions and a reference, and report "
                    "Error = max_n (||sigma_n - sigma_n^ref||_Q + ||u_n - u_n^ref||_V + "
                    "||kappa_n - kappa_n^ref||_Y) per level with observed rates and wall times "
                    "(convergence.csv, convergence.md, convergence.png). Runs are cached. "
                    "Built-in structured mesh: level L is the L x L mesh with L steps. "
                    "mesh.file: level r is the case's mesh refined r times (each triangle into "
                    "4, each tetrahedron into 8: nested meshes; a .geo is meshed once at its "
                    "mesh.size, then refined) with time.N 2^r steps; the reference is the mesh "
                    "refined R times. Example: --levels 0 1 2 --reference 3.")
    conv.add_argument("case", help="YAML case file with a structured mesh or a mesh.file")
    conv.add_argument("--levels", type=int_range(0, MAX_CELLS), nargs="+", metavar="L",
                      help="levels: built-in mesh: 1/h and/or 1/k of each run (default: 8 16 32 "
                           "64); mesh.file: refinements of its mesh (default: 0 1 2, or 0 .. "
                           "R-1 with --reference R)")
    conv.add_argument("--reference", type=int_range(1, MAX_CELLS), metavar="R",
                      help="the reference run: built-in mesh n = N = R (default: 128); "
                           "mesh.file: its mesh refined R times (default: the largest level "
                           "+ 1)")
    conv.add_argument("--vary", choices=["both", "h", "k"], default="both",
                      help="refine h and k together, or one with the other at the reference")
    conv.add_argument("--deltas", type=positive_float, nargs="+", metavar="D",
                      help="friction regularisation widths to study (default: the case's); "
                           "the reference uses the smallest of these and the case's")
    _case_options(conv, "study", "results/<case name>/convergence")
    _law_module_option(conv)
    conv.add_argument("--adaptive", type=positive_float, nargs="+", metavar="TOL",
                      help="after the study, for each TOL the passes of run --tol TOL from "
                           "the coarsest level h = k = 1/L (L the first of --levels; a "
                           "mesh.file: the mesh as read, --levels 0 ...) with the first of "
                           "--deltas, in DIR/adaptive/tol_<TOL>; then error_vs_wall.csv and "
                           "error_vs_wall.png: estimate (and the uniform levels' Error) "
                           "relative to the solution's scale against wall time, the uniform "
                           "levels against each run's passes (TOL > 0; with --vary both)")
    _max_passes_option(conv, "--adaptive")
    conv.add_argument("--cache-dir", metavar="DIR", type=_path_arg,
                      help=f"run cache (default: {CACHE_SEARCH})")
    conv.add_argument("--no-cache", action="store_true", help="recompute every run")


def _add_stability(sub) -> None:
    stab = sub.add_parser(
        "stability", help="sweep stiff and extreme variants of a case",
        description="Run stiff and extreme variants of a case (viscosity, near-Signorini "
                    "contact, friction, loads, material, time steps) with the explicit and "
                    "implicit history schemes on a coarse mesh, and report convergence, "
                    "growth, stability indicator and well-posedness margin "
                    "(stability.csv, stability.md).")
    stab.add_argument("case", help="YAML case file (a built-in mesh or a mesh.file)")
    _case_options(stab, "sweep", "results/<case name>/stability")
    _law_module_option(stab)
    stab.add_argument("--n", type=int_range(1, MAX_CELLS),
                      help="cells per side of the coarse built-in mesh (default: 8; not with "
                           "mesh.file)")
    stab.add_argument("--refine", type=int_range(0, MAX_REFINEMENTS), metavar="R",
                      help="mesh.file: refine the case's mesh R times for the base (default: "
                           "0, the mesh as read; the variant 'h/2' refines once more)")
    stab.add_argument("--steps", type=int_range(1, MAX_STEPS), default=8,
                      help="time steps of the base variant")


def _add_bench(sub) -> None:
    b = sub.add_parser("bench", help="time the step solvers on the paper case",
                       description="Whole-process timings of a case with each step solver, "
                                   "serial and under mpirun -n 2 (bench.json, bench.md), also "
                                   "as ratios to a reference solve on each mesh timed in the "
                                   "same bench run (comparable between machines).")
    b.add_argument("case", nargs="?", default="cases/wang_cheng_2021.yaml")
    b.add_argument("--levels", type=int_range(1, MAX_CELLS), nargs="+", default=[16, 32, 64, 128],
                   help="h = k = 1/L levels (default 16 32 64 128)")
    b.add_argument("--extra", type=cells_and_steps, nargs="*", default=[(256, 32)],
                   metavar="n:N", help="extra (cells per side : steps) runs (default 256:32)")
    b.add_argument("--memory-steps", type=int_range(1, MAX_STEPS), nargs="*",
                   default=[64, 256, 1024, 4096],
                   metavar="N", help="step counts of the memory-term cost runs "
                                     "(recursion vs direct sum; none: skip)")
    b.add_argument("--scene-n", type=int_range(0, MAX_CELLS), default=121, metavar="n",
                   help="cells per side of the user-scene comparison (the case's square "
                        "rotated and read from a .geo, against the built-in rectangle, 64 "
                        "steps; default 121: 29768 dofs; 0: skip)")
    b.add_argument("--box3d-levels", type=int_range(1, MAX_CELLS), nargs="*",
                   default=[8, 16, 24, 32, 64],
                   metavar="n", help="cells per edge of the 3D rows (cases/box3d.yaml, 8 steps, "
                                     "default solver; with a 32-step n = 32 run, SNES VI at "
                                     "n <= 16, mpirun -n 2 at 32 (else the largest n), the 2D "
                                     "reference at 1/128 and a log-log plot; default 8 16 24 "
                                     "32 64: 824k dofs at 64; none: skip)")
    b.add_argument("--ranks", type=int_range(1, MAX_RANKS), nargs="+", default=[1, 2])
    b.add_argument("--repeat", type=int_range(1, MAX_REPEAT), default=3, metavar="R",
                   help="measured runs per configuration, every solver alike; the fastest "
                        "is reported, all are kept (default 3; the --extra levels run once)")
    b.add_argument("--out", default="results/bench", type=_path_arg, help="output directory")


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``vpcontact``'s own arguments (the PETSc options are taken out first,
    see ``split_petsc_args``).

    Returns:
        The parser: ``--version`` and the commands run, plot, check, info, convergence,
        stability and bench (``args.command``); a bad argument exits 2 with one line.
    """
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
    _add_run(sub)
    _add_plot_check_info(sub)
    _add_convergence(sub)
    _add_stability(sub)
    _add_bench(sub)
    return p
