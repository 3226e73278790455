"""Pictures of the body with pyvista (VTK), off-screen, from the files of a results
directory: solution.xdmf (one dataset: the mesh with u, sigma_vm, ... at every output time)
and contact.xdmf (the Gamma3 facets with the contact table), for any geometry, 2D or 3D.

- body.png: the deformed body at the last time (displacement magnified as in fig3),
  coloured by the von Mises stress, with the contact boundary Gamma3 drawn in black (where
  the scene has one);
- fig5_vm_kappa.png: the von Mises stress and kappa at the last time on the body (the
  paper's Fig. 5; in 3D the body clipped at mid y, its inside shown);
- contact_pressure.png (3D, a scene with contact forces): the contact pressure -sigma_nu
  on Gamma3, seen from the foundation;
- animation.gif (``plot --animate``): the deformed, coloured body at every output time.

Each field is coloured on its whole range with its unit, a uniform one in one colour with
its value (app/post/colourscale.py).

No display is needed: VTK renders through EGL (libEGL, Mesa) where no X display is set.

The pictures are drawn in a process of their own (``python -m vpcontact.post.pictures``, started by
app/post/plot.py, which also hands it some of the line figures; a second such process with
--no-pictures draws the other line figures meanwhile): VTK's wheel is built with
the old C++ string ABI, and in a process that has loaded dolfinx its std::regex code binds to
dolfinx's instantiations and aborts (std::bad_alloc as soon as a scalar bar is drawn;
observed).  This module, app/post/plot.py and linefigures.py import no dolfinx.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

from vpcontact.io.files import write_replacing
from vpcontact.post.colourscale import ColourScale, bar_title, colour_scale, uniform_note
from vpcontact.post.linefigures import draw_line_figures, pyplot
from vpcontact.post.results import contact_scene

PICTURES = ("body.png", "fig5_vm_kappa.png", "contact_pressure.png")
ANIMATION = "animation.gif"
WINDOW = (1000, 700)             # the pictures' pixels
FRAME = (800, 560)               # the animation's (render and GIF palette cost per pixel)


def _pyvista():
    """pyvista, set up for off-screen rendering (EGL when no X display)."""
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv
    pv.OFF_SCREEN = True
    return pv


class Dataset:
    """A one-dataset XDMF file (solution.xdmf, contact.xdmf) read with VTK.

    Args:
        path: the XDMF file.
    """

    def __init__(self, path: Path):
        self.reader = _pyvista().get_reader(str(path))
        self.times = list(self.reader.time_values)

    def at(self, t: float | None = None):
        """The dataset at time t (default: the last).

        Args:
            t: one of ``times``, or None.

        Returns:
            The pyvista UnstructuredGrid.
        """
        if self.times:
            self.reader.set_active_time_value(self.times[-1] if t is None else t)
        return self.reader.read()


def _moved_points(grid, factor: float) -> np.ndarray:
    """The grid's points (points, 3) moved by factor * u (NaN displacements count as 0)."""
    return np.asarray(grid.points) + factor * np.nan_to_num(np.asarray(grid.point_data["u"]))


def _deformed(grid, factor: float):
    """A copy of the grid (with point data u) moved by factor * u."""
    out = grid.copy()
    out.points = _moved_points(grid, factor)
    return out


BAR = {"color": "black", "vertical": False, "position_x": 0.2, "position_y": 0.02,
       "width": 0.6, "height": 0.08, "fmt": "%.3g", "n_labels": 5}
NARROW_BAR = {**BAR, "position_x": 0.1, "width": 0.8, "n_labels": 3}   # fig5's subplots
UNIFORM_COLOUR = "lightsteelblue"    # a uniform field: one colour, its value in the title


def _save(plotter, path: Path) -> None:
    """Render and write the PNG (PIL, zlib level 1: faster than the default 6;
    docs/performance.md, section 9)."""
    from PIL import Image
    Image.fromarray(plotter.screenshot(return_img=True)).save(path, compress_level=1)


