"""Faults of the environment and of the files a run reads back, and the arguments of the study
commands: unwritable caches (replaced, one warning), a damaged compiled kernel (rebuilt),
damaged checkpoints, and bench / convergence / stability arguments refused before anything
runs (one line, exit code 2).

Unwritable paths lie under a regular file: mkdir fails there for root as well."""
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
import pytest

from conftest import MPI_ENV, PAPER_CASE, ROOT

TINY = ["--set", "mesh.n=4", "--set", "time.N=2"]
CACHE_VARS = ("HOME", "XDG_CACHE_HOME", "XDG_CONFIG_HOME", "VPCONTACT_CACHE", "MPLCONFIGDIR")


def _cli(args, env=None, nprocs=1, timeout=600):
    """``python -m vpcontact ARGS`` with the environment ``env`` in place of the cache variables."""
    base = {k: v for k, v in os.environ.items() if k not in CACHE_VARS}
    base.update(MPI_ENV, PYTHONPATH=str(ROOT), HOME=os.environ.get("HOME", "/root"))
    cmd = [sys.executable, "-m", "vpcontact", *map(str, args)]
    if nprocs > 1:
        cmd = ["mpirun", "-n", str(nprocs), *cmd]
    return subprocess.run(cmd, cwd=ROOT, env={**base, **(env or {})}, capture_output=True,
                          text=True, timeout=timeout)


def _one_error_line(proc, code=2) -> str:
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == code, proc.stderr
    assert "Traceback" not in proc.stderr
    errors = [ln for ln in lines if ln.startswith("vpcontact")]
    assert len(errors) == 1, proc.stderr
    return errors[0]


@pytest.fixture
def blocker(tmp_path):
    """A regular file: no directory can be created under it."""
    f = tmp_path / "file"
    f.write_text("not a directory")
    return f


# ------------------------------------------------------------------ caches: usable or replaced
def test_unwritable_home_runs_on_temporary_caches(blocker):
    home = blocker / "home"
    base = os.path.join(tempfile.gettempdir(), f"vpcontact-{os.getuid()}")
    for args in (["check", PAPER_CASE, *TINY],
                 ["run", PAPER_CASE, *TINY, "--out", blocker.parent / "out", "--no-plots"]):
        proc = _cli(args, {"HOME": str(home)})
        assert proc.returncode == 0, proc.stderr
        warnings = [ln for ln in proc.stderr.splitlines() if "warning" in ln.lower()]
        assert len(warnings) == 1, proc.stderr
        for wanted, used in ((home / ".cache" / "vpcontact", f"{base}/vpcontact"),
                             (home / ".cache" / "fenics", f"{base}/fenics")):
            assert f"{wanted} (" in warnings[0] and f"-> {used}" in warnings[0]
    assert (blocker.parent / "out" / "summary.json").is_file()
    info = _cli(["info"], {"HOME": str(home)}).stdout
    assert f"JIT cache (FFCx): {base}/fenics" in info
    assert f"run cache (convergence study): {base}/vpcontact" in info


def test_unwritable_run_cache_only_is_replaced(blocker):
    proc = _cli(["info"], {"VPCONTACT_CACHE": str(blocker / "cache")})
    assert proc.returncode == 0
    line = _one_error_line(proc, 0)
    assert line.startswith("vpcontact: warning:") and str(blocker / "cache") in line
    assert "FFCx" not in line


def test_nothing_writable_is_one_error_line(blocker, tmp_path):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    (tmp / f"vpcontact-{os.getuid()}").write_text("taken")
    proc = _cli(["check", PAPER_CASE, *TINY], {"HOME": str(blocker / "home"),
                                               "TMPDIR": str(tmp)})
    line = _one_error_line(proc, 1)
    assert line.startswith("vpcontact: error: no writable ")
    assert proc.stdout == ""


