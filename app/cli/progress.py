"""Progress of a long run on rank 0: a bar with step, t, iterations and an ETA.

On a terminal the bar is redrawn in place (stderr); into a file or pipe it prints a line at
every 10% of the simulated time, so logs stay short.  The ETA extrapolates the wall time per
unit of simulated time (right for uniform and adaptive steps alike).
"""
from __future__ import annotations

import sys
import time

from vpcontact.observers import Observer


def _clock(seconds: float) -> str:
    seconds = int(round(max(seconds, 0.0)))
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class Progress:
    """The bar (see the module docstring); app/observers.ProgressBar drives it in a run.

    Args:
        T: the final time.
        total: the number of steps (None: adaptive, unknown).
        t0: the start time (a restart's t_n).
        enabled: False: draw nothing (ranks other than 0, --quiet).
        stream: where to draw (default stderr).
        width: the bar's width in characters.
    """

    def __init__(self, T: float, total: int | None, t0: float = 0.0, enabled: bool = True,
                 stream=None, width: int = 24):
        self.T, self.total, self.t0 = T, total, t0
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = enabled and hasattr(self.stream, "isatty") and self.stream.isatty()
        self.width = width
        self.start = time.perf_counter()
        self._next_line = 0.1
        self._drawn = False

    def text(self, n: int, t: float, its: int) -> str:
        """The bar's line after a step.

        Args:
            n: the step.
            t: its time.
            its: its iterations.

        Returns:
            The line, without a newline.
        """
        frac = min(max((t - self.t0) / max(self.T - self.t0, 1e-300), 0.0), 1.0)
        elapsed = time.perf_counter() - self.start
        eta = elapsed * (1 - frac) / frac if frac > 0 else float("nan")
        bar = "#" * int(round(frac * self.width))
        steps = f"{n}/{self.total}" if self.total else f"{n}"
        eta_s = _clock(eta) if eta == eta else "?"
        return (f"[{bar:<{self.width}}] {100 * frac:5.1f}%  step {steps}  t = {t:<9.4g} "
                f"iterations {its:2d}  elapsed {_clock(elapsed)}  ETA {eta_s}")

    def update(self, n: int, t: float, its: int) -> None:
        """Redraw (terminal) or print a line at every 10% of T (file, pipe) after a step.

        Args:
            n: the step.
            t: its time.
            its: its iterations.
        """
        if not self.enabled:
            return
        line = self.text(n, t, its)
        frac = (t - self.t0) / max(self.T - self.t0, 1e-300)
        if self.tty:
            self.stream.write("\r" + line)
            self.stream.flush()
            self._drawn = True
        elif frac >= self._next_line - 1e-12 or frac >= 1 - 1e-12:
            self.stream.write(line + "\n")
            self.stream.flush()
            while self._next_line <= frac + 1e-12:
                self._next_line += 0.1

    def close(self) -> None:
        """End the redrawn line on a terminal."""
        if self.enabled and self.tty and self._drawn:
            self.stream.write("\n")
            self.stream.flush()


class ProgressBar(Observer):
    """The observer that draws the Progress bar of a run on rank 0."""

    def __init__(self):
        self.bar = None

    def start(self, sim) -> None:
        """Create the bar (drawn on rank 0 only).

        Args:
            sim: the Simulation, set up (T, the number of steps if fixed, the start time).
        """
        self.bar = Progress(sim.case.time.T, sim.stepper.total, sim.t,
                            enabled=sim.comm.rank == 0)

    def step(self, sim, record: dict) -> None:
        """Advance the bar to step n.

        Args:
            sim: the Simulation after step n was accepted.
            record: the step's record (its Newton iterations are shown).
        """
        self.bar.update(sim.n, sim.t, record["newton_iterations"])

    def end(self, sim, summary) -> None:
        """Finish the bar's line.

        Args:
            sim: the Simulation (unused).
            summary: the RunSummary (unused).
        """
        if self.bar is not None:
            self.bar.close()


class ReaderWatch(Observer):
    """At every step, drops stdout and stderr whose reader downstream of mpirun has gone
    (app/cli/streams.py check_readers): PETSc's monitors write without Python."""

    def step(self, sim, record: dict) -> None:
        """Check the readers.

        Args:
            sim: the Simulation.
            record: the step's record.
        """
        from vpcontact.cli.streams import check_readers
        check_readers()
