"""Hostile case data is refused by validation, before any mesh, form or solver exists, with
one line naming the key: path-like names, expressions that are not finite somewhere on the
body or in [0, T], initial values outside the model's set, inconsistent adaptive steps,
degenerate sizes and numbers, unreadable files, PETSc options PETSc would refuse.  Also the
node states of contact.csv, whose tolerances come from the solution, not from g."""
import os
import re

import numpy as np
import pytest

from conftest import PAPER_CASE, make_case, paper_raw
from vpcontact.case import CaseError, load_raw
from vpcontact.case.reading import parse_override
from vpcontact.io.output import classify


def _refused(pattern: str, raw=None, **sections):
    """make_case(raw, **sections) raises one line matching pattern (without the '(line N)'
    that follows key paths read from the file)."""
    with pytest.raises(CaseError) as info:
        make_case(raw, **sections)
    msg = re.sub(r" \(line \d+\)", "", str(info.value))
    assert "\n" not in msg and re.search(pattern, msg), msg


@pytest.mark.parametrize("name", ["..", ".", "../x", "a/b", "", ".hidden", "-x"])
def test_names_that_are_paths_are_refused(name):
    _refused(r"name: .*allowed: letters, digits", name=name)


def test_a_file_name_that_is_a_path_needs_a_name(tmp_path):
    from vpcontact.case import validate
    raw = load_raw(PAPER_CASE)
    del raw["name"]
    with pytest.raises(CaseError, match="set name"):
        validate(raw, str(tmp_path / "..yaml"))
    assert make_case(name="ok_name-1.2").name == "ok_name-1.2"


@pytest.mark.parametrize("sections,pattern", [
    ({"loads": {"traction": {"top": [0, "sqrt(-1)"], "right": [0, 0]}}},
     r"loads\.traction\.top\[1\]: nan is not a finite number at x = 0, y = 1"),
    ({"material": {"E": 1000.0, "nu": 0.4, "viscoplastic": {
        "lambda1": 1.0, "lambda2": 1.0, "kappa0": "sqrt(x - 0.5)"}}},
     r"material\.viscoplastic\.kappa0: nan is not a finite number at x = 0"),
    ({"loads": {"f0": [0, "1e308*10"]}}, r"loads\.f0\[1\]: inf is not a finite number"),
    ({"loads": {"f0": [0, "1/(t - 0.5)"]}, "time": {"T": 1.0, "N": 2}},
     r"loads\.f0\[1\]: .*inf is not a finite number at .*t = 0\.5"),
    ({"loads": {"f0": ["(-1)**0.5", 0]}}, r"loads\.f0\[0\]: nan is not a finite number"),
    ({"loads": {"f0": [0, "1e200*x"]}}, r"loads\.f0\[1\]: .* is out of range at x ="),
    ({"initial": {"u0": [0, "log(x)"]}}, r"initial\.u0\[1\]: -inf is not a finite number"),
    ({"initial": {"sigma0": [["1/y", 0], [0, 0]]}}, r"initial\.sigma0\[0\]\[0\]: inf"),
])
def test_expressions_not_finite_on_the_body_are_refused(sections, pattern):
    _refused(pattern, **sections)


def test_an_integer_literal_beyond_the_largest_float_is_refused():
    big = "1" + "0" * 400            # 1e400 > 1.8e308: no float holds it
    _refused(r"loads\.f0\[1\]: number out of range: an integer of 401 digits \(allowed: "
             r"magnitudes up to 1\.8e\+308\)", loads={"f0": [0, f"{big}*t"]})
    _refused(r"material\.E: number out of range: an integer of 401 digits",
             material={"E": big, "nu": 0.4})


def test_a_traction_is_sampled_on_its_side_only():
    # 1/x is infinite on Gamma1 {x = 0}, finite on the right side {x = 1}
    case = make_case(loads={"traction": {"right": ["1/x", 0], "top": [0, -8.0]}})
    assert case.loads.traction["right"] == ("1/x", 0)


