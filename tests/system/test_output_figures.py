"""The figures of a run are drawn by the two figure processes: the
run's process only hands out the jobs, so that a loaded machine does not hold the run's
process up for the line figures (it drew four of them itself: 1.1 s idle, 2.9 s loaded for
the 1/128 run)."""
import shutil

import pytest


@pytest.fixture(scope="module")
def results(tiny_run_dir, tmp_path_factory):
    """A copy of the run: these tests redraw and delete its figures."""
    out = tmp_path_factory.mktemp("figures") / "run"
    shutil.copytree(tiny_run_dir, out)
    return out


def test_the_runs_process_draws_no_figure(results, monkeypatch):
    from vpcontact.post import plot

    def here(*args, **kwargs):
        raise AssertionError("a line figure drawn in the run's process")
    monkeypatch.setattr(plot, "draw_line_figures", here)
    files = plot.plot_all(results)
    names = {f.name for f in files}
    assert names == set(plot.LINE_FIGURES) | {"body.png", "fig5_vm_kappa.png"}
    assert all((results / n).stat().st_size > 10_000 for n in names)


def test_a_failed_line_figure_process_leaves_them_to_the_runs_process(results, monkeypatch):
    """If the line figures' process dies, the line figures are drawn in this process."""
    from vpcontact.post import plot
    for name in plot.LINE_FIGURES:
        (results / name).unlink(missing_ok=True)
    painter = plot.Painter()
    painter.lines.kill()
    files = plot.plot_all(results, painter=painter)
    assert {f.name for f in files} >= set(plot.LINE_FIGURES)
    assert all((results / n).is_file() for n in plot.LINE_FIGURES)


def test_stopped_figure_processes_leave_no_temporary_files(results):
    """Ctrl-C while drawing stops the figure processes (SIGKILL): the temporary files they
    were writing (.animation.tmp.gif, ...) are removed."""
    from vpcontact.post import plot
    painter = plot.Painter()
    painter.draw(results, 1.0, 2, True)
    (results / ".animation.tmp.gif").write_bytes(b"GIF89a")   # as a killed writer leaves it
    painter.cancel()
    assert not list(results.glob(".*.tmp*"))