def _view(plotter, dim: int, body=None, gamma3=None) -> None:
    """The camera: from +z, parallel projection in 2D; in 3D an oblique view from the side
    of Gamma3 (from below for a body on a foundation below it), else isometric."""
    if dim == 2:
        plotter.view_xy()
        plotter.enable_parallel_projection()
    elif body is not None and gamma3 is not None and gamma3.n_cells:
        n = _mean_normal(gamma3)
        n = n if n @ (np.asarray(gamma3.center) - np.asarray(body.center)) >= 0 else -n
        side = np.array([1.0, 1.0, 1.0]) - (np.array([1.0, 1.0, 1.0]) @ n) * n
        direction = 0.6 * n + side / max(np.linalg.norm(side), 1e-300)
        direction /= np.linalg.norm(direction)
        up = -n - (-n @ direction) * direction        # Gamma3 at the bottom of the image
        plotter.camera_position = [tuple(np.asarray(body.center) + 3 * body.length * direction),
                                   body.center, tuple(up / np.linalg.norm(up))]
    else:
        plotter.view_isometric()
    plotter.reset_camera()


def _add_field(plotter, mesh, name: str, scale: ColourScale, bar: dict,
               copy: bool = False) -> str:
    """Colour the mesh by a cell field on its whole range with a titled colour bar, or in
    one colour (UNIFORM_COLOUR, no bar) when the field is uniform (copy: the plotter
    draws a copy of the mesh, else the mesh itself, which the animation updates).

    Returns:
        "" or, for a uniform field, its uniform_note (for the picture's title).
    """
    if scale.uniform:
        plotter.add_mesh(mesh, color=UNIFORM_COLOUR, show_edges=False, copy_mesh=copy)
        return uniform_note(name, scale)
    plotter.add_mesh(mesh, scalars=name, preference="cell", cmap="viridis", clim=scale.clim,
                     show_edges=False, copy_mesh=copy,
                     scalar_bar_args={"title": bar_title(name), **bar})
    return ""


def _body_plotter(body, gamma3, dim: int, scale: ColourScale, title: str, window=WINDOW):
    """A plotter with the body coloured by sigma_vm (scale: its ColourScale) and Gamma3 in
    black if given (not rendered); a uniform stress is stated after the title."""
    pv = _pyvista()
    p = pv.Plotter(off_screen=True, window_size=window)
    p.set_background("white")
    note = _add_field(p, body, "sigma_vm", scale, BAR)
    if gamma3 is not None:
        p.add_mesh(gamma3.extract_all_edges() if dim == 3 else gamma3, color="black",
                   line_width=4 if dim == 2 else 2, label="contact boundary Gamma3")
    if title or note:
        p.add_text("; ".join(x for x in (title, note) if x), font_size=10, color="black")
    _view(p, dim, body, gamma3)
    return p


def draw_all(outdir: Path, factor: float, dim: int) -> list[Path]:
    """Every picture of a results directory: body.png and fig5_vm_kappa.png, and in 3D
    contact_pressure.png where the scene has contact forces (app/post/results.py,
    contact_scene), each written to a temporary file and renamed; a picture not drawn is
    removed if an earlier plot left it.

    Args:
        outdir: the results directory.
        factor: the displacement magnification (fig3's).
        dim: the body's dimension.

    Returns:
        The files written.
    """
    solution = Dataset(outdir / "solution.xdmf")
    grid, t = solution.at(), (solution.times[-1] if solution.times else 0.0)
    jobs = [("body.png", lambda f: body_picture(outdir, grid, t, factor, dim, f)),
            ("fig5_vm_kappa.png", lambda f: fields_picture(grid, t, dim, f))]
    if dim == 3 and (outdir / "contact.xdmf").exists() and contact_scene(outdir).forces:
        jobs.append(("contact_pressure.png", lambda f: pressure_picture(outdir, f)))
    drawn = [name for name, _ in jobs]
    for name in PICTURES:
        if name not in drawn:
            (outdir / name).unlink(missing_ok=True)
    for name, draw in jobs:
        write_replacing(outdir / name, draw)
    return [outdir / name for name in drawn]


