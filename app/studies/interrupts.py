"""Interrupts of a study (SIGINT, SIGTERM): a signal ends the whole study, not one of its
runs.

Inside a run the time loop turns the signal into the status "interrupted" after the current
step (app/simulation.py); outside a run the command line's handler raises KeyboardInterrupt
(app/cli/main.py, ``take_signals``), whose argument names the signal.  A study turns both
into ``StudyInterrupted`` (a KeyboardInterrupt, so that no ``except Exception`` of a study
takes it for a failed run), and the command prints one line and exits 3.  Writes that must
not be cut in half (a run cache entry) run with the signals held back
(``signals_held``).
"""
from __future__ import annotations

import contextlib


class StudyInterrupted(KeyboardInterrupt):
    """A signal ended a study.

    Args:
        signal: the signal's name ("SIGINT", "SIGTERM"), or "a signal".
        where: what the study was doing, e.g. "the run r = 2, N = 4, delta = 1e-07".
        finished: the study's runs that had finished (kept in its cache or report).
        results: what the finished runs gave (the stability sweep's Outcomes), or None.
    """

    def __init__(self, signal: str, where: str, finished: int = 0, results: list | None = None):
        super().__init__(signal, where)
        self.signal, self.where, self.finished, self.results = signal, where, finished, results


def signal_name(exc: BaseException) -> str:
    """The signal that raised a KeyboardInterrupt.

    Args:
        exc: the exception (a KeyboardInterrupt, or one caused by it).

    Returns:
        Its signal's name (the argument app/cli/main.py's handler gives it), or "a signal".
    """
    if isinstance(exc, StudyInterrupted):
        return exc.signal
    name = exc.args[0] if exc.args and isinstance(exc.args[0], str) else ""
    return name if name.startswith("SIG") else "a signal"


def caused_by_interrupt(exc: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt (Ctrl-C, SIGTERM) among an exception's causes, as when it
    arrives while a C extension initialises (ImportError 'initialization failed').

    Args:
        exc: the exception.

    Returns:
        The KeyboardInterrupt, or None.
    """
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


class SignalWatch:
    """An observer of a study's run (the hooks of app.observers.Observer; not derived from
    it, so that this module imports nothing heavy) that sees a signal the time loop took but
    never acted on: one that arrived during the last step or the run's end (the run then
    completes and its handler is gone; without this the study would go on).  ``signal``: its
    name, the same on every rank, or None.
    """

    def __init__(self):
        self.signal = None

    def start(self, sim) -> None:
        """Nothing at the start.

        Args:
            sim: the Simulation.
        """

    def check(self, sim, record: dict) -> None:
        """Nothing before a step is accepted.

        Args:
            sim: the Simulation.
            record: the step's record.
        """

    def step(self, sim, record: dict) -> None:
        """Nothing after a step.

        Args:
            sim: the Simulation.
            record: the step's record.
        """

    def end(self, sim, summary) -> None:
        """Collect the signal the run's stop request holds, from every rank (collective).

        Args:
            sim: the Simulation, at its end.
            summary: its RunSummary (unused).
        """
        names = sim.comm.allgather(sim.stop_signal)
        self.signal = next((n for n in names if n), None)


    def stop_if_signalled(self, where: str) -> None:
        """Raise StudyInterrupted if a signal arrived at the end of the run (call once the
        run's results are kept: the run itself finished).

        Args:
            where: what the run is, for the message.

        Raises:
            StudyInterrupted: with ``finished`` 1 (this run), if the watch saw a signal.
        """
        if self.signal:
            raise StudyInterrupted(self.signal, f"{where} (at its end; that run finished)", 1)


def check_run(summary: dict, where: str) -> None:
    """Raise StudyInterrupted if a signal stopped a run of the study.

    Args:
        summary: the run's summary (summary.json's content).
        where: what the run is, for the message.

    Raises:
        StudyInterrupted: the run's status is "interrupted" (every rank agrees on it).
    """
    if summary["status"] == "interrupted":
        # "interrupted by SIGINT", or "... by a signal on another rank" (mpirun)
        by = summary["failure"]["reason"].removeprefix("interrupted by ")
        raise StudyInterrupted(by, f"{where} (after its step {summary['failure']['step']})")


@contextlib.contextmanager
def signals_held():
    """SIGINT and SIGTERM held back inside the block and acted on after it: the block (a
    file written through a temporary name) is never cut in half (main thread only; elsewhere
    a no-op).

    Yields:
        None.

    Raises:
        KeyboardInterrupt: after the block, if a signal arrived during it (its argument
            names the signal).
    """
    import signal
    import threading
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    old = {sig: signal.signal(sig, lambda signum, frame: caught.append(signum))
           for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
    if caught:
        raise KeyboardInterrupt(signal.Signals(caught[0]).name)