@pytest.mark.parametrize("sections,pattern", [
    ({"initial": {"u0": [0, "-x"]}},
     r"initial\.u0: violates u_nu <= g on Gamma3 \(y = 0\): u_nu = 1 > g"),
    ({"initial": {"u0": ["y", 0]}},
     r"initial\.u0: must vanish on Gamma1 \(x = 0\), got u0\[0\] = 1"),
    ({"material": {"E": 1000.0, "nu": 0.4, "viscoplastic": {
        "lambda1": 1.0, "lambda2": 1.0, "kappa0": "-100"}}},
     r"kappa0: must be >= 0 everywhere, got -100"),
    ({"initial": {"sigma0": [[0, "x"], ["y", 0]]}}, r"initial\.sigma0: must be symmetric"),
    ({"initial": {"u0": [0, {"table": [[0, 0], [1, 1]]}]}},
     r"initial\.u0\[1\]: a table in time is not an initial value"),
])
def test_initial_values_outside_the_model_are_refused(sections, pattern):
    _refused(pattern, **sections)


def test_initial_values_inside_the_model_are_accepted():
    case = make_case(initial={"u0": [0, "-0.01*x"], "sigma0": [[0, "x*y"], ["y*x", 0]]})
    assert case.initial.u0 == (0, "-0.01*x")


@pytest.mark.parametrize("time,pattern", [
    ({"T": 1.0, "N": 16, "adaptive": {"k_min": 1.0, "k_max": 1e-6}},
     r"k_min: 1 is larger than .*k_max"),
    ({"T": 1.0, "N": 16, "adaptive": {"k_min": 0.5}}, r"k_min: 0\.5 is larger than the first"),
    ({"T": 1.0, "k": 1e-90}, r"time\.k: 1e-90 gives 1e\+90 steps .*limit"),
    ({"T": 1.0, "N": 4, "adaptive": {"k_min": 1e-9, "k_max": 1e-9}},
     r"time\.adaptive\.k_max: 1e-09 gives at least 1e\+09 steps of T = 1 \(limit 1000000\)"),
    ({"T": 1.0, "N": 4, "adaptive": {"k_max": 1e-7}}, r"time\.adaptive\.k_max: 1e-07 gives"),
    ({"T": 1.0, "N": 4, "grading": 1e99}, r"time\.grading: .*overflow"),
    # k_max below the default k_min (first step / 1024 = 6.1e-5): no step is possible
    ({"T": 1.0, "N": 16, "adaptive": {"k_max": 1e-5}},
     r"time\.adaptive\.k_max: 1e-05 is smaller than the default time\.adaptive\.k_min = "
     r"first step / 1024 = 6\.10352e-05"),
])
def test_inconsistent_time_settings_are_refused(time, pattern):
    raw = paper_raw()
    raw["time"] = time
    _refused(pattern, raw)


def test_adaptive_settings_in_range_are_accepted():
    case = make_case(time={"adaptive": {"k_min": 1e-3, "k_max": 0.5}})
    assert case.time.adaptive["k_min"] == 1e-3


@pytest.mark.parametrize("sections,pattern", [
    ({"mesh": {"L1": 1e-120}}, r"mesh\.L1: 1e-120 is out of range"),
    ({"mesh": {"L1": 1e-35}}, r"mesh\.L1: 1e-35 m is a degenerate length"),
    ({"mesh": {"L2": 1e-7}}, r"mesh\.L2: 1e-07 m is too thin"),
    ({"material": {"E": 1e300, "nu": 0.4}}, r"material\.E: 1e\+300 is out of range"),
    ({"contact": {"g": 1e-300}}, r"contact\.g: 1e-300 is out of range"),
])
def test_degenerate_sizes_and_numbers_are_refused(sections, pattern):
    _refused(pattern, **sections)


def test_yaml_errors_are_one_line_with_line_and_column(tmp_path):
    with pytest.raises(CaseError) as info:
        parse_override("material.E=[1")
    assert "\n" not in str(info.value) and "line 1, column 3" in str(info.value)
    bad = tmp_path / "bad.yaml"
    bad.write_text("mesh:\n  n: 4\nmaterial: {E: 1\n")
    with pytest.raises(CaseError) as info:
        load_raw(bad)
    assert "\n" not in str(info.value) and re.search(r"line \d+, column \d+", str(info.value))
    bad.write_bytes(b"mesh:\n  n: \x01\n")
    with pytest.raises(CaseError, match=r"unacceptable character #x0001 \(line 2, column 6\)"):
        load_raw(bad)
    bad.write_text("mesh:\n  n: " + "1" * 5000 + "\n")      # Python refuses to read it
    with pytest.raises(CaseError, match=r"more than 30 digits \(line 2, column 6\)"):
        load_raw(bad)