def body_picture(outdir: Path, grid, t: float, factor: float, dim: int, path: Path) -> None:
    """body.png: the deformed body at time t coloured by von Mises stress on its whole
    range (colourscale.py), the contact boundary in black where the scene has one.

    Args:
        outdir: the results directory (contact.xdmf).
        grid: solution.xdmf's dataset at t.
        t: the time.
        factor: the displacement magnification.
        dim: the body's dimension.
        path: the PNG file.
    """
    body = _deformed(grid, factor)
    gamma3 = _contact_last(outdir, factor)
    title = f"t = {t:g}: von Mises stress, displacement x {factor:g}"
    if gamma3 is not None:
        title += f", {_gamma3_name(outdir)} in black"
    p = _body_plotter(body, gamma3, dim, colour_scale(body.cell_data["sigma_vm"]), title)
    _save(p, path)
    p.close()


def _gamma3_name(outdir: Path) -> str:
    """Gamma3 as the titles name it: "Gamma3", or with contact pairs the surfaces."""
    try:
        case = json.loads((outdir / "summary.json").read_text()).get("case_data", {})
    except (OSError, ValueError):
        return "Gamma3"
    pairs = (case.get("contact") or {}).get("pairs") or []
    if not pairs:
        return "Gamma3"
    return "contact surface " + ", ".join(f"{q['surface']} (on {q['target']})" for q in pairs)


def fields_picture(grid, t: float, dim: int, path: Path) -> None:
    """fig5_vm_kappa.png: von Mises stress and kappa at time t on the undeformed body, side
    by side (kappa only where the run has it; the laws norton and chaboche: their
    accumulated strain p), each on its whole range with its unit, a uniform field in one
    colour with its value (colourscale.py); in 3D the body clipped at mid y.

    Args:
        grid: solution.xdmf's dataset at t.
        t: the time.
        dim: the body's dimension.
        path: the PNG file.
    """
    pv = _pyvista()
    names = [n for n in ("sigma_vm", "kappa", "p") if n in grid.cell_data]   # p: norton, ...
    body = grid.clip(normal="y", origin=grid.center, invert=True) if dim == 3 else grid
    p = pv.Plotter(off_screen=True, window_size=(WINDOW[0], WINDOW[1] * 3 // 4),
                   shape=(1, len(names)))
    for i, name in enumerate(names):
        p.subplot(0, i)
        p.set_background("white")
        note = _add_field(p, body, name, colour_scale(body.cell_data[name]), NARROW_BAR,
                          copy=True)
        text = note or f"{bar_title(name).split(' [')[0]}"
        p.add_text(f"{text} at t = {t:g}" + (" (clipped at mid y)" if dim == 3 else ""),
                   font_size=9, color="black")
        _view(p, dim)
        if dim == 3:
            p.camera.zoom(0.8)                   # room for the colour bar below
    _save(p, path)
    p.close()


def _contact_last(outdir: Path, factor: float):
    """Gamma3 (contact.xdmf) at the last time, deformed; None without a contact boundary
    (no contact.xdmf, or no Gamma3 node: app/post/results.py, contact_scene)."""
    path = outdir / "contact.xdmf"
    if not path.exists() or not contact_scene(outdir).boundary:
        return None
    return _deformed(Dataset(path).at(), factor)


def pressure_picture(outdir: Path, path: Path) -> None:
    """contact_pressure.png (3D): -sigma_nu on Gamma3 (contact.xdmf) at the last time, seen
    from the foundation's side, on its whole range (a uniform pressure: one colour, its
    value in the title).

    Args:
        outdir: the results directory.
        path: the PNG file.
    """
    pv = _pyvista()
    contact = Dataset(outdir / "contact.xdmf")
    gamma3 = contact.at()
    p = pv.Plotter(off_screen=True, window_size=WINDOW)
    p.set_background("white")
    scale = colour_scale(gamma3["neg_sigma_nu"])
    p.add_mesh(gamma3, scalars="neg_sigma_nu", cmap="inferno", nan_color="lightgray",
               show_edges=True, edge_color="gray", clim=scale.clim,
               show_scalar_bar=not scale.uniform,
               scalar_bar_args={"title": bar_title("neg_sigma_nu"), **BAR})
    t = contact.times[-1] if contact.times else 0.0
    fixed = np.isnan(np.asarray(gamma3["neg_sigma_nu"], dtype=float)).any()
    p.add_text(f"t = {t:g}: contact pressure on Gamma3"
               + (" (grey: fixed by Dirichlet data)" if fixed else "")
               + (f"; {uniform_note('neg_sigma_nu', scale)}" if scale.uniform else ""),
               font_size=10, color="black")
    normal = _mean_normal(gamma3)
    p.camera_position = [tuple(gamma3.center - 3 * gamma3.length * normal), gamma3.center,
                         _up(normal)]
    p.enable_parallel_projection()
    p.reset_camera()
    p.camera.zoom(0.8)                           # room for the colour bar below
    _save(p, path)
    p.close()


def _mean_normal(surface) -> np.ndarray:
    """The area-weighted mean unit normal of a triangulated surface (its outward side when
    the facets are oriented as the body's boundary; else the sign of the first facet)."""
    tri = surface.triangulate()
    faces = np.asarray(tri.cells).reshape(-1, 4)[:, 1:]
    x = np.asarray(tri.points)
    n = np.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])
    n *= np.sign(n @ n[0])[:, None]
    mean = n.sum(axis=0)
    return mean / max(np.linalg.norm(mean), 1e-300)


