"""The figures of a run, the progress bar, check (dry run) and info."""
import shutil
import struct

import numpy as np
import pytest

from conftest import PAPER_CASE, ROOT, run_cli

FIGURES = ("fig3_deformed_contact.png", "fig4_tangential.png", "fig5_vm_kappa.png",
           "fig2_laws.png", "history.png", "forces.png", "body.png")


def _png(path):
    """(width, height, pixels) of a PNG, checking its signature and header."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    width, height = struct.unpack(">II", data[16:24])
    import matplotlib.image as mpimg
    return width, height, mpimg.imread(path)


@pytest.fixture(scope="module")
def paper_out(paper_cli_run, tmp_path_factory):
    """A copy of the paper case's run (conftest.paper_cli_run): these tests delete, redraw
    and add figures."""
    run, proc = paper_cli_run
    assert "figures" in proc.stdout
    # the progress bar (not a terminal: a line per 10% of the time interval) on stderr
    assert "100.0%" in proc.stderr and "ETA" in proc.stderr and "step 16/16" in proc.stderr
    out = tmp_path_factory.mktemp("plots") / "paper"
    shutil.copytree(run, out)
    return out


@pytest.mark.parametrize("name", FIGURES)
def test_figure_is_a_nonblank_png(paper_out, name):
    w, h, px = _png(paper_out / name)
    assert 500 <= w <= 2000 and 400 <= h <= 1500, (w, h)
    assert px.shape[:2] == (h, w)
    assert px[..., :3].std() > 0.05, f"{name} looks blank"


def test_deformed_mesh_differs_from_undeformed(paper_out, tmp_path):
    from vpcontact.post.linefigures import fig3_deformed_contact
    from vpcontact.post.results import Results
    res = Results(paper_out)
    f0 = fig3_deformed_contact(res, tmp_path / "undeformed.png", factor=0.0)
    f1 = fig3_deformed_contact(res, tmp_path / "deformed.png")
    assert f0 == 0.0 and f1 >= 1.0
    a, b = _png(tmp_path / "undeformed.png")[2], _png(tmp_path / "deformed.png")[2]
    assert a.shape == b.shape and np.abs(a - b).mean() > 1e-3


def test_fig3_shows_the_bound_as_c_nu_g(paper_out):
    """The paper's convention: where u_nu = g the bar is c_nu g; the figure's data say so."""
    from vpcontact.post.results import Results
    res = Results(paper_out)
    c = res.contact
    assert set(c["state"]) <= {"bound", "compliance", "separated"}
    assert (c["state"] == "bound").sum() == 10 and (c["state"] == "compliance").sum() == 6


def test_plot_command_redraws_and_rejects_a_non_results_dir(paper_out, tmp_path):
    for name in FIGURES:
        (paper_out / name).unlink()
    proc = run_cli(["plot", paper_out])
    assert proc.returncode == 0, proc.stderr
    assert all((paper_out / name).is_file() for name in FIGURES)
    proc = run_cli(["plot", tmp_path])
    assert proc.returncode == 2 and "not a results directory" in proc.stderr


def test_3d_figures(tmp_path):
    out = tmp_path / "box"
    proc = run_cli(["run", ROOT / "cases" / "box3d.yaml", "--out", out, "--set", "mesh.n=3",
                    "--set", "time.N=2"], plots=True)
    assert proc.returncode == 0, proc.stderr
    for name in FIGURES + ("contact_pressure.png",):
        w, h, px = _png(out / name)
        assert px[..., :3].std() > 0.05, name
    assert _colours(out / "contact_pressure.png") >= 64       # a pressure field, not a fill


def _colours(path):
    """The number of distinct RGB colours of a PNG."""
    px = (_png(path)[2][..., :3] * 255).round().astype(np.uint32)
    return len(np.unique(px[..., 0] << 16 | px[..., 1] << 8 | px[..., 2]))


def test_body_picture_is_the_paraview_recipe(paper_out, tmp_path):
    """body.png is what the README's ParaView recipe shows (Warp By Vector u, colour by
    sigma_vm, one dataset): a stress picture of many colours on the deformed body (not a
    uniform grey square), and the undeformed body (factor 0) differs from it."""
    import subprocess
    import sys

    from vpcontact.post import pictures
    assert _colours(paper_out / "body.png") >= 200
    out = tmp_path / "still"
    out.mkdir()
    for f in ("solution.xdmf", "solution.h5", "contact.xdmf", "contact.h5"):
        (out / f).write_bytes((paper_out / f).read_bytes())
    proc = subprocess.run([sys.executable, "-P", pictures.__file__, str(out), "--factor", "0",
                           "--dim", "2"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    a, b = _png(out / "body.png")[2], _png(paper_out / "body.png")[2]
    assert a.shape == b.shape and np.abs(a - b).mean() > 1e-3


def test_plot_animate_writes_a_frame_per_output_time(paper_out):
    from PIL import Image, ImageSequence
    proc = run_cli(["plot", paper_out, "--animate"])
    assert proc.returncode == 0, proc.stderr
    assert "animation.gif: 17 frames" in proc.stdout
    gif = Image.open(paper_out / "animation.gif")
    frames = [np.asarray(f.convert("RGB"), dtype=float) for f in ImageSequence.Iterator(gif)]
    assert len(frames) == 17                           # t_0 .. t_16, none merged as equal
    assert np.abs(frames[0] - frames[-1]).mean() > 1.0


def test_check_reports_without_writing(tmp_path):
    proc = run_cli(["check", PAPER_CASE], cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    assert "dofs: 578" in out and "512 cells" in out and "16 steps" in out
    assert "normal compliance" in out and "nonmonotone friction" in out
    assert "left out: memory term, slip dependence" in out
    assert "stability indicator" in out and "well-posedness" in out
    assert list(tmp_path.iterdir()) == []           # nothing written
    proc = run_cli(["check", PAPER_CASE, "--set", "material.nu=0.5"], cwd=tmp_path)
    assert proc.returncode == 2 and "material.nu" in proc.stderr


def test_info():
    proc = run_cli(["info"])
    assert proc.returncode == 0, proc.stderr
    assert "dolfinx 0.5.2" in proc.stdout and "PETSc 3." in proc.stdout
    assert "mumps" in proc.stdout and "MPI" in proc.stdout and "JIT cache" in proc.stdout


def test_fine_mesh_figure_draws_outlines(tmp_path):
    """Above MAX_DRAWN_CELLS the deformed mesh is drawn by its outline (not a block of
    lines); still deformed != undeformed."""
    from vpcontact.post.linefigures import MAX_DRAWN_CELLS, fig3_deformed_contact
    from vpcontact.post.results import Results
    out = tmp_path / "fine"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--set", "mesh.n=72", "--set",
                    "time.N=2", "--set", "solver.method=fast"])
    assert proc.returncode == 0, proc.stderr
    res = Results(out)
    assert len(res.cells) > MAX_DRAWN_CELLS
    fig3_deformed_contact(res, tmp_path / "a.png", factor=0.0)
    fig3_deformed_contact(res, tmp_path / "b.png")
    a, b = _png(tmp_path / "a.png")[2], _png(tmp_path / "b.png")[2]
    assert b[..., :3].std() > 0.05 and np.abs(a - b).mean() > 1e-3


def test_overwrite_removes_the_old_figures(tmp_path):
    """--overwrite replaces a whole earlier run: no stale figures stay behind."""
    out = tmp_path / "o"
    assert run_cli(["run", PAPER_CASE, "--out", out, "--set", "time.N=2"],
                   plots=True).returncode == 0
    assert all((out / f).exists() for f in FIGURES)
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--set", "time.N=2"])
    assert proc.returncode == 2 and "fig3_deformed_contact.png" in proc.stderr
    assert run_cli(["run", PAPER_CASE, "--out", out, "--set", "time.N=2",
                    "--overwrite"]).returncode == 0
    assert not any((out / f).exists() for f in FIGURES)


def test_failed_pictures_are_a_warning_and_the_line_figures_stay(paper_out, tmp_path):
    out = tmp_path / "broken"
    out.mkdir()
    for f in ("summary.json", "solution.h5", "contact.csv", "contact.xdmf", "contact.h5"):
        (out / f).write_bytes((paper_out / f).read_bytes())
    (out / "solution.xdmf").write_text("<Xdmf><Domain></Domain></Xdmf>\n")   # no dataset
    proc = run_cli(["plot", out])
    assert proc.returncode == 1
    said = proc.stdout + proc.stderr
    assert "pictures (pyvista) not drawn" in said and "history.png" in said
    assert (out / "history.png").is_file() and not (out / "body.png").exists()
