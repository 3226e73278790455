"""``check`` takes the command line's PETSc options as ``run`` does (the same checks, the
same step solver reported), and the commands that use no PETSc options (plot, info, bench)
refuse them in one line, exit 2, instead of dropping them silently."""
import pytest
import yaml

from conftest import PAPER_CASE, ROOT, run_cli

SMALL = ["--set", "mesh.n=4", "--set", "time.N=2"]


def _one_line_exit_2(proc) -> str:
    assert proc.returncode == 2, (proc.returncode, proc.stdout[-1500:], proc.stderr[-1500:])
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("vpcontact: error: "), proc.stderr
    return lines[0]


def test_check_refuses_what_run_refuses(tmp_path):
    """-snes_type newtonls ignores the bound u_nu <= g: run refuses it, and check with the
    same line (before: check said "valid", exit 0)."""
    option = ["-snes_type", "newtonls"]
    ran = _one_line_exit_2(run_cli(["run", PAPER_CASE, *SMALL, "--out", tmp_path / "o",
                                    *option]))
    checked = _one_line_exit_2(run_cli(["check", PAPER_CASE, *SMALL, *option]))
    assert checked == ran and "-snes_type: 'newtonls'" in checked


def test_check_reports_the_step_solver_run_uses(tmp_path):
    """The punch held only by its contact pair (cases/punch_on_substrate.yaml, coarse): with
    a fast_* option on the command line the condensed solver is not possible
    (app/solvers/choice.py), so check reports SNES VI, as the case file's petsc: section
    gives it (before: check said "condensed", and run used SNES VI)."""
    raw = yaml.safe_load((ROOT / "cases" / "punch_on_substrate.yaml").read_text())
    raw["mesh"].update(file=str(ROOT / "cases" / raw["mesh"]["file"]), size=3.0)
    raw["time"].update(T=0.24, N=3)
    case = tmp_path / "punch.yaml"
    case.write_text(yaml.safe_dump(raw))
    option = ["-fast_pc_factor_mat_solver_type", "mumps"]

    def solver_line(args):
        proc = run_cli(["check", case, *args])
        assert proc.returncode == 0, proc.stderr
        return next(ln for ln in proc.stdout.splitlines() if ln.startswith("step solver:"))

    assert solver_line([]).startswith("step solver: condensed")
    in_file = solver_line(["--set", "petsc.fast_pc_factor_mat_solver_type=mumps"])
    assert in_file.startswith("step solver: snes_vi")
    assert solver_line(option) == in_file


@pytest.mark.parametrize("args", [["info"], ["plot", "RESULTS"], ["bench", "--levels", "1"]])
def test_commands_without_petsc_options_refuse_them(args, tmp_path):
    args = [str(tmp_path) if a == "RESULTS" else a for a in args]
    line = _one_line_exit_2(run_cli([*args, "-snes_monitor", "-ksp_type", "cg"],
                                    cwd=tmp_path))
    assert "-snes_monitor -ksp_type" in line and f"{args[0]}:" in line
    assert "allowed with: run, check, convergence, stability" in line