def _up(normal: np.ndarray) -> tuple:
    """A view-up vector orthogonal to the viewing direction."""
    axis = np.eye(3)[int(np.argmin(np.abs(normal)))]
    up = axis - (axis @ normal) * normal
    return tuple(up / np.linalg.norm(up))


def animate(outdir: Path, factor: float, dim: int, path: Path, duration_ms: int = 150) -> int:
    """animation.gif: the deformed body coloured by von Mises stress at every output time,
    Gamma3 marked (one frame each; one colour scale, the range of all times
    (animation_scale), and the last time's camera for all; one render window whose meshes
    are updated in place).  The frames are streamed: each time is read, rendered and
    written to the file before the next, so the memory does not grow with the number of
    frames.

    Args:
        outdir: the results directory.
        factor: the displacement magnification.
        dim: the body's dimension.
        path: the GIF file.
        duration_ms: the time a frame is shown.

    Returns:
        The number of frames.
    """
    from PIL import Image
    solution = Dataset(outdir / "solution.xdmf")
    contact = Dataset(outdir / "contact.xdmf") if (outdir / "contact.xdmf").exists() else None
    times = solution.times or [0.0]
    body = _deformed(solution.at(times[-1]), factor)
    gamma3 = _deformed(contact.at(times[-1]), factor) if contact is not None else None
    scale = animation_scale(solution, times)
    p = _body_plotter(body, gamma3, dim, scale, "", FRAME)
    caption = p.add_text(" ", position=(10, 10), font_size=10, color="black")  # a vtkTextActor
    try:
        with open(path, "wb") as fh:
            gif = GifStream(fh, duration_ms)
            for t in times:
                grid = solution.at(t)
                body.points = _moved_points(grid, factor)
                body.cell_data["sigma_vm"] = grid.cell_data["sigma_vm"]
                if gamma3 is not None:
                    gamma3.points = _moved_points(contact.at(t), factor)
                caption.SetInput(f"t = {t:g}: von Mises stress, displacement x {factor:g}"
                                 + (f"; {uniform_note('sigma_vm', scale)}"
                                    if scale.uniform else ""))
                p.render()
                image = Image.fromarray(p.screenshot(return_img=True))
                gif.add(image.quantize(method=Image.Quantize.FASTOCTREE))
            gif.close()
    finally:
        p.close()
    return gif.frames


def animation_scale(solution: Dataset, times) -> ColourScale:
    """The animation's colour scale: the whole range of the von Mises stress over all
    times (colour_scale of each time's smallest and largest finite value), reading one
    time at a time.

    Args:
        solution: solution.xdmf.
        times: the output times.

    Returns:
        The ColourScale.
    """
    ends = []
    for t in times:
        vm = np.asarray(solution.at(t).cell_data["sigma_vm"], dtype=float)
        vm = vm[np.isfinite(vm)]
        ends += [vm.min(), vm.max()] if vm.size else []
    return colour_scale(ends)