@pytest.mark.parametrize("kind", ["device", "directory", "fifo"])
def test_files_that_are_not_regular_are_refused_without_reading(kind, tmp_path):
    path = {"device": "/dev/zero", "directory": str(tmp_path)}.get(kind, tmp_path / "fifo")
    if kind == "fifo":
        os.mkfifo(path)        # opening it would block until a writer comes
    with pytest.raises(CaseError, match="not a regular file"):
        load_raw(path)


def test_a_file_larger_than_the_limit_is_read_no_further(tmp_path, monkeypatch):
    import vpcontact.case.reading
    monkeypatch.setattr(vpcontact.case.reading, "MAX_FILE_BYTES", 100)
    big = tmp_path / "big.yaml"
    big.write_text("# " + "x" * 200 + "\n")
    with pytest.raises(CaseError, match="larger than 100 bytes"):
        load_raw(big)


@pytest.mark.parametrize("options,pattern", [
    ({"ksp_type": "nonexistent"}, r"petsc\.ksp_type: 'nonexistent' is not a KSP type "
                                  r"\(allowed: .*preonly"),
    ({"snes_type": "foo"}, r"petsc\.snes_type: 'foo' is not a SNES type \(allowed: .*newtonls"),
    ({"pc_type": "foo"}, r"petsc\.pc_type: 'foo' is not a PC type"),
    ({"snes_linesearch_type": "foo"}, r"line search type \(allowed: basic, bt"),
    ({"pc_factor_mat_solver_type": "nosuch"}, r"not a factorisation package \(allowed: .*petsc"),
    ({"fast_ksp_type": "bad"}, r"petsc\.fast_ksp_type: 'bad' is not a KSP type"),
    ({"snes_rtol": "abc"}, r"petsc\.snes_rtol: 'abc' is not a tolerance"),
    ({"snes_max_it": 1.5}, r"petsc\.snes_max_it: 1\.5 is not an integer"),
    ({"snes_ksp_ew": 3}, r"petsc\.snes_ksp_ew: PETSc refuses it: Unknown logical value"),
    ({"snes_linesearch_order": "x"}, r"petsc\.snes_linesearch_order: PETSc refuses it"),
])
def test_petsc_options_petsc_would_refuse_are_refused(options, pattern):
    _refused(pattern, petsc=options)


def test_valid_petsc_options_pass_and_the_database_is_left_clean():
    from petsc4py import PETSc

    from vpcontact.solvers.optioncheck import check_petsc_options
    from vpcontact.solvers.options import PREFIX
    options = {"snes_monitor": None, "ksp_type": "gmres", "pc_type": "jacobi",
               "snes_rtol": 1e-12, "snes_max_it": "20", "fast_pc_factor_mat_solver_type": "petsc"}
    check_petsc_options(options, "test")
    assert not any(PETSc.Options().hasName(PREFIX + k) for k in options)
    with pytest.raises(CaseError, match=r"^command line: -ksp_type: 'x' is not a KSP type"):
        check_petsc_options({"ksp_type": "x"}, "command line", where="-")
    # refused together with the case's options (MUMPS has no ILU): the given one is named
    with pytest.raises(CaseError, match=r"^command line: -pc_type: PETSc refuses it: .*ILU"):
        check_petsc_options({"pc_type": "ilu"}, "command line", where="-",
                            base=make_case().petsc)


def test_absolute_petsc_tolerances_scale_with_the_case():
    paper = make_case().petsc
    assert paper["snes_atol"] == 1e-11 and paper["snes_vi_zero_tolerance"] == 1e-8
    tiny = make_case(mesh={"L1": 1e-9, "L2": 1e-9}).petsc
    assert tiny["snes_atol"] == pytest.approx(1e-20) and \
        tiny["snes_vi_zero_tolerance"] == pytest.approx(1e-17)
    assert make_case(petsc={"snes_atol": 1e-6}).petsc["snes_atol"] == 1e-6


