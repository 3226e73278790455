"""SIGTERM / SIGINT after the run's time loop (app/cli/ending.py): the run's files are
complete, so the process says so in one line and exits 3, never "interrupted before the
time loop started" and never killed by the raw signal while it finalises PETSc and MPI."""
import json
import os
import signal
import subprocess
import sys

import pytest

from conftest import MPI_ENV, ROOT

CASE = """name: after_loop
mesh: {n: 8}
material: {E: 1000.0, nu: 0.4}
contact:
  g: 0.012
  normal_compliance: {c_nu: 100.0}
  friction: {b: 1.0, c1: 60.0, c2: 60.0, u1: 0.01}
loads:
  traction: {top: [0.0, -8.0], right: [-3.2, 0.0]}
time: {T: 1.0, N: 4}
"""


def _run_signalled_at(pattern: str, sig, tmp_path):
    """Run the case, send ``sig`` when a log line contains ``pattern``; (exit code, output)."""
    case = tmp_path / "case.yaml"
    case.write_text(CASE)
    cmd = [sys.executable, "-m", "vpcontact", "run", str(case), "--out", str(tmp_path / "o"),
           "--no-plots"]
    env = {**os.environ, **MPI_ENV, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    lines, sent = [], False
    for line in proc.stdout:
        lines.append(line)
        if not sent and pattern in line:
            os.kill(proc.pid, sig)
            sent = True
    assert proc.wait(timeout=300) is not None and sent, "".join(lines)
    return proc.returncode, "".join(lines)


@pytest.mark.parametrize("pattern, sig", [("done:", signal.SIGTERM),
                                          ("outputs:", signal.SIGTERM),
                                          ("Gamma3 nodes at T", signal.SIGINT)])
def test_a_signal_after_the_loop_says_the_run_completed(pattern, sig, tmp_path):
    code, out = _run_signalled_at(pattern, sig, tmp_path)
    assert code == 3, (code, out[-2000:])
    assert "Traceback" not in out and "before the time loop" not in out
    name = signal.Signals(sig).name
    assert (f"vpcontact: interrupted by {name} after the run completed; its outputs are "
            f"complete in {tmp_path / 'o'}") in out
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["status"] == "completed"


def test_a_signal_while_the_process_finalises_is_reported(tmp_path):
    """A SIGTERM sent right after PETSc's finalisation (which puts the default action, death
    by the signal, back) and one sent before it: exit 3 with one line, not -15."""
    script = ("import os, signal\n"
              "from petsc4py import PETSc\n"
              "from vpcontact.cli.ending import hold_signals, signal_at_exit\n"
              "from vpcontact.startup import quick_exit\n"
              "def after_petsc():\n"
              "    hold_signals()\n"
              "    os.kill(os.getpid(), signal.SIGTERM)\n"
              "hold_signals()\n"
              "os.kill(os.getpid(), signal.SIGINT)\n"
              "quick_exit(0, last=signal_at_exit, after_petsc=after_petsc)\n")
    env = {**os.environ, **MPI_ENV, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                          text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 3, (proc.returncode, proc.stderr)
    assert proc.stderr.strip() == ("vpcontact: interrupted by SIGINT as vpcontact ended (the "
                                   "command had completed)")


def test_main_names_a_signal_after_the_run(monkeypatch, capsys, tmp_path):
    """In process: a KeyboardInterrupt reaching main after the run ended (here raised by a
    stand-in of cmd_run) is reported as after the run, with its status."""
    import vpcontact.cli.main as cli
    from vpcontact.cli import ending

    def run_then_signal(args, petsc_cli):
        ending.run_ended("diverged", tmp_path)
        raise KeyboardInterrupt("SIGTERM")

    monkeypatch.setitem(cli.COMMANDS, "run", (run_then_signal, True))
    assert cli.main(["run", str(tmp_path / "case.yaml")]) == 3
    err = capsys.readouterr().err
    assert err.strip() == (f"vpcontact: interrupted by SIGTERM after the run ended (diverged: "
                           f"see {tmp_path}/summary.json); its outputs are as written")
    ending.forget()
