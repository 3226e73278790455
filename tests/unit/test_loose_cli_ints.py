"""Every integer option of run, convergence, stability and bench has a range: a huge, a
negative or a zero (where zero means nothing) value is refused by the parser in one line
naming the option and the range, exit 2, before any case is read (a huge --reference of a
mesh.file study reached range() as an "internal error", a huge --levels or --refine kept
the study counting refinements for ever, --scene-n took negative values)."""
import subprocess
import sys
from pathlib import Path

import pytest

from vpcontact.cli import parser as cli

ROOT = Path(__file__).resolve().parents[2]
HUGE = "99999999999999999999"

# (command and its case, option, a value refused, the range the message names)
REFUSED = [
    (["run", "cases/wang_cheng_2021.yaml"], "--threads", HUGE, "1 to 1024"),
    (["run", "cases/wang_cheng_2021.yaml"], "--threads", "0", "1 to 1024"),
    (["run", "cases/wang_cheng_2021.yaml"], "--threads", "-2", "1 to 1024"),
    (["convergence", "cases/hertz_cylinder.yaml"], "--reference", HUGE, "1 to 4096"),
    (["convergence", "cases/hertz_cylinder.yaml"], "--reference", "0", "1 to 4096"),
    (["convergence", "cases/wang_cheng_2021.yaml"], "--reference", "100000", "1 to 4096"),
    (["convergence", "cases/hertz_cylinder.yaml"], "--levels", HUGE, "0 to 4096"),
    (["convergence", "cases/hertz_cylinder.yaml"], "--levels", "-1", "0 to 4096"),
    (["stability", "cases/hertz_cylinder.yaml"], "--refine", HUGE, "0 to 30"),
    (["stability", "cases/hertz_cylinder.yaml"], "--refine", "-1", "0 to 30"),
    (["stability", "cases/wang_cheng_2021.yaml"], "--n", HUGE, "1 to 4096"),
    (["stability", "cases/wang_cheng_2021.yaml"], "--n", "0", "1 to 4096"),
    (["stability", "cases/wang_cheng_2021.yaml"], "--steps", HUGE, "1 to 1000000"),
    (["stability", "cases/wang_cheng_2021.yaml"], "--steps", "0", "1 to 1000000"),
    (["bench"], "--levels", HUGE, "1 to 4096"),
    (["bench"], "--levels", "0", "1 to 4096"),
    (["bench"], "--repeat", HUGE, "1 to 100"),
    (["bench"], "--repeat", "0", "1 to 100"),
    (["bench"], "--scene-n", "-5", "0 to 4096"),
    (["bench"], "--scene-n", HUGE, "0 to 4096"),
    (["bench"], "--box3d-levels", HUGE, "1 to 4096"),
    (["bench"], "--box3d-levels", "0", "1 to 4096"),
    (["bench"], "--ranks", HUGE, "1 to 4096"),
    (["bench"], "--ranks", "-1", "1 to 4096"),
    (["bench"], "--memory-steps", HUGE, "1 to 1000000"),
    (["bench"], "--memory-steps", "0", "1 to 1000000"),
    (["bench"], "--extra", f"8:{HUGE}", "1 to 1000000"),
    (["bench"], "--extra", "0:8", "1 to 4096"),
    (["bench"], "--levels", "9" * 5000, "1 to 4096"),     # beyond int()'s 4300 digits
    (["bench"], "--levels", "1e3", "1 to 4096"),
]


@pytest.mark.parametrize("command, option, value, allowed", REFUSED,
                         ids=[f"{c[0]} {o} {v[:12]}" for c, o, v, _ in REFUSED])
def test_an_integer_option_out_of_range_is_one_line_exit_2(capsys, command, option, value,
                                                           allowed):
    with pytest.raises(SystemExit) as stop:
        cli.build_parser().parse_args([*command, option, value])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert f"argument {option}:" in err and f"allowed: {allowed}" in err, err
    assert "Traceback" not in err and "internal error" not in err


@pytest.mark.parametrize("command, option, value, expected", [
    (["run", "c.yaml"], "--threads", "1024", 1024),
    (["convergence", "c.yaml"], "--levels", "0", [0]),
    (["convergence", "c.yaml"], "--reference", "4096", 4096),
    (["stability", "c.yaml"], "--refine", "30", 30),
    (["stability", "c.yaml"], "--steps", "1000000", 1000000),
    (["bench"], "--scene-n", "0", 0),
    (["bench"], "--extra", "4096:1000000", [(4096, 1000000)]),
])
def test_the_ends_of_each_range_are_accepted(command, option, value, expected):
    args = cli.build_parser().parse_args([*command, option, value])
    assert vars(args)[option.lstrip("-").replace("-", "_")] == expected


def test_the_ranges_are_the_limits_of_the_case_and_the_bench():
    from vpcontact.case.meshrules import MAX_VERTICES
    from vpcontact.case.schema import SCHEMA
    from vpcontact.case.timegrid import MAX_STEPS
    from vpcontact.studies.bench import MAX_REPEAT
    assert cli.MAX_CELLS == SCHEMA["properties"]["mesh"]["properties"]["n"]["maximum"]
    assert cli.MAX_STEPS == MAX_STEPS
    assert cli.MAX_REPEAT == MAX_REPEAT
    assert 4 ** cli.MAX_REFINEMENTS > MAX_VERTICES    # no refusal of a refinement that fits


def test_box3d_levels_over_the_vertex_limit_are_refused_before_the_bench_runs():
    from vpcontact.case import CaseError
    from vpcontact.studies import bench
    with pytest.raises(CaseError, match=r"--box3d-levels 4096: .*box3d\.yaml: mesh\.n"):
        bench.check_arguments(str(ROOT / "cases/wang_cheng_2021.yaml"), [8], [], [1], 1,
                              [], box3d_levels=[8, 4096])
    bench.check_arguments(str(ROOT / "cases/wang_cheng_2021.yaml"), [8], [], [1], 1, [],
                          box3d_levels=[8, 16])


def test_a_huge_reference_of_a_mesh_file_study_is_one_line_exit_2(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "vpcontact", "convergence",
                           "cases/hertz_cylinder.yaml", "--reference", HUGE,
                           "--out", str(tmp_path / "cv")],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "--reference" in lines[0] and "1 to 4096" in lines[0], \
        proc.stderr
    assert not (tmp_path / "cv").exists()
