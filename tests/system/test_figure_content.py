"""What the figures draw, read from the objects drawn (matplotlib's Figure, pyvista's
plotters through tests/system/picture_probe.py), not from pixels: a figure shows only what
the scene has, states what it draws and has units.  The references are the results' own
files (solution.h5, contact.csv) read here with h5py and csv, and the cases' geometry."""
import csv
import json
import re
import shutil
import subprocess
import sys

import h5py
import numpy as np
import pytest

from conftest import ROOT, run_cli

CASES = ROOT / "cases"
CONTACT_FIGURES = ("fig2_laws.png", "fig3_deformed_contact.png", "fig4_tangential.png")


def _probe(out, factor=1.0, dim=2) -> dict:
    """What the pictures of ``out`` draw (picture_probe.py, a process without dolfinx)."""
    proc = subprocess.run([sys.executable, "-P", str(ROOT / "tests/system/picture_probe.py"),
                           str(out), str(factor), str(dim)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _last(out, name) -> np.ndarray:
    """A field's values at the last output time, read from solution.h5."""
    with h5py.File(out / "solution.h5", "r") as f:
        group = f["Function"][name]
        return group[max(group, key=lambda k: float(k.replace("_", ".")))][...]


def _figure(monkeypatch, draw, *args, **kwargs):
    """The matplotlib Figure a line figure function draws (linefigures._save records it,
    lays it out and draws it, but closes nothing)."""
    from vpcontact.post import linefigures
    kept = {}

    def record(plt, fig, path, title=None):
        if title:
            wrap = getattr(linefigures, "wrap", lambda text, width: text)   # ae4aeab: none
            fig.suptitle(wrap(title, fig.get_figwidth()), fontsize=10)
        fig.tight_layout()
        fig.canvas.draw()
        kept["fig"] = fig
    monkeypatch.setattr(linefigures, "_save", record)
    draw(*args, **kwargs)
    return kept["fig"]


@pytest.fixture(scope="module")
def paper(paper_cli_run, tmp_path_factory):
    """A copy of the paper case's run (h = k = 1/16, figures drawn)."""
    out = tmp_path_factory.mktemp("content") / "paper"
    shutil.copytree(paper_cli_run[0], out)
    return out


@pytest.fixture(scope="module")
def norton(tmp_path_factory):
    """cases/norton_relaxation.yaml, two steps, figures drawn: a homogeneous stress and no
    contact boundary (boundaries.contact: [])."""
    out = tmp_path_factory.mktemp("content") / "norton"
    proc = run_cli(["run", CASES / "norton_relaxation.yaml", "--out", out, "--set",
                    "time.N=2", "--quiet"], plots=True)
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.fixture(scope="module")
def cylinders(tmp_path_factory):
    """cases/two_cylinders.yaml in one step (no figures): two bodies, the contact surface
    upper_arc on the upper cylinder, its target lower_arc on the lower one below."""
    out = tmp_path_factory.mktemp("content") / "cylinders"
    proc = run_cli(["run", CASES / "two_cylinders.yaml", "--out", out, "--set", "time.N=1",
                    "--quiet"])
    assert proc.returncode == 0, proc.stderr
    return out


def test_colour_bars_span_the_whole_field_with_units(paper):
    """body.png and fig5 colour the stress and kappa from their smallest to their largest
    value (the bar ended at the 99.5th percentile, 12.1 for a largest 23.2, unsaid), each
    bar titled with its unit."""
    drawn = _probe(paper, 2.0)
    vm, kappa = _last(paper, "sigma_vm"), _last(paper, "kappa")
    assert drawn["body.png"]["bars"] == {
        "von Mises stress [N/m^2]": pytest.approx([vm.min(), vm.max()], rel=1e-12)}
    assert drawn["fig5_vm_kappa.png"]["bars"] == {
        "von Mises stress [N/m^2]": pytest.approx([vm.min(), vm.max()], rel=1e-12),
        "kappa [N/m^2]": pytest.approx([kappa.min(), kappa.max()], rel=1e-12)}
    assert vm.max() > 1.5 * np.percentile(vm, 99.5)     # a range a percentile would cut


CHAR_EM = 0.6      # a digit's width / the font size (DejaVu Sans 0.64, Arial 0.56)


def test_colour_bar_labels_do_not_overlap(paper):
    """Each colour bar's labels, as VTK formats them at their font size, fit side by side
    in the bar's width (fig5's half-width bars had five labels of up to six characters at
    18 px on 250 px: 0.0170 0.0520 ... overlapped)."""
    drawn = _probe(paper, 2.0)
    for name in ("body.png", "fig5_vm_kappa.png"):
        for title, bar in drawn[name]["labels"].items():
            fmt = bar["format"]
            text = [(fmt.format(v) if "{" in fmt else fmt % v).strip()
                    for v in np.linspace(*bar["range"], bar["n"])]
            needed = (sum(map(len, text)) + len(text) - 1) * CHAR_EM * bar["font_px"]
            assert needed <= bar["width_px"], (name, title, text, bar["width_px"])


def test_a_uniform_field_is_one_colour_with_its_value(norton):
    """The Norton bar's stress and creep strain are homogeneous (equal to rounding): one
    colour each, no colour bar, the value in the title (they were split into two colours
    on a bar from 19.3104 to 19.3104)."""
    drawn = _probe(norton)
    vm, p = _last(norton, "sigma_vm"), _last(norton, "p")
    assert np.ptp(vm) <= 1e-12 * vm.max() and np.ptp(p) <= 1e-12 * p.max()
    for name in ("body.png", "fig5_vm_kappa.png"):
        assert drawn[name]["bars"] == {} and drawn[name]["coloured"] == [], name
    texts = " ".join(drawn["fig5_vm_kappa.png"]["texts"])
    assert f"von Mises stress uniform: {vm.mean():.4g} N/m^2" in texts
    assert f"accumulated viscoplastic strain p uniform: {p.mean():.4g}" in texts
    assert f"uniform: {vm.mean():.4g} N/m^2" in drawn["body.png"]["texts"][0]


def test_no_contact_figures_without_a_contact_boundary(norton):
    """A scene without a contact boundary gets no contact figures (fig2, fig3, fig4 were
    drawn with an empty contact), and body.png names no Gamma3."""
    assert not (norton / "contact.csv").exists()
    written = {f.name for f in norton.glob("*.png")}
    assert written == {"body.png", "fig5_vm_kappa.png", "history.png", "forces.png"}
    assert "Gamma3" not in " ".join(_probe(norton)["body.png"]["texts"])
    proc = run_cli(["plot", norton])
    assert proc.returncode == 0, proc.stderr
    assert "body.png: displacement magnified" in proc.stdout + proc.stderr
    assert "fig3" not in proc.stdout + proc.stderr


def test_no_fig3_fig4_without_contact_forces(paper, tmp_path):
    """A contact boundary without a node in contact (all separated) keeps the laws (fig2)
    but draws no contact forces along it; plot removes the earlier ones."""
    from vpcontact.post.linefigures import LINE_FIGURES, draw_line_figures
    out = tmp_path / "apart"
    shutil.copytree(paper, out)
    with open(paper / "contact.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    for r in rows:
        r.update(state="separated", neg_sigma_nu="0.0", neg_sigma_tau="0.0")
    with open(out / "contact.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    written = {f.name for f in draw_line_figures(out, LINE_FIGURES, 1.0)}
    assert written == {"fig2_laws.png", "history.png", "forces.png"}
    assert not (out / "fig3_deformed_contact.png").exists()
    assert not (out / "fig4_tangential.png").exists()
    assert all((paper / name).exists() for name in CONTACT_FIGURES)


def _from_nodes(bars, x, y) -> np.ndarray:
    """The bars (x, y0, y1) turned to start at the node (x[i], y[i]) they stand on."""
    out = []
    for bx, y0, y1 in bars:
        d0, d1 = (np.min(np.hypot(x - bx, y - yy)) for yy in (y0, y1))
        out.append((bx, y0, y1) if d0 <= d1 else (bx, y1, y0))
    return np.array(out)


def _bars(fig):
    """fig3's force bars (vertical segments: x, y at one end, y at the other) and its
    scale bar (its segment, its value from its label)."""
    from matplotlib.collections import LineCollection

    from vpcontact.post import linefigures
    gid = getattr(linefigures, "FORCE_SCALE", "force_scale")     # ae4aeab: no scale bar
    ax = fig.axes[0]
    bars, scale = [], None
    for coll in ax.collections:
        if not isinstance(coll, LineCollection) or not coll.get_label().startswith(
                ("-sigma_nu", "scale")):
            continue
        segs = [np.asarray(s) for s in coll.get_segments()]
        if coll.get_gid() == gid:
            scale = segs[0]
        else:
            bars += [(s[0, 0], s[0, 1], s[1, 1]) for s in segs]
    label = [t.get_text() for t in ax.texts if t.get_gid() == gid]
    return np.array(bars), scale, label


def test_fig3_force_bars_have_a_scale(paper, monkeypatch):
    """fig3's force bars come with a scale bar of a stated value in N/m^2, and a node's bar
    is as long as its force in that scale (contact.csv's -sigma_nu, compliance nodes)."""
    from vpcontact.post.linefigures import fig3_deformed_contact
    from vpcontact.post.results import Results
    res = Results(paper)
    fig = _figure(monkeypatch, fig3_deformed_contact, res, paper / "f.png", factor=2.0)
    bars, scale, label = _bars(fig)
    assert scale is not None and len(label) == 1
    value = float(re.fullmatch(r"\s*([0-9.eE+-]+) N/m\^2", label[0]).group(1))
    per_force = abs(scale[1, 1] - scale[0, 1]) / value
    c = res.contact
    bars = _from_nodes(bars, c["x"] + 2.0 * c["u_x"], c["y"] + 2.0 * c["u_y"])
    m = c["state"] == "compliance"
    xb, yb = c["x"][m] + 2.0 * c["u_x"][m], c["y"][m] + 2.0 * c["u_y"][m]
    for x, y, f in zip(xb, yb, c["neg_sigma_nu"][m]):
        bar = bars[np.argmin(np.hypot(bars[:, 0] - x, bars[:, 1] - y))]
        assert bar[2] - bar[1] == pytest.approx(-per_force * f, rel=1e-9)   # below Gamma3
    assert any("N/m^2" in t.get_text() for t in fig.axes[0].get_legend().get_texts())


def test_two_body_bars_stay_off_the_other_body(cylinders, monkeypatch):
    """With two bodies the bars rise from the contact surface upper_arc into the upper
    cylinder, its own side (they were drawn down across the lower cylinder)."""
    from vpcontact.post.linefigures import fig3_deformed_contact
    from vpcontact.post.results import Results
    res = Results(cylinders)
    fig = _figure(monkeypatch, fig3_deformed_contact, res, cylinders / "f.png")
    bars, scale, _ = _bars(fig)
    c = res.contact
    bars = _from_nodes(bars, c["x"] + c["u_x"], c["y"] + c["u_y"])    # true scale
    length = bars[:, 2] - bars[:, 1]
    touching = bars[np.abs(length) > 1e-6 * np.abs(length).max()]   # separated: rounding
    assert len(touching) >= 10 and np.all(touching[:, 2] > touching[:, 1])
    assert scale is not None and scale[1, 1] > scale[0, 1]


def test_3d_fig3_title_says_what_is_drawn(tmp_path, monkeypatch):
    """box3d's fig3 draws Gamma3's facets, no forces: its title does not say "contact
    forces" but names the picture that has the pressure, whose bar has its unit."""
    from vpcontact.post.linefigures import fig3_deformed_contact
    from vpcontact.post.results import Results
    out = tmp_path / "box"
    proc = run_cli(["run", CASES / "box3d.yaml", "--out", out, "--set", "mesh.n=2", "--set",
                    "time.N=1", "--quiet"])
    assert proc.returncode == 0, proc.stderr
    fig = _figure(monkeypatch, fig3_deformed_contact, Results(out), out / "f.png")
    bars = _probe(out, 1.0, 3)["contact_pressure.png"]["bars"]
    assert list(bars) == ["contact pressure -sigma_nu [N/m^2]"]      # with its unit
    title = fig.axes[0].get_title()
    assert "contact forces" not in title and "contact_pressure.png" in title
    assert not fig.axes[0].collections or all(
        not c.get_label().startswith("-sigma_nu") for c in fig.axes[0].collections)


def test_long_titles_stay_inside_the_figure(paper, monkeypatch):
    """fig4's title with mindlin's pair names (cut at both sides) is wrapped: every text
    of the figure lies inside it."""
    from vpcontact.post.linefigures import fig4_tangential
    from vpcontact.post.results import Results
    res = Results(paper)
    res.case = {**res.case, "contact": {**res.case["contact"], "pairs": [
        {"surface": "cylinder_arc", "target": "block_top_contact"}]}}
    fig = _figure(monkeypatch, fig4_tangential, res, paper / "f.png")
    renderer = fig.canvas.get_renderer()
    width, height = fig.canvas.get_width_height()
    texts = [fig._suptitle] + [t for ax in fig.axes for t in ax.texts]
    assert "block_top_contact" in fig._suptitle.get_text()
    for text in texts:
        box = text.get_window_extent(renderer)
        assert box.x0 >= 0 and box.x1 <= width and box.y1 <= height, text.get_text()


def test_history_names_both_axes_of_the_norms(paper, monkeypatch):
    """history.png's norms panel has two y-axes: one legend names both curves and their
    axes; the quantities have their units (Perzyna's kappa is a stress)."""
    from vpcontact.post.linefigures import history
    from vpcontact.post.results import Results
    fig = _figure(monkeypatch, history, Results(paper), paper / "f.png")
    legend = fig.axes[0].get_legend()
    assert legend is not None
    labels = [t.get_text() for t in legend.get_texts()]
    assert labels == ["||u||_V (left axis)", "||sigma||_Q (right axis)"]
    units = [fig.axes[0].get_ylabel(), fig.axes[-1].get_ylabel(), fig.axes[1].get_title(),
             fig.axes[2].get_title()]               # 2D: L2 norms over an area, in m
    assert units == ["||u||_V = ||eps(u)||_L2 [m]", "||sigma||_Q [N/m^2 x m]",
                     "max ||sigma||_VM [N/m^2]", "max kappa [N/m^2]"]


def test_forces_do_not_magnify_rounding(norton, monkeypatch):
    """The Norton bar's vertical reactions are rounding (1e-15 of the 40 N/m pull): their
    axis spans at least 1e-9 of the largest force, so they are drawn flat (they filled the
    axis as noise)."""
    from vpcontact.post.linefigures import forces
    from vpcontact.post.results import Results
    steps = json.loads((norton / "summary.json").read_text())["steps"]
    top = max(abs(v) for s in steps for r in s["reactions"].values() for v in r)
    fy = [r[1] for s in steps for r in s["reactions"].values()]
    assert max(map(abs, fy)) < 1e-12 * top
    fig = _figure(monkeypatch, forces, Results(norton), norton / "f.png")
    low, high = fig.axes[1].get_ylim()
    assert low <= -1e-9 * top and high >= 1e-9 * top


ANIMATION_SCALE = """
import json, sys
from pathlib import Path
from vpcontact.post import pictures
solution = pictures.Dataset(Path(sys.argv[1]) / "solution.xdmf")
if hasattr(pictures, "animation_scale"):
    scale = pictures.animation_scale(solution, solution.times)
    print(json.dumps([scale.low, scale.high]))
else:                                                   # ae4aeab
    print(json.dumps(list(pictures.animation_range(solution, solution.times))))
"""


def test_the_animation_colours_the_whole_range_of_all_times(paper):
    """animation.gif's one colour scale runs from the smallest to the largest von Mises
    stress of all output times (solution.h5: the largest, 32.7, is at the first step;
    the 99.5th percentile ended it lower)."""
    with h5py.File(paper / "solution.h5", "r") as f:
        vm = np.concatenate([f["Function/sigma_vm"][k][...].ravel()
                             for k in f["Function/sigma_vm"]])
    proc = subprocess.run([sys.executable, "-P", "-c", ANIMATION_SCALE, str(paper)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    low, high = json.loads(proc.stdout.strip().splitlines()[-1])
    assert [low, high] == pytest.approx([vm.min(), vm.max()], rel=1e-12)
