"""All figures of a run (plot_all), drawn by two figure processes (Painter): the pictures'
process (app/post/pictures.py: pyvista's pictures, PAINTER_LINE_FIGURES, the animation) and
the line figures' process (the other line figures of app/post/linefigures.py).
"""
from __future__ import annotations

import json
from pathlib import Path

from vpcontact.io.files import temporary
from vpcontact.post import pictures
from vpcontact.post.linefigures import LINE_FIGURES, draw_line_figures
from vpcontact.post.pictures import ANIMATION, PICTURES
from vpcontact.post.results import Results

FIGURES = LINE_FIGURES + PICTURES + (ANIMATION,)       # what plot (--animate) may write


class PicturesError(RuntimeError):
    """The pyvista pictures could not be drawn; ``written``: the line figures that were."""

    def __init__(self, reason: str, written: list[Path]):
        super().__init__(reason)
        self.written = written


PAINTER_LINE_FIGURES = ("forces.png",)    # drawn by the pictures' process (balances the two)


def plot_all(outdir: Path, log=None, animate: bool = False, painter=None) -> list[Path]:
    """Write every figure into ``outdir`` (atomically: temporary file, then rename), in the
    two figure processes of a Painter at once (started ahead of a serial run, so that
    loading matplotlib, pyvista and OpenGL overlaps the computation): one draws the
    pictures (app/post/pictures.py), PAINTER_LINE_FIGURES and the animation if asked for,
    the other the other line figures.

    Args:
        outdir: the results directory.
        log: called with a line naming the displacement factor of fig3 and body.png (those
            drawn), or None.
        animate: also write animation.gif (a frame per output time).
        painter: a Painter started ahead of time (None: one is started now).

    Returns:
        The files written (of FIGURES).

    Raises:
        PicturesError: the pictures' process failed (the line figures are written).
    """
    outdir = Path(outdir)
    res = Results(outdir)
    factor = res.magnification()
    painter = painter or Painter()
    try:
        painter.draw(outdir, factor, res.dim, animate)
        result = painter.finish()
    finally:
        painter.cancel()
    drawn = [Path(f).name for f in result["files"]]
    if log:
        log(", ".join(n for n in ("fig3_deformed_contact.png", "body.png") if n in drawn)
            + ": " + (
            "true scale (two bodies: magnified, they would overlap)" if res.pairs
            else f"displacement magnified x {factor:g}"))
        if result["frames"] is not None:
            log(f"{ANIMATION}: {result['frames']} frames")
    return [Path(f) for f in result["files"]]


class Painter:
    """The figures' processes: ``python -m vpcontact.post.pictures --wait`` (pyvista's pictures,
    PAINTER_LINE_FIGURES, the animation; it loads pyvista and matplotlib and starts OpenGL
    at once) and ``... --wait --no-pictures`` (the other line figures; it loads
    matplotlib), each waiting for its job, without MPI's variables (they are no ranks of a
    job).  Started ahead of a run, their start-up overlaps the run, and the figures are
    drawn on two cores while the run's process waits.

    Raises:
        OSError: a process cannot be started.
    """

    def __init__(self):
        self.pictures, self.lines, self._job = _figure_process(), None, None
        try:
            self.lines = _figure_process("--no-pictures")
        except OSError:
            self.cancel()
            raise

    def draw(self, outdir: Path, factor: float, dim: int, animate: bool) -> None:
        """Give the processes their jobs (they draw while the caller goes on).

        Args:
            outdir: the results directory.
            factor: the displacement magnification.
            dim: the body's dimension.
            animate: also the animation.
        """
        self._job = {"results": str(outdir), "factor": factor, "dim": dim}
        _give(self.pictures, {**self._job, "animate": animate,
                              "line": list(PAINTER_LINE_FIGURES)})
        _give(self.lines, {**self._job, "animate": False, "line": _own_line_figures()})

    def finish(self) -> dict:
        """Wait for the figures (if the line figures' process failed, they are drawn here).

        Returns:
            {"files": [...], "frames": the animation's, or None}.

        Raises:
            PicturesError: the pictures' process failed (its last error line; ``written``:
                the line figures).
        """
        job = self._job
        try:
            lines = _result(self.lines)["files"]
        except PicturesError:
            lines = [str(f) for f in draw_line_figures(Path(job["results"]),
                                                       _own_line_figures(), job["factor"])]
        try:
            pictures = _result(self.pictures)
        except PicturesError as exc:
            exc.written = [Path(f) for f in lines]
            raise
        return {"files": lines + pictures["files"], "frames": pictures["frames"]}

    def cancel(self) -> None:
        """Stop the processes that still run (a run that ends without figures, Ctrl-C while
        drawing) and remove the temporary files they were writing."""
        killed = False
        for proc in (self.pictures, self.lines):
            if proc is not None and proc.poll() is None:
                proc.kill()
                proc.communicate()
                killed = True
        if killed and self._job is not None:
            for name in FIGURES:
                temporary(Path(self._job["results"]) / name).unlink(missing_ok=True)


def _own_line_figures() -> list[str]:
    """The line figures of the line figures' process."""
    return [n for n in LINE_FIGURES if n not in PAINTER_LINE_FIGURES]


def _figure_process(*options):
    """Start ``python -m vpcontact.post.pictures --wait`` (with options), MPI's variables left
    out."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_", "PMI_"))}
    return subprocess.Popen([sys.executable, "-P", "-m", pictures.__name__, "--wait", *options],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)


def _give(proc, job: dict) -> None:
    """Send a figure process its job (one JSON line).

    SIGPIPE is ignored during the write: a figure process that died makes the write fail
    (BrokenPipeError) instead of raising SIGPIPE, which PETSc's signal handler, installed
    in any process that has loaded dolfinx, turns into an MPI_Abort of the caller (the
    command line ignores SIGPIPE anyway; a Python script or a test does not)."""
    import signal
    import threading

    main = threading.current_thread() is threading.main_thread()
    before = signal.signal(signal.SIGPIPE, signal.SIG_IGN) if main else None
    try:
        proc.stdin.write(json.dumps(job) + "\n")
        proc.stdin.flush()                     # communicate() closes it
    except OSError:            # it died while starting: _result reports its error
        pass
    finally:
        if main:
            signal.signal(signal.SIGPIPE, before)


def _result(proc) -> dict:
    """The files (and frames) a figure process wrote; PicturesError if it failed."""
    out, err = proc.communicate()
    if proc.returncode != 0 or not out.strip():
        lines = [x for x in err.splitlines() if x.strip()]
        raise PicturesError(lines[-1] if lines else f"exit {proc.returncode}", [])
    return json.loads(out.strip().splitlines()[-1])