def _table(u_nu, pressure, u_tau):
    return {"x": np.arange(len(u_nu)), "u_x": np.asarray(u_tau), "u_y": -np.asarray(u_nu),
            "u_nu": np.asarray(u_nu), "u_tau": np.asarray(u_tau),
            "neg_sigma_nu": np.asarray(pressure), "neg_sigma_tau": np.zeros(len(u_nu))}


def test_contact_states_do_not_depend_on_the_size_of_g():
    table = _table([0.011, 0.023, 0.041, -0.002], [1.1, 2.3, 4.1, 1e-15], [-0.01, -0.02, 0, 0])
    expected = ["compliance", "compliance", "compliance", "separated"]
    for g in (None, 0.05, 1e8):
        assert list(classify(table, g)) == expected
    assert list(classify(table, 0.023)) == ["compliance", "bound", "bound", "separated"]


def test_a_stiff_compliance_penetrates_below_round_off_but_is_in_contact():
    # c_nu = 1e300: u_nu ~ 1e-300 under a finite pressure
    table = _table([1.7e-300, 3.9e-300, -1e-3], [1.7, 3.9, 0.0], [-2e-3, -4e-3, -5e-3])
    assert list(classify(table, None)) == ["compliance", "compliance", "separated"]


@pytest.mark.parametrize("options,pattern", [
    ({"snes_type": "newtonls"}, r"petsc\.snes_type: 'newtonls' ignores the bound u_nu <= g .*"
                                r"\(allowed: vinewtonrsls, vinewtonssls\)"),
    ({"snes_type": "ksponly"}, r"petsc\.snes_type: 'ksponly' ignores the bound"),
    ({"fast_pc_type": "jacobi"}, r"petsc\.fast_pc_type: 'jacobi': the fast solver needs an "
                                 r"exact factorisation \(allowed: lu, cholesky\)"),
    ({"fast_ksp_type": "cg", "fast_pc_type": "none"},
     r"petsc\.fast_ksp_type: 'cg': .*exact factorisation \(allowed: preonly\)"),
    ({"fast_pc_factor_mat_solver_type": "superlu"},
     r"petsc\.fast_pc_factor_mat_solver_type: 'superlu' cannot factorise the fast solver's "
     r"BAIJ matrix by lu in serial \(allowed: mumps, petsc\)"),
    ({"fast_pc_type": "cholesky", "fast_pc_factor_mat_solver_type": "cholmod"},
     r"'cholmod' cannot factorise .* by cholesky in serial \(allowed: petsc\)"),
    ({"snes_rtol": 1e300}, r"petsc\.snes_rtol: 1e\+300 is not a relative tolerance.*"
                           r"\(allowed: 0 <= value < 1\)"),
    ({"snes_stol": 1}, r"petsc\.snes_stol: 1 is not a relative tolerance"),
    ({"ksp_rtol": 2.0}, r"petsc\.ksp_rtol: 2\.0 is not a relative tolerance"),
    ({"snes_atol": 1e90}, r"petsc\.snes_atol: 1e\+90 is too large: Newton would stop before "
                          r"solving.*of order 8 .*\(allowed: a number >= 0 up to 0\.008\)"),
    ({"snes_vi_zero_tolerance": 1e10}, r"petsc\.snes_vi_zero_tolerance: 10+\.0 is too large: "
                                       r"SNES VI would take dofs .*\(1e-3 the gap g\)"),
    ({"snes_max_it": 10**12}, r"petsc\.snes_max_it: 1000000000000 is out of range \(allowed: "
                              r"integers from 0 to 2147483647\)"),
    ({"ksp_max_it": -1}, r"petsc\.ksp_max_it: -1 is out of range"),
    ({"snes_lag_jacobian": -2**40}, r"snes_lag_jacobian: .* is out of range \(allowed: "
                                    r"integers from -2147483647"),
    ({f"foo_{i}": 1 for i in range(600)}, r"petsc: 610 options .*too many \(allowed: at most "
                                          r"100\)"),
])
def test_petsc_options_that_would_solve_a_different_problem_are_refused(options, pattern):
    _refused(pattern, petsc=options)


