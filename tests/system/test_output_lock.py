"""The output directory's lock: no `.vpcontact.lock` is left in the
directory after a command, however it ended, serial or under mpirun; two processes are
still kept out of one directory, also across the moment a process removes the file."""
import fcntl
import os
import subprocess
import sys

import pytest

from conftest import MPI_ENV, PAPER_CASE, ROOT, run_cli

TINY = ["--set", "mesh.n=4", "--set", "time.N=2", "--quiet"]


def _names(out) -> list[str]:
    return sorted(p.name for p in out.iterdir())


@pytest.mark.parametrize("nprocs", [1, 2])
def test_no_lock_file_after_a_run(tmp_path, nprocs):
    out = tmp_path / "o"
    proc = run_cli(["run", PAPER_CASE, "--out", out, *TINY], nprocs=nprocs)
    assert proc.returncode == 0, proc.stderr
    assert ".vpcontact.lock" not in _names(out)
    assert "summary.json" in _names(out)


def test_no_lock_file_after_a_failed_or_refused_run(tmp_path):
    """A failed run (exit 1) and a refusal after the lock was taken (earlier outputs,
    no --overwrite: exit 2) leave no lock file either."""
    out = tmp_path / "o"
    proc = run_cli(["run", PAPER_CASE, "--out", out, *TINY, "--set", "solver.method=snes_vi",
                    "-snes_max_it", "0"])
    assert proc.returncode == 1, proc.stderr
    assert ".vpcontact.lock" not in _names(out)
    before = _names(out)
    proc = run_cli(["run", PAPER_CASE, "--out", out, *TINY])
    assert proc.returncode == 2 and "--overwrite" in proc.stderr
    assert _names(out) == before


def test_a_held_lock_still_refuses_a_second_run(tmp_path):
    """While a process holds the directory (a run's lock() in a process that waits), a
    run there is refused with exit 2; once that process ends, the file is gone."""
    out = tmp_path / "o"
    code = ("import sys; from pathlib import Path; from vpcontact.cli.outdir import lock; "
            "assert lock(Path(sys.argv[1])) is None; print('locked', flush=True); "
            "sys.stdin.readline()")
    holder = subprocess.Popen([sys.executable, "-c", code, str(out)], cwd=ROOT, text=True,
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                              env={**os.environ, **MPI_ENV, "PYTHONPATH": str(ROOT)})
    try:
        assert holder.stdout.readline().strip() == "locked"
        proc = run_cli(["run", PAPER_CASE, "--out", out, "--overwrite", *TINY])
        assert proc.returncode == 2 and "another vpcontact process" in proc.stderr
    finally:
        holder.communicate("\n", timeout=60)
    assert holder.returncode == 0
    assert not out.exists()        # the holder created it and left it empty: removed


def test_lock_taken_on_a_file_being_removed_is_taken_again(tmp_path, monkeypatch):
    """The race of removing the file: process B opens the lock file, A (which held it)
    removes it and ends, B's flock then succeeds on a file that is no longer in the
    directory; B must lock the directory's file instead (else a third process C would
    take the new file while B writes)."""
    from vpcontact.cli import outdir
    path = tmp_path / ".vpcontact.lock"
    a = open(path, "a+")
    fcntl.flock(a, fcntl.LOCK_EX)
    real = fcntl.flock
    calls = []

    def flock(fh, op):
        calls.append(fh)
        if len(calls) == 1:            # A ends between B's open and B's flock
            path.unlink()
            a.close()
        return real(fh, op)
    monkeypatch.setattr(fcntl, "flock", flock)
    fh = outdir._take(path)
    assert fh is not None and len(calls) == 2
    assert os.fstat(fh.fileno()).st_ino == os.stat(path).st_ino
    monkeypatch.setattr(fcntl, "flock", real)
    c = open(path, "a+")                        # C: refused
    with pytest.raises(BlockingIOError):
        fcntl.flock(c, fcntl.LOCK_EX | fcntl.LOCK_NB)
    c.close()
    fh.close()
