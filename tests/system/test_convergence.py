"""The convergence command: end to end on a cheap configuration (levels 4, 8 vs 16), rates
from the printed errors, the run cache (hit / miss), serial == mpirun -n 2, bad input."""
import csv
import math

import pytest

from conftest import PAPER_CASE, run_cli

CHEAP = ["--levels", "4", "8", "--reference", "16"]


def _rows(out):
    return list(csv.DictReader(open(out / "convergence.csv")))


@pytest.fixture(scope="module")
def first(tmp_path_factory):
    base = tmp_path_factory.mktemp("conv")
    out, cache = base / "out", base / "cache"
    proc = run_cli(["convergence", PAPER_CASE, *CHEAP, "--out", out, "--cache-dir", cache,
                    "--deltas", "1e-7", "1e-2"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return base, out, cache, proc


def test_end_to_end_and_rates_from_printed_errors(first):
    base, out, cache, proc = first
    for name in ("convergence.csv", "convergence.md", "convergence.png"):
        assert (out / name).stat().st_size > 0
    assert (out / "convergence.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = _rows(out)
    assert [(r["delta"], r["level"]) for r in rows] == [
        ("1e-07", "4"), ("1e-07", "8"), ("0.01", "4"), ("0.01", "8")]
    for r in rows:
        err = float(r["error"])
        parts = float(r["e_sigma"]) + float(r["e_u"]) + float(r["e_kappa"])
        assert err == pytest.approx(parts, rel=1e-9) and err > 0
        assert int(r["steps"]) == int(r["level"]) and float(r["solve_s"]) > 0
        assert r["cached"] == "False"
    for a, b in ((rows[0], rows[1]), (rows[2], rows[3])):
        assert a["rate"] == ""
        expected = math.log(float(a["error"]) / float(b["error"])) / math.log(
            float(a["h"]) / float(b["h"]))
        assert float(b["rate"]) == pytest.approx(expected, rel=1e-12)
    md = (out / "convergence.md").read_text()
    assert "| 1/8 | 1/8 | 162 | 8 |" in md and "delta = 0.01" in md
    assert "paper Error" not in md   # Table 1 applies only to 8..64 against 128


def test_cache_hit_then_miss(first):
    base, out, cache, _ = first
    before = _rows(out)
    proc = run_cli(["convergence", PAPER_CASE, *CHEAP, "--out", base / "out2",
                    "--cache-dir", cache, "--deltas", "1e-7", "1e-2"])
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.count("from the cache") == 5 and "Newton iterations" not in proc.stdout
    again = _rows(base / "out2")
    assert all(r["cached"] == "True" for r in again)
    assert [r["error"] for r in again] == [r["error"] for r in before]
    # a changed case misses the cache (every run is solved again)
    proc = run_cli(["convergence", PAPER_CASE, *CHEAP, "--out", base / "out3",
                    "--cache-dir", cache, "--set", "contact.g=0.011"])
    assert proc.returncode == 0, proc.stderr
    assert "from the cache" not in proc.stdout
    assert all(r["cached"] == "False" for r in _rows(base / "out3"))
    # --no-cache recomputes although the cache holds the runs
    proc = run_cli(["convergence", PAPER_CASE, *CHEAP, "--out", base / "out4",
                    "--cache-dir", cache, "--no-cache"])
    assert proc.returncode == 0 and "from the cache" not in proc.stdout


@pytest.mark.mpi
def test_two_ranks_give_the_same_errors(first, tmp_path):
    base, out, cache, _ = first
    proc = run_cli(["convergence", PAPER_CASE, *CHEAP, "--out", tmp_path / "np2",
                    "--no-cache", "--deltas", "1e-7", "1e-2"], nprocs=2)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    for a, b in zip(_rows(out), _rows(tmp_path / "np2"), strict=True):
        for key in ("error", "e_sigma", "e_u", "e_kappa"):
            assert float(b[key]) == pytest.approx(float(a[key]), rel=1e-8), key
        assert a["n_max"] == b["n_max"]


@pytest.mark.parametrize("args,pattern", [
    (["--levels", "3", "8", "--reference", "16"], "divide the reference"),
    (["--levels", "8", "4", "--reference", "16"], "increase strictly"),
    (["--levels", "4", "--reference", "16", "--set", "mesh.kind=unstructured",
      "--set", "mesh.h=0.1"], "nested meshes"),
])
def test_bad_study_input_exits_2(tmp_path, args, pattern):
    proc = run_cli(["convergence", PAPER_CASE, *args, "--out", tmp_path / "o", "--no-cache"])
    assert proc.returncode == 2 and pattern in proc.stderr, proc.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("errors", [(3.8, 5.5), (1e-4, 2e-2)], ids=["within-a-decade", "decades"])
def test_convergence_figure_labels_both_log_axes(errors):
    """convergence.png: the Error axes carry tick labels (the left panel had none when the
    errors spanned less than a decade), and no labelled minor ticks crowd the time axis."""
    from vpcontact.studies.convergence import convergence_figure
    rows = [{"delta": 1e-7, "h": h, "k": h, "error": e, "solve_s": s}
            for h, e, s in ((0.5, errors[0], 0.021), (1.0, errors[1], 0.014))]
    fig = convergence_figure({"vary": "h", "deltas": [1e-7], "rows": rows, "paper": False,
                              "reference_level": 4})
    fig.canvas.draw()
    for ax, axis in ((fig.axes[0], "y"), (fig.axes[1], "y"), (fig.axes[1], "x")):
        lo, hi = sorted(getattr(ax, f"get_{axis}lim")())
        ticks = getattr(ax, f"get_{axis}ticks")()
        shown = [t for t in ticks if lo <= t <= hi]
        assert 2 <= len(shown) <= 12, (axis, shown)


def test_a_case_without_contact(tmp_path):
    """A body without Gamma3 (Norton's relaxation bar: no contact group, no contact table at
    T) is studied like any other: it crashed on the missing contact table before."""
    proc = run_cli(["convergence", "cases/norton_relaxation.yaml", "--vary", "k", "--levels",
                    "10", "20", "--reference", "40", "--out", tmp_path / "o", "--no-cache"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = _rows(tmp_path / "o")
    assert [r["N"] for r in rows] == ["10", "20"]
    assert all(0 < float(r["e_kappa"]) < float(r["error"]) < 10 for r in rows)