def test_the_case_scales_bound_the_absolute_tolerances_given_later():
    from vpcontact.solvers.optioncheck import check_petsc_options
    petsc = make_case(mesh={"L1": 1e-3, "L2": 1e-3}).petsc
    with pytest.raises(CaseError, match=r"^command line: -snes_atol: .*up to 8e-06"):
        check_petsc_options({"snes_atol": 1e-5}, "command line", where="-", base=petsc)
    check_petsc_options({"snes_atol": 1e-6, "snes_lag_jacobian": -2, "snes_type": "vinewtonssls",
                         "fast_pc_type": "cholesky"}, "command line", where="-", base=petsc)


@pytest.mark.parametrize("sections,name", [
    ({"loads": {"f0": ["z*1e200", 0]}}, "loads.f0[0]"),
    ({"loads": {"f0": [0, 0], "traction": {"top": ["z", 0]}}}, "loads.traction.top[0]"),
    ({"initial": {"u0": [0, "z"]}}, "initial.u0[1]"),
    ({"initial": {"sigma0": [[0, "z"], ["z", 0]]}}, "initial.sigma0[0][1]"),
])
def test_a_2d_case_has_no_z(sections, name):
    _refused(re.escape(name) + r": unknown name 'z' \(allowed: t?,? ?x, y, e, pi\)", **sections)


def test_kappa0_of_a_2d_case_has_no_z():
    raw = paper_raw()
    raw["material"]["viscoplastic"]["kappa0"] = "1 + z"
    _refused(r"kappa0\[0\]: unknown name 'z' \(allowed: x, y, e, pi\)", raw)


def test_a_small_gap_keeps_a_valid_default_active_set_tolerance():
    """g = 1e-6: the default snes_vi_zero_tolerance (1e-8 L) was above its own limit
    (1e-3 g) and the paper case with a small gap was refused."""
    from conftest import make_case
    case = make_case(contact={"g": 1e-6})
    assert case.petsc["snes_vi_zero_tolerance"] <= 1e-4 * 1e-6 * (1 + 1e-12)
    assert make_case().petsc["snes_vi_zero_tolerance"] == 1e-8      # the paper's value


@pytest.mark.parametrize("kind", ["fifo", "device", "directory", "nul", "long"])
def test_a_mesh_file_that_is_not_a_regular_file_is_refused_without_reading(kind, tmp_path):
    """mesh.file names a FIFO (opening it would block), a device, a directory, a name with
    a NUL character or too long for the file system: one line naming mesh.file."""
    name = {"nul": "a\0b.msh", "long": "x" * 300 + ".msh"}.get(kind, "m.msh")
    if kind == "fifo":
        os.mkfifo(tmp_path / name)
    elif kind == "device":
        os.symlink("/dev/zero", tmp_path / name)
    elif kind == "directory":
        (tmp_path / name).mkdir()
    raw = {"mesh": {"file": name}, "material": {"E": 1.0, "nu": 0.3}, "loads": {},
           "time": {"T": 1.0, "N": 1}}
    from vpcontact.case import validate
    with pytest.raises(CaseError) as info:
        validate(raw, str(tmp_path / "case.yaml"))
    assert "\n" not in str(info.value) and re.search(
        r"mesh\.file: .*(no such file|not a readable regular file)", str(info.value))


def test_an_error_in_a_value_from_set_cites_set_not_a_line_of_the_file(tmp_path):
    from vpcontact.case import validate
    case = tmp_path / "case.yaml"
    case.write_text(open(PAPER_CASE).read())
    for item, pattern in [
            ("material.E=-3", r"case\.yaml: material\.E: -3 is less than or equal to the "
                              r"minimum of 0 \(the value of --set material\.E=-3\)$"),
            ("material={E: -1, nu: 0.3}", r"material\.E: .* \(the value of --set "
                                          r"material=\{E: -1, nu: 0\.3\}\)$"),
            ("material.E=1e400", r"material\.E: inf is not a finite number \(the value of "
                                 r"--set material\.E=1e400\)$")]:
        with pytest.raises(CaseError) as info:
            validate(load_raw(case, [item]), str(case))
        assert "(line" not in str(info.value) and re.search(pattern, str(info.value)), \
            str(info.value)
    # a value of the file keeps its line, beside another key given by --set
    case.write_text(open(PAPER_CASE).read().replace("E: 1000.0", "E: -3.0"))
    with pytest.raises(CaseError) as info:
        validate(load_raw(case, ["material.nu=0.3"]), str(case))
    assert re.search(r"material\.E \(line 14\): -3\.0 is less", str(info.value)) and \
        "--set" not in str(info.value), str(info.value)