@pytest.mark.parametrize("value", ["", "relative/cache", "."])
@pytest.mark.parametrize("var", ["XDG_CACHE_HOME", "XDG_CONFIG_HOME"])
def test_empty_or_relative_xdg_values_are_ignored(tmp_path, var, value):
    """No cache or settings directory relative to the current one: dolfinx, matplotlib and
    vpcontact all use the home directory's, as the XDG specification asks."""
    work, home = tmp_path / "work", tmp_path / "home"
    work.mkdir()
    code = ("from vpcontact.cli.entry import prepare_process; prepare_process(); "
            "import matplotlib; from dolfinx import jit; from vpcontact import cachepaths; "
            "print(jit.DOLFINX_DEFAULT_JIT_PARAMETERS['cache_dir'][0]); "
            "print(cachepaths.cache_root()); print(matplotlib.get_cachedir())")
    env = {k: v for k, v in os.environ.items() if k not in CACHE_VARS}
    env.update(MPI_ENV, PYTHONPATH=str(ROOT), HOME=str(home), **{var: value})
    proc = subprocess.run([sys.executable, "-c", code], cwd=work, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == [str(home / ".cache" / "fenics"),
                                   str(home / ".cache" / "vpcontact"),
                                   str(home / ".cache" / "matplotlib")]
    assert list(work.iterdir()) == []
    warnings = [ln for ln in proc.stderr.splitlines() if ln.startswith("vpcontact")]
    assert warnings == ([f"vpcontact: warning: {var}={value!r} is not an absolute path, "
                         "ignored (as the XDG base directory specification asks)"]
                        if value else [])


@pytest.mark.parametrize("where", ["file", "missing"])
def test_a_tmpdir_that_is_no_writable_directory_is_ignored(blocker, where):
    """MPI starts (no pages of Open MPI mkdir errors) and the run says so in one line."""
    tmp = blocker if where == "file" else blocker.parent / "missing"
    proc = _cli(["run", PAPER_CASE, *TINY, "--out", blocker.parent / "out", "--no-plots",
                 "--quiet"], {"TMPDIR": str(tmp)})
    assert proc.returncode == 0, proc.stderr
    assert [ln for ln in proc.stderr.splitlines() if "warning" in ln or "mkdir" in ln] == \
        [f"vpcontact: warning: TMPDIR={str(tmp)!r} is not a writable directory, ignored"]
    assert (blocker.parent / "out" / "summary.json").is_file()


# ------------------------------------------------------------------ compiled kernels
def _tiny_module(tmp_path, monkeypatch, tag):
    from vpcontact.kernels import build as kernels
    monkeypatch.setattr(kernels, "cache_dir", lambda: tmp_path / "kernels")
    src = f"int plus_{tag}(int x) {{ return x + {len(tag)}; }}"
    name = kernels.module_name(f"_vpcontact_test_{tag}", f"int plus_{tag}(int x);", src)
    return kernels, src, tmp_path / "kernels" / f"{name}.so"


def test_damaged_cached_kernel_is_rebuilt_in_process(tmp_path, monkeypatch, caplog):
    kernels, src, target = _tiny_module(tmp_path, monkeypatch, "damaged")
    target.parent.mkdir(parents=True)
    target.write_bytes(b"\x7fELF\x02\x01\x01" + bytes(57))      # a truncated library
    with caplog.at_level("INFO", logger="vpcontact"):
        mod = kernels.compiled("_vpcontact_test_damaged", "int plus_damaged(int x);", src,
                               "test kernel")
    assert mod is not None and mod.lib.plus_damaged(1) == 8
    assert "rebuilding" in caplog.text and "unavailable" not in caplog.text
    assert target.stat().st_size > 64
    assert sorted(p.name for p in target.parent.iterdir()) == [target.name]   # no leftovers


def test_damaged_cached_kernel_is_rebuilt_by_a_run(tmp_path):
    from vpcontact import kernels
    cache = tmp_path / "cache"
    name = kernels.CELL_KERNELS.name()
    target = cache / "kernels" / f"{name}.so"
    target.parent.mkdir(parents=True)
    target.write_bytes(b"\x7fELF\x02\x01\x01" + bytes(57))
    for _ in range(2):            # rebuilt by the first run, used by the second
        proc = _cli(["run", PAPER_CASE, *TINY, "--out", tmp_path / "out", "--overwrite",
                     "--no-plots"], {"VPCONTACT_CACHE": str(cache)})
        assert proc.returncode == 0, proc.stderr
        assert "unavailable" not in proc.stdout + proc.stderr      # no numpy fallback
    assert target.stat().st_size > 10000 and "rebuilding" not in proc.stdout


# ------------------------------------------------------------------ checkpoints
@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    out = tmp_path_factory.mktemp("ck") / "full"
    proc = _cli(["run", PAPER_CASE, *TINY, "--set", "output.checkpoint_every=1", "--out", out,
                 "--no-plots", "--quiet"])
    assert proc.returncode == 0, proc.stderr
    return out / "checkpoint_000001.npz"


def _variant(src, dst, **changes):
    data = dict(np.load(src))
    meta = json.loads(str(data["meta"]))
    for key, value in changes.items():
        if key == "meta_changes":
            data["meta"] = np.array(json.dumps({**meta, **value}))
        elif value is None:
            data.pop(key)
        else:
            data[key] = value(data[key]) if callable(value) else value
    np.savez(dst, **data)


CORRUPT = {
    "no kappa_v": dict(kappa_v=None),
    "no meta": dict(meta=None),
    "short u_v": dict(u_v=lambda a: a[:-1]),
    "short u": dict(u_x=lambda a: a[:-1], u_v=lambda a: a[:-1]),   # found against the mesh
    "moved nodes": dict(u_x=lambda a: a + 0.01),
    "meta a list": dict(meta=np.array("[1, 2]")),
    "meta not JSON": dict(meta=np.array("{n: 1")),
    "n a string": dict(meta_changes={"n": "1"}),
    "n off the grid": dict(meta_changes={"n": 2}),
    "steps not records": dict(meta_changes={"steps": [1]}),
    "stepper missing": dict(meta_changes={"stepper": None}),
    "memory for a case without": dict(meta_changes={"memory": {"t_prev": [], "k": []}}),
    "u not finite": dict(u_v=lambda a: np.full_like(a, np.nan)),
    "u integers": dict(u_v=lambda a: a.astype(np.int64)),
    "u flat": dict(u_v=lambda a: a.reshape(-1)),
    "kappa two columns": dict(kappa_v=lambda a: np.hstack([a, a])),
    "sigma strings": dict(sigma_v=lambda a: a.astype(str)),
}


@pytest.mark.parametrize("name", sorted(CORRUPT))
def test_corrupt_checkpoint_is_one_error_line(checkpoint, tmp_path, name):
    bad = tmp_path / "bad.npz"
    _variant(checkpoint, bad, **CORRUPT[name])
    proc = _cli(["run", PAPER_CASE, *TINY, "--out", tmp_path / "re", "--no-plots", "--quiet",
                 "--restart", bad])
    line = _one_error_line(proc)
    assert line.startswith(f"vpcontact: error: --restart: {bad} is not a readable checkpoint: ")
    assert line.count("is not a readable checkpoint") == 1
    assert not (tmp_path / "re" / "solution.xdmf").exists()


def test_garbage_checkpoint_is_one_error_line(tmp_path):
    bad = tmp_path / "checkpoint_000001.npz"
    bad.write_bytes(b"PK\x03\x04 truncated")
    line = _one_error_line(_cli(["run", PAPER_CASE, *TINY, "--out", tmp_path / "re",
                                 "--restart", bad]))
    assert "is not a readable checkpoint" in line


def test_short_checkpoint_under_mpi_stops_every_rank(checkpoint, tmp_path):
    bad = tmp_path / "bad.npz"
    _variant(checkpoint, bad, **CORRUPT["short u"])
    proc = _cli(["run", PAPER_CASE, *TINY, "--out", tmp_path / "re", "--no-plots", "--quiet",
                 "--restart", bad], nprocs=2)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.count("is not a readable checkpoint") == 1


# ------------------------------------------------------------------ bench
def test_bench_refuses_bad_input_before_running(tmp_path, blocker):
    cases = [(["bench", tmp_path / "missing.yaml"], "missing.yaml"),
             (["bench", "--out", blocker / "b"], "--out"),
             (["bench", "--out", blocker], "--out"),
             (["bench", "--levels", "5000"], "--levels: 5000 is out of range (allowed: 1 to "
                                             "4096)")]
    for args, named in cases:
        if "--out" not in args:
            args += ["--out", tmp_path / "b"]
        line = _one_error_line(_cli(args))
        assert named in line, line
    assert not (tmp_path / "b").exists()


@pytest.mark.parametrize("kwargs, option", [
    (dict(levels=[0]), "--levels"), (dict(levels=[-3]), "--levels"),
    (dict(levels=[2.5]), "--levels"), (dict(levels=[], extra=[]), "--levels"),
    (dict(extra=[(4, 0)]), "--extra"), (dict(extra=["foo"]), "--extra"),
    (dict(nprocs=[0]), "--ranks"), (dict(nprocs=[]), "--ranks"),
    (dict(repeat=0), "--repeat"), (dict(memory_steps=[0]), "--memory-steps"),
    (dict(nprocs=[1, 99999]), "--ranks 99999: more ranks than the"),
    (dict(repeat=99999999999), r"--repeat: 99999999999 is not allowed \(allowed: 1 to 100\)")])
def test_bench_arguments_are_checked_by_the_library(kwargs, option):
    from vpcontact.io.errors import CaseError
    from vpcontact.studies import bench
    args = dict(levels=[4], extra=[], nprocs=[1], repeat=1, memory_steps=[])
    args.update(kwargs)
    with pytest.raises(CaseError, match=f"^{option}"):
        bench.check_arguments(PAPER_CASE, **args)
    if option != "--memory-steps":    # bench() itself refuses too, before running anything
        with pytest.raises(CaseError, match=f"^{option}"):
            bench.bench(PAPER_CASE, None, args["levels"], nprocs=args["nprocs"],
                        extra=args["extra"], repeat=args["repeat"])


def test_bench_fast_solver_impossible_is_refused(tmp_path):
    from vpcontact.case import CaseError, load_raw
    from vpcontact.studies import bench
    raw = load_raw(PAPER_CASE)
    raw.setdefault("time", {})["scheme"] = "implicit"
    case = tmp_path / "implicit.yaml"
    case.write_text(json.dumps(raw))             # YAML reads JSON
    with pytest.raises(CaseError, match="fast"):
        bench.check_arguments(case, [4], [], [1], 1, [])


def test_bench_with_failed_configurations_exits_1(tmp_path, monkeypatch, capsys):
    from vpcontact.cli.commands import cmd_bench
    from vpcontact.cli.parser import build_parser
    from vpcontact.studies import bench
    monkeypatch.setattr(bench, "bench", lambda *a, **k: [
        {"n": 4, "h": 0.25, "N": 4, "method": "fast", "nprocs": 1, "failed": "boom"}])
    args = build_parser().parse_args(["bench", "--levels", "4", "--extra", "--ranks", "1",
                                      "--repeat", "1", "--memory-steps", "--scene-n", "0",
                                      "--box3d-levels", "--out", str(tmp_path / "b")])
    assert cmd_bench(args) == 1
    err = capsys.readouterr().err
    assert "1 bench configuration(s) failed: h = 1/4, N = 4, fast, 1 rank(s)" in err
    assert "failed: boom" in (tmp_path / "b" / "bench.md").read_text()


# ------------------------------------------------------------------ convergence
def test_convergence_cache_dir_checked_first(tmp_path, blocker):
    for cache in (blocker, blocker / "sub"):
        proc = _cli(["convergence", PAPER_CASE, "--levels", "2", "--reference", "4",
                     "--out", tmp_path / "c", "--cache-dir", cache])
        line = _one_error_line(proc)
        assert line.startswith(f"vpcontact: error: --cache-dir {cache}: not a writable")
        assert "reference run" not in proc.stdout
    assert not (tmp_path / "c" / "convergence.csv").exists()


@pytest.mark.parametrize("deltas", [[float("nan")], [0.0], [-1e-3], [float("inf")], [],
                                    [1e-3, 1e-3], [1e-4, 1e-3, 0.001]])
def test_convergence_deltas_checked_by_the_library(deltas):
    from vpcontact.io.errors import CaseError
    from vpcontact.studies.convergence import plan_runs
    with pytest.raises(CaseError, match="^--deltas"):
        plan_runs([2], 4, "both", None, deltas)


def test_convergence_plan_validates_every_run():
    from conftest import make_case
    from vpcontact.io.errors import CaseError
    from vpcontact.studies.convergence import plan_runs
    with pytest.raises(CaseError, match="mesh.n"):
        plan_runs([8], 8192, "both", make_case())


# ------------------------------------------------------------------ stability
@pytest.mark.parametrize("n, steps, option", [(0, 8, "--n"), (-3, 8, "--n"),
                                               (8, 0, "--steps"), (True, 8, "--n")])
def test_stability_refuses_bad_n_and_steps(n, steps, option):
    from mpi4py import MPI

    from conftest import paper_raw
    from vpcontact.io.errors import CaseError
    from vpcontact.studies import stability
    with pytest.raises(CaseError, match=f"^{option}: .* \\(allowed: positive integers\\)"):
        stability.sweep(paper_raw(), MPI.COMM_WORLD, {}, n, steps)


def test_stability_sweep_of_only_invalid_variants_is_an_error():
    from mpi4py import MPI

    from conftest import paper_raw
    from vpcontact.io.errors import CaseError
    from vpcontact.studies import stability
    bad = [stability.Variant("material", "E < 0", {"material.E": -1.0})]
    with pytest.raises(CaseError, match="no variant of the stability sweep"):
        stability.sweep(paper_raw(), MPI.COMM_WORLD, {}, 4, 2, variants=bad)


def test_damaged_run_cache_entries_are_recomputed(tmp_path):
    from vpcontact.studies import runcache
    cache = tmp_path / "cache"
    args = ["convergence", PAPER_CASE, "--levels", "2", "--reference", "4", "--out",
            tmp_path / "c", "--overwrite", "--cache-dir", cache]
    assert _cli(args).returncode == 0
    entries = sorted(cache.glob("run-*.h5"))
    assert len(entries) == 2
    entries[0].write_bytes(entries[0].read_bytes()[:300])          # truncated
    entries[1].write_bytes(b"")                                      # empty
    proc = _cli(args)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.count("is not usable") == 2 and "Traceback" not in proc.stderr
    for entry in entries:
        runcache.load(entry)                                         # written again
    proc = _cli(args)
    assert proc.stdout.count("from the cache") == 2 and "is not usable" not in proc.stdout


# ------------------------------------------------------------------ a real full disk (tmpfs)
@pytest.fixture
def small_disk(tmp_path):
    """mount(kb): a tmpfs of kb kilobytes (needs root: skipped otherwise), unmounted after."""
    mounted = []

    def mount(kb):
        d = tmp_path / f"disk{kb}"
        d.mkdir()
        if subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={kb}k", "tmpfs", str(d)],
                          capture_output=True).returncode:
            pytest.skip("mounting a tmpfs needs root")
        mounted.append(d)
        return d
    yield mount
    for d in mounted:
        subprocess.run(["umount", str(d)], capture_output=True)