class GifStream:
    """A GIF file written a frame at a time (Pillow's ``save_all`` holds every frame until
    it writes the file: docs/performance.md, section 9).  Each frame after the first is the
    rectangle where it differs from the one before (drawn over it, as Pillow writes them),
    with its own colour table.

    Args:
        fh: the file, open for binary writing.
        duration_ms: the time each frame is shown.
    """

    def __init__(self, fh, duration_ms: int):
        self.fh, self.duration, self.frames, self._previous = fh, duration_ms, 0, None

    def add(self, frame) -> None:
        """Write one frame.

        Args:
            frame: a palette ("P") image of the animation's size.
        """
        from PIL import GifImagePlugin, ImageChops
        if self._previous is None:
            header, _ = GifImagePlugin.getheader(frame, info={"loop": 0,
                                                              "duration": self.duration})
            self.fh.write(b"".join(header))
            box = (0, 0) + frame.size
        else:
            box = ImageChops.difference(self._previous.convert("RGB"),
                                        frame.convert("RGB")).getbbox() or (0, 0, 1, 1)
        self.fh.write(b"".join(GifImagePlugin.getdata(
            frame.crop(box), box[:2], duration=self.duration, include_color_table=True)))
        self._previous = frame
        self.frames += 1

    def close(self) -> None:
        """Write the trailer (the file stays open)."""
        self.fh.write(b";")


def warm_up(pictures: bool = True) -> None:
    """Load matplotlib, the figures' module (and h5py, which it reads with) and, for the
    pictures, pyvista's plotting modules, and start VTK's OpenGL (EGL) once, in a process
    started ahead of time while the run computes (docs/performance.md, section 9).

    Args:
        pictures: also pyvista and OpenGL (False: a process for line figures only).
    """
    import h5py  # noqa: F401

    plt = pyplot()                              # matplotlib's first figure is slow: drawn here
    fig = plt.figure(figsize=(1, 1))
    fig.text(0.5, 0.5, "x")
    fig.savefig(os.devnull, format="png")
    plt.close(fig)
    if not pictures:
        return
    pv = _pyvista()
    p = pv.Plotter(off_screen=True, window_size=(64, 48))
    p.add_mesh(pv.Sphere(), scalars=np.arange(pv.Sphere().n_points, dtype=float),
               scalar_bar_args=BAR)
    p.screenshot(return_img=True)
    p.close()


def main(argv=None) -> int:
    """The process: draw the pictures (and the animation, and the line figures it is given)
    of a results directory.  With --wait it warms up first and then reads the job as one
    JSON line from standard input ({"results", "factor", "dim", "animate", "line"}); at end
    of input it exits with nothing drawn.  With --no-pictures it draws the line figures
    only (and loads no pyvista).

    Args:
        argv: the arguments (default sys.argv[1:]): RESULTS_DIR --factor F --dim D
            [--animate] [--line NAME ...] [--no-pictures], or --wait [--no-pictures].

    Returns:
        0; the files written and the animation's frames are printed as one JSON line.
    """
    ap = argparse.ArgumentParser(description="pyvista pictures of a vpcontact run")
    ap.add_argument("results", type=Path, nargs="?")
    ap.add_argument("--factor", type=float, default=1.0)
    ap.add_argument("--dim", type=int, default=2)
    ap.add_argument("--animate", action="store_true")
    ap.add_argument("--line", nargs="*", default=[], help="line figures (app/post/linefigures.py)")
    ap.add_argument("--wait", action="store_true")
    ap.add_argument("--no-pictures", action="store_true",
                    help="only the line figures given with --line")
    args = ap.parse_args(argv)
    if args.wait:
        warm_up(not args.no_pictures)
        line = sys.stdin.readline()
        if not line.strip():
            return 0
        job = json.loads(line)
        args.results, args.factor = Path(job["results"]), job["factor"]
        args.dim, args.animate, args.line = job["dim"], job["animate"], job["line"]
    files = [] if args.no_pictures else draw_all(args.results, args.factor, args.dim)
    if args.line:
        files += draw_line_figures(args.results, args.line, args.factor)
    frames = None
    if args.animate:
        frames = write_replacing(args.results / ANIMATION,
                                 lambda tmp: animate(args.results, args.factor, args.dim, tmp))
        files.append(args.results / ANIMATION)
    print(json.dumps({"files": [str(f) for f in files], "frames": frames}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