# Options that would load code or name a file: {out} a file outside any output directory,
# {module} a module that leaves a marker file when imported (petsc4py imports the module of a
# python type's class when the options are read: check's option test would do that).
PETSC_ATTACKS = [
    ({"pc_type": "python", "pc_python_type": "{module}.PC"},
     r"petsc\.pc_type: a python type makes petsc4py import and run Python code"),
    ({"ksp_type": "python", "ksp_python_type": "{module}.KSP"}, r"petsc\.ksp_type: a python"),
    ({"snes_type": "python", "snes_python_type": "{module}.SNES"}, r"petsc\.snes_type: a pyt"),
    ({"amg_mg_levels_pc_type": "python"}, r"petsc\.amg_mg_levels_pc_type: a python type"),
    ({"pc_python_type": "{module}.PC"}, r"petsc\.pc_python_type: not an option a case may"),
    ({"ksp_monitor": "ascii:{out}"}, r"petsc\.ksp_monitor: 'ascii:.*' would write to a file"),
    ({"snes_view": "binary:{out}"}, r"petsc\.snes_view: 'binary:.*' would write to a file"),
    ({"fast_ksp_view": "ascii:{out}:ascii_info"}, r"petsc\.fast_ksp_view: .* would write"),
    ({"snes_monitor": "draw"}, r"petsc\.snes_monitor: 'draw' would write to a file or a win"),
    ({"snes_converged_reason": "{out}"}, r"petsc\.snes_converged_reason: .* would write"),
    ({"ksp_view_mat": "binary:{out}"}, r"petsc\.ksp_view_mat: not an option a case may give"),
    ({"log_view": "ascii:{out}"}, r"petsc\.log_view: not an option a case may give"),
    ({"options_file": "{opts}"}, r"petsc\.options_file: not an option a case may give"),
    ({"malloc_dump": "{out}"}, r"petsc\.malloc_dump: not an option a case may give"),
    ({"pc_factor_mat_ordering_type": "{out}"}, r"petsc\.pc_factor_mat_ordering_type: .* is "
     r"not a plain value"),
]


@pytest.mark.parametrize("options,pattern", PETSC_ATTACKS)
def test_petsc_options_that_load_code_or_name_files_are_refused(options, pattern, tmp_path,
                                                                 monkeypatch):
    from vpcontact.solvers.optioncheck import check_petsc_options
    module = f"vpcontact_attack_{os.getpid()}"
    marker, out, opts = tmp_path / "imported", tmp_path / "outside.txt", tmp_path / "opts"
    (tmp_path / f"{module}.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    opts.write_text(f"-vpcontact_ksp_monitor ascii:{out}\n-ksp_monitor ascii:{out}\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    given = {k: v.format(module=module, out=out, opts=opts) for k, v in options.items()}
    _refused(pattern, petsc=given)
    with pytest.raises(CaseError, match=r"^command line: -" + pattern.split(r"\.", 1)[1]):
        check_petsc_options(given, "command line", where="-", base=make_case().petsc)
    assert not marker.exists() and not out.exists()


def test_petsc_options_users_need_pass_the_allow_list():
    from vpcontact.solvers.amg import AMG_PETSC
    from vpcontact.solvers.optionpolicy import policy_fault
    from vpcontact.solvers.options import DEFAULT_PETSC
    needed = {**DEFAULT_PETSC, **AMG_PETSC, "snes_monitor": None, "ksp_view": True,
              "fast_ksp_view": "::ascii_info_detail", "snes_converged_reason": "ascii",
              "ksp_converged_reason": None, "fast_pc_factor_mat_solver_type": "mumps",
              "mat_mumps_icntl_14": 50, "snes_linesearch_damping": 0.5, "snes_ksp_ew": False,
              "amg_keep_levels": False, "ksp_gmres_restart": 100, "pc_hypre_type": "boomeramg",
              "sub_pc_type": "ilu", "mg_levels_1_ksp_type": "richardson", "snes_lag_jacobian": -2,
              "ksp_error_if_not_converged": True, "snes_vi_monitor": None}
    assert {k: policy_fault(k, v) for k, v in needed.items() if policy_fault(k, v)} == {}