@pytest.mark.parametrize("nprocs", [1, 2])
def test_a_full_disk_fails_the_run_with_a_summary_that_says_so(small_disk, nprocs):
    """1000 kB hold the paper case's outputs up to step ~4 of 16 (its seven fields, 146 kB
    a step, and the margin check_space keeps): the fields' write fails,
    the run stops with exit 1, one error line, and summary.json says failed (before: no
    summary.json, only the log's 'summary.json not written'; under mpirun -n 2 the ranks
    hung in parallel HDF5's collectives for ever)."""
    out = small_disk(1000) / "out"
    try:
        proc = _cli(["run", PAPER_CASE, "--out", out, "--no-plots", "--quiet"],
                    nprocs=nprocs, timeout=180)
    except subprocess.TimeoutExpired:
        pytest.fail("the run hung on the full disk")
    assert proc.returncode == 1, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr
    errors = [ln for ln in proc.stderr.splitlines() if ln.startswith("vpcontact: error:")]
    assert len(errors) == 1 and "No space left on device" in errors[0], proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed", summary["status"]
    assert "No space left on device" in summary["failure"]["reason"]
    assert 0 < summary["last_good_step"] < 16
    assert not list(out.glob(".summary.json.tmp*"))


def test_contact_h5_filling_the_disk_is_an_output_error_not_a_crash(small_disk):
    """contact.h5 is written with h5py: on a full disk h5py raised a RuntimeError (an
    internal error) and its half-closed file crashed the process at its exit (segmentation
    fault, exit 139).  Now an OutputError (ENOSPC) naming the file, nothing printed, exit 0
    (app/io/h5files.py)."""
    disk = small_disk(64)
    code = ("import numpy as np\n"
            "from mpi4py import MPI\n"
            "from vpcontact.io.contact_xdmf import ContactWriter\n"
            "from vpcontact.io.output import OutputError\n"
            "x = np.linspace(0.0, 1.0, 9)\n"
            "facets = np.zeros((8, 2, 3))\n"
            "facets[:, 0, 0], facets[:, 1, 0] = x[:-1], x[1:]\n"
            f"w = ContactWriter(MPI.COMM_WORLD, {str(disk / 'contact.xdmf')!r}, facets, 2)\n"
            "for n in range(100000):\n"
            "    try:\n"
            "        w.write(0.01 * n, {'x': x, 'y': 0 * x, 'u_x': 0 * x + n, 'u_y': 0 * x,\n"
            "                           'u_nu': 0 * x, 'state': np.array(['separated'] * 9)})\n"
            "    except OutputError as exc:\n"
            "        print(exc)\n"
            "        break\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip() in (f"{disk / 'contact.h5'}: No space left on device",
                                   f"{disk / 'contact.xdmf'}: No space left on device")
    assert proc.stderr == ""
