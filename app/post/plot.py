"""Figures of a run, drawn headless with matplotlib (Agg) from the files of a results
directory: solution.xdmf/.h5 (mesh and fields), contact.csv (Gamma3 table) and summary.json
(case data and step history); the pictures of the body (body.png, fig5_vm_kappa.png,
contact_pressure.png, animation.gif) are pyvista's (app/post/pictures.py).

- fig3_deformed_contact.png: deformed mesh at T (displacement magnified, factor printed) with
  the interface forces -sigma_nu along Gamma3 as in the paper's Fig. 3; at nodes with
  u_nu = g the bar shows c_nu g (the paper plots the normal compliance part there);
- fig4_tangential.png: u_tau and -sigma_tau along Gamma3 with u1 marked (Fig. 4);
- fig2_laws.png: the normal and tangential contact laws of the case (Fig. 2);
- history.png: norms, max von Mises, max kappa and iterations against time;
- forces.png: the contact force and the supports' reactions against time.
In 3D fig3 shows Gamma3 seen along z.
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from vpcontact.model import contact_laws
from vpcontact.post.pictures import ANIMATION, PICTURES, write_replacing

LINE_FIGURES = ("fig3_deformed_contact.png", "fig4_tangential.png", "fig2_laws.png",
                "history.png", "forces.png")
FIGURES = LINE_FIGURES + PICTURES + (ANIMATION,)       # what plot (--animate) may write
DPI = 110


def _mpl():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


# ----------------------------------------------------------------------------- reading
class ResultsError(ValueError):
    """A file of a results directory is damaged or incomplete (the message names it)."""


def check_results(outdir: Path) -> None:
    """Check the files the figures read before any figure is drawn: summary.json is a JSON
    object, solution.xdmf and contact.xdmf are complete XML whose every HDF5 dataset exists
    in a readable solution.h5 / contact.h5 with the shape the XML states, contact.csv has
    whole rows of numbers (a damaged file made VTK abort the pictures' process, or ended
    in a matplotlib error naming no file).

    Args:
        outdir: the results directory.

    Raises:
        ResultsError: one line naming the file and what is wrong with it.
    """
    outdir = Path(outdir)
    path = outdir / "summary.json"
    try:
        summary = json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise ResultsError(f"{path}: not valid JSON ({exc}); the run's summary is damaged") \
            from None
    if not isinstance(summary, dict):
        raise ResultsError(f"{path}: not a run summary (a JSON object expected)")
    for stem in ("solution", "contact"):
        if stem == "solution" or (outdir / f"{stem}.xdmf").exists():
            _check_xdmf(outdir / f"{stem}.xdmf")
    _check_contact_csv(outdir / "contact.csv")


def _check_xdmf(path: Path) -> None:
    """An XDMF file parses and its HDF5 datasets exist with their stated shapes."""
    import xml.etree.ElementTree as ET
    try:
        items = [i for i in ET.parse(path).getroot().iter("DataItem")
                 if i.get("Format") == "HDF"]
    except (ET.ParseError, OSError) as exc:
        raise ResultsError(f"{path}: not a complete XDMF file ({exc})") from None
    files = {}
    try:
        for item in items:
            name, _, dataset = (item.text or "").strip().partition(":")
            _check_dataset(files, path, name, dataset, item.get("Dimensions", ""))
    finally:
        for f in files.values():
            f.close()


def _check_dataset(files: dict, path: Path, name: str, dataset: str, dims: str) -> None:
    """The dataset an XDMF DataItem names exists with its shape (files: open HDF5 files)."""
    import h5py
    h5 = path.parent / name
    try:
        if name not in files:
            files[name] = h5py.File(h5, "r")
        shape = tuple(int(n) for n in dims.split())
        found = files[name][dataset].shape if dataset in files[name] else None
    except (OSError, ValueError) as exc:
        raise ResultsError(f"{h5}: cannot be read ({exc})") from None
    if found != shape:
        raise ResultsError(f"{h5}: no dataset {dataset} of shape {shape} (named by "
                           f"{path.name}): the file is incomplete or damaged")


def _check_contact_csv(path: Path) -> None:
    """contact.csv (if there) has whole rows: a number in every column but state."""
    if not path.exists():
        return
    with open(path, newline="") as fh:
        for line, row in enumerate(csv.DictReader(fh), start=2):
            try:
                if None in row or None in row.values():
                    raise ValueError("a different number of columns than the header")
                [float(v) for k, v in row.items() if k != "state"]
            except ValueError as exc:
                raise ResultsError(f"{path}: line {line}: {exc}") from None


class Results:
    """The data of a results directory needed by the figures.

    Args:
        outdir: the results directory (solution.h5, contact.csv, summary.json).

    Attributes:
        summary: summary.json's data; ``case``: its case data.
        x, cells: the mesh's vertex coordinates and cells.
        fields: the last stored value of each field; ``t``: the time of u.
        contact: contact.csv's columns, or None.
    """

    def __init__(self, outdir: Path):
        self.dir = Path(outdir)
        self.summary = json.loads((self.dir / "summary.json").read_text())
        self.case = self.summary.get("case_data", {})
        self._read_fields()
        self.contact = self._read_contact()

    def _read_fields(self):
        import h5py
        with h5py.File(self.dir / "solution.h5", "r") as f:
            self.x = f["Mesh/mesh/geometry"][...]
            self.cells = f["Mesh/mesh/topology"][...].astype(np.int64)
            self.fields, self.times = {}, {}
            for name in f["Function"]:
                keys = list(f["Function"][name])
                last = max(keys, key=lambda k: float(k.replace("_", ".")))
                self.fields[name] = f["Function"][name][last][...]
                self.times[name] = float(last.replace("_", "."))
        self.dim = self.cells.shape[1] - 1
        self.x = self.x[:, :self.dim]
        self.t = self.times.get("u", 0.0)

    def _read_contact(self):
        path = self.dir / "contact.csv"
        if not path.exists():
            return None
        rows = list(csv.DictReader(open(path)))
        if not rows:
            return None
        out = {k: np.array([r[k] for r in rows]) for k in rows[0]}
        for k in out:
            if k != "state":
                out[k] = out[k].astype(float)
        return out

    @property
    def u(self) -> np.ndarray:
        """The displacement at the vertices, (vertices, d)."""
        return self.fields["u"][:, :self.dim]

    def magnification(self) -> float:
        """The factor of the deformed views.

        Returns:
            1, 2 or 5 x 10^k making the largest displacement about 25% of the body size (1
            without displacement).
        """
        size = float(np.ptp(self.x, axis=0).max())
        umax = float(np.abs(self.u).max())
        if umax <= 0:
            return 1.0
        raw = 0.25 * size / umax
        return float(10 ** np.floor(np.log10(raw)) * np.array([1, 2, 5])[
            np.searchsorted([1, 2, 5], raw / 10 ** np.floor(np.log10(raw)), side="right") - 1])


# ----------------------------------------------------------------------------- 2D / 3D views
MAX_DRAWN_CELLS = 8192          # finer 2D meshes are drawn by their outline


def _boundary_edges(cells: np.ndarray) -> np.ndarray:
    """Edges (vertex pairs) of a triangle mesh that belong to one triangle only."""
    e = np.concatenate([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [2, 0]]])
    key = np.sort(e, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return e[counts[inv] == 1]


def _faces_3d(cells: np.ndarray) -> np.ndarray:
    """Boundary faces (triangles) of a set of tetrahedra."""
    f = np.concatenate([cells[:, [0, 1, 2]], cells[:, [0, 1, 3]], cells[:, [0, 2, 3]],
                        cells[:, [1, 2, 3]]])
    owner = np.tile(np.arange(len(cells)), 4)
    key = np.sort(f, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    once = counts[inv] == 1
    return f[once], owner[once]


def _bottom_faces(res: Results):
    """Triangles of Gamma3 and the cell each belongs to (3D): the boundary faces whose
    vertices are all contact.csv nodes, else (no contact) the bottom face z = 0, else the
    whole boundary."""
    faces, owner = _faces_3d(res.cells)
    scale = max(1.0, float(np.ptp(res.x)))
    if res.contact is not None:
        keys = {tuple(p) for p in np.round(np.column_stack(
            [res.contact[a] for a in "xyz"]) / scale, 8)}
        at = np.array([tuple(p) in keys for p in np.round(res.x / scale, 8)])
        on = at[faces].sum(axis=1) >= 2          # the faces next to clamped nodes too
    else:
        on = np.all(np.abs(res.x[faces, 2]) <= 1e-9 * scale, axis=1)
    if not on.any():
        on[:] = True
    return faces[on], owner[on]


def _save(plt, fig, path: Path, title: str | None = None) -> None:
    """Title, tight layout, write the PNG, free the figure."""
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI, pil_kwargs={"compress_level": 1})    # 3x faster than 6
    plt.close(fig)


# ----------------------------------------------------------------------------- figures
def fig3_deformed_contact(res: Results, path: Path, factor: float | None = None) -> float:
    """Deformed mesh at T with the contact forces along Gamma3 (the paper's Fig. 3).

    Args:
        res: the run's data.
        path: the PNG file to write.
        factor: the displacement factor, default ``res.magnification()``.

    Returns:
        The factor used.
    """
    plt = _mpl()
    factor = res.magnification() if factor is None else factor
    fig, ax = plt.subplots(figsize=(7.5, 6.5))
    X = res.x + factor * res.u
    if res.dim == 2 and len(res.cells) > MAX_DRAWN_CELLS:
        # a fine mesh would be a solid block of lines: the outlines (body.png shows the body)
        edges = _boundary_edges(res.cells)
        from matplotlib.collections import LineCollection
        for P, colour in ((res.x, "0.6"), (X, "tab:blue")):     # one artist, not one a line
            ax.add_collection(LineCollection(P[edges], colors=colour, lw=0.8))
        ax.autoscale_view()
    elif res.dim == 2:
        ax.triplot(res.x[:, 0], res.x[:, 1], res.cells, color="0.85", lw=0.4)
        ax.triplot(X[:, 0], X[:, 1], res.cells, color="tab:blue", lw=0.5)
    else:
        faces, _ = _bottom_faces(res)
        ax.triplot(res.x[:, 0], res.x[:, 1], faces, color="0.85", lw=0.4)
        ax.triplot(X[:, 0], X[:, 1], faces, color="tab:blue", lw=0.5)
    c = res.contact
    if c is not None and res.dim == 2:
        c_nu = (res.case.get("contact", {}).get("normal_compliance") or {}).get("c_nu")
        g = res.case.get("contact", {}).get("g")
        force = c["neg_sigma_nu"].copy()
        bound = c["state"] == "bound"
        if c_nu is not None and g is not None:
            force[bound] = c_nu * g              # the paper's Fig. 3 convention
        scale = 0.15 * float(np.ptp(res.x[:, 1])) / max(np.abs(force).max(), 1e-300)
        xb = c["x"] + factor * c["u_x"]
        yb = c["y"] + factor * c["u_y"]
        for state, colour in (("bound", "tab:red"), ("compliance", "tab:green"),
                              ("separated", "0.5")):
            m = c["state"] == state
            if m.any():
                ax.vlines(xb[m], yb[m] - scale * force[m], yb[m], colors=colour, lw=2,
                          label=f"-sigma_nu, {state} ({int(m.sum())} nodes)")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="upper right", fontsize=8)
        ax.set_ylim(min(yb.min() - scale * max(force.max(), 0) - 0.05, -0.3), None)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]" if res.dim == 2 else "y [m] (Gamma3 seen along z)")
    ax.set_title(f"Deformed configuration at t = {res.t:g} (displacement x {factor:g}); "
                 "contact forces on Gamma3", fontsize=10)
    _save(plt, fig, path)
    return factor


def fig4_tangential(res: Results, path: Path) -> None:
    """u_tau and -sigma_tau along Gamma3 at T, with u1 marked (the paper's Fig. 4).

    Args:
        res: the run's data.
        path: the PNG file to write.
    """
    plt = _mpl()
    fig, axes = plt.subplots(2, 1, figsize=(7.5, 6.5), sharex=True)
    c = res.contact
    u1 = (res.case.get("contact", {}).get("friction") or {}).get("u1")
    if c is None:
        axes[0].text(0.5, 0.5, "no contact boundary in this case", ha="center")
    else:
        key = "u_tau" if "u_tau" in c else "u_tau1"
        skey = "neg_sigma_tau" if "neg_sigma_tau" in c else "neg_sigma_tau1"
        order = np.argsort(c["x"])
        x = c["x"][order]
        axes[0].plot(x, c[key][order], "o-", ms=3, label="u_tau . tau")
        if u1:
            for s in (-u1, u1):
                axes[0].axhline(s, color="tab:red", ls="--", lw=1)
            axes[0].text(x.min(), -u1, " -u1", color="tab:red", va="bottom", fontsize=8)
        axes[0].set_ylabel("u_tau . tau [m]")
        axes[0].legend(fontsize=8)
        axes[1].plot(x, c[skey][order], "o-", ms=3, color="tab:orange",
                     label="-sigma_tau . tau")
        axes[1].set_ylabel("-sigma_tau . tau [N/m^2]")
        axes[1].legend(fontsize=8)
        if res.dim == 3:
            axes[0].set_title("3D: first tangential component, all Gamma3 nodes", fontsize=9)
    axes[1].set_xlabel("x on Gamma3 [m]")
    _save(plt, fig, path,
          f"Tangential displacement and friction stress along Gamma3 at t = {res.t:g}")


def normal_law(c_nu, g, r):
    """-sigma_nu of (4.1) for the figure (Fig. 2a).

    Args:
        c_nu: the compliance coefficient, or None (no normal compliance: 0).
        g: the bound of u_nu (at u_nu = g any value from c_nu g up is admissible).
        r: normal displacements u_nu <= g.

    Returns:
        p(u_nu) = c_nu u_nu^+ (app/model/contact_laws.py).
    """
    return contact_laws.normal_compliance(r, c_nu or 0.0)


def tangential_law(fr, rho):
    """|sigma_tau| = psi'(|u_tau|) of law (4.2) for |u_tau| > 0 (Fig. 2b).

    Args:
        fr: the case's friction parameters (b, c1, c2, u1).
        rho: slips |u_tau| > 0.

    Returns:
        psi'(rho) (app/model/contact_laws.py).
    """
    return contact_laws.dpsi(rho, fr["b"], fr["c1"], fr["c2"], fr["u1"])


def fig2_laws(res: Results, path: Path) -> None:
    """The case's normal law (4.1) and friction law (4.2) (the paper's Fig. 2).

    Args:
        res: the run's data.
        path: the PNG file to write.
    """
    plt = _mpl()
    contact = res.case.get("contact") or {}
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    g = contact.get("g")
    if isinstance(g, str):          # a gap field: the law at its largest value on Gamma3
        c = res.contact
        g = float(c["g"].max()) if c is not None and "g" in c else None
    c_nu = (contact.get("normal_compliance") or {}).get("c_nu")
    ax = axes[0]
    if g is not None or c_nu is not None:
        top = g if g else 0.02
        r = np.linspace(-0.5 * top, top, 200)
        ax.plot(r, normal_law(c_nu, g, r), color="tab:blue", label="p(u_nu) = c_nu u_nu^+")
        if g is not None:
            pg = normal_law(c_nu, g, np.array([g]))[0]
            ax.vlines(g, pg, pg + max(pg, 1.0), color="tab:red",
                      label="u_nu = g: -sigma_nu >= c_nu g (unilateral)")
            ax.axvline(g, color="tab:red", ls=":", lw=0.8)
        ax.legend(fontsize=8)
    else:
        ax.text(0.5, 0.5, "no normal contact law", ha="center", transform=ax.transAxes)
    ax.set_xlabel("u_nu [m]")
    ax.set_ylabel("-sigma_nu [N/m^2]")
    ax.set_title("normal law (4.1)", fontsize=10)
    fr = contact.get("friction")
    ax = axes[1]
    if fr:
        rho = np.linspace(0, 3 * fr["u1"], 300)[1:]
        ax.plot(rho, tangential_law(fr, rho), color="tab:blue", label="psi'(|u_tau|)")
        ax.vlines(0, 0, fr["b"], color="tab:blue", lw=3, label="|u_tau| = 0: [0, b] (stick)")
        ax.axvline(fr["u1"], color="tab:red", ls="--", lw=1)
        ax.text(fr["u1"], 0, " u1", color="tab:red", va="bottom")
        ax.legend(fontsize=8)
        ax.set_ylim(bottom=0)
    else:
        ax.text(0.5, 0.5, "frictionless", ha="center", transform=ax.transAxes)
    ax.set_xlabel("|u_tau| [m]")
    ax.set_ylabel("|sigma_tau| [N/m^2]")
    ax.set_title("nonmonotone friction law (4.2)", fontsize=10)
    _save(plt, fig, path, f"Contact laws of case {res.summary.get('case')} (the paper's Fig. 2)")


def history(res: Results, path: Path) -> None:
    """Norms, max von Mises stress, max kappa and iterations against time.

    Args:
        res: the run's data.
        path: the PNG file to write.

    Returns:
        None (the figure is written to ``path``).
    """
    plt = _mpl()
    steps = res.summary.get("steps", [])
    t = np.array([s["t"] for s in steps])
    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True)

    def col(k):
        return np.array([s[k] for s in steps])
    if len(t):
        ax = axes[0, 0]
        ax.plot(t, col("norm_u_V"), "o-", ms=2, label="||u||_V")
        ax.set_ylabel("||u||_V")
        ax2 = ax.twinx()
        ax2.plot(t, col("norm_sigma_Q"), "s-", ms=2, color="tab:orange", label="||sigma||_Q")
        ax2.set_ylabel("||sigma||_Q")
        ax.set_title("norms", fontsize=10)
        axes[0, 1].plot(t, col("max_vm"), "o-", ms=2)
        axes[0, 1].set_title("max ||sigma||_VM", fontsize=10)
        axes[1, 0].plot(t, col("max_kappa"), "o-", ms=2, color="tab:green")
        axes[1, 0].set_title("max kappa", fontsize=10)
        axes[1, 1].vlines(t, 0, col("newton_iterations"), color="tab:purple",
                          lw=max(0.5, min(4.0, 300 / len(t))))      # one artist per panel
        axes[1, 1].set_title("Newton / Gamma3 iterations per step", fontsize=10)
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    _save(plt, fig, path, f"History of run {res.summary.get('case')} "
                          f"({res.summary.get('status')})")


def forces(res: Results, path: Path) -> None:
    """The force resultants on the body against time: the foundation's (contact_force) and
    each Dirichlet group's reaction, per component (a held indentation shows the contact
    force relaxing).

    Args:
        res: the run's data.
        path: the PNG file to write.
    """
    plt = _mpl()
    steps = [s for s in res.summary.get("steps", []) if "reactions" in s]
    dim = res.dim
    fig, axes = plt.subplots(1, dim, figsize=(5 * dim, 4.2), sharex=True)
    t = np.array([s["t"] for s in steps])
    series = {}
    if any("contact_force" in s for s in steps):
        series["contact (foundation)"] = [s.get("contact_force", [0.0] * dim) for s in steps]
    for name in (steps[-1]["reactions"] if steps else {}):
        series[f"reaction on {name}"] = [s["reactions"][name] for s in steps]
    for i, ax in enumerate(axes):
        for label, values in series.items():
            ax.plot(t, np.asarray(values)[:, i], "o-", ms=2, label=label)
        ax.axhline(0.0, color="0.7", lw=0.8)
        ax.set_xlabel("t [s]")
        ax.set_ylabel(f"F_{'xyz'[i]} [N{'/m' if dim == 2 else ''}]")
    if series:
        axes[0].legend(fontsize=8)
    else:
        axes[0].text(0.5, 0.5, "no supports or contact", ha="center",
                     transform=axes[0].transAxes)
    _save(plt, fig, path, f"Forces on the body, run {res.summary.get('case')}")


class PicturesError(RuntimeError):
    """The pyvista pictures could not be drawn; ``written``: the line figures that were."""

    def __init__(self, reason: str, written: list[Path]):
        super().__init__(reason)
        self.written = written


PAINTER_LINE_FIGURES = ("forces.png",)    # drawn by the pictures' process (balances the two)


def draw_line_figures(outdir: Path, names, factor: float, res=None) -> list[Path]:
    """Draw line figures (each to a temporary file, then renamed).

    Args:
        outdir: the results directory.
        names: which (of LINE_FIGURES).
        factor: fig3's displacement magnification.
        res: the run's Results (None: read).

    Returns:
        The files written.
    """
    from functools import partial
    res = Results(outdir) if res is None else res
    written = []
    for name in names:
        options = {"factor": factor} if name.startswith("fig3") else {}
        path = Path(outdir) / name
        write_replacing(path, partial(LINE_FIGURE_FUNCTIONS[name], res, **options))
        written.append(path)
    return written


def plot_all(outdir: Path, log=None, animate: bool = False, painter=None) -> list[Path]:
    """Write every figure into ``outdir`` (atomically: temporary file, then rename), in the
    two figure processes of a Painter at once (started ahead of a serial run, so that
    loading matplotlib, pyvista and OpenGL overlaps the computation): one draws the
    pictures (app/post/pictures.py), PAINTER_LINE_FIGURES and the animation if asked for,
    the other the other line figures.

    Args:
        outdir: the results directory.
        log: called with a line naming fig3's displacement factor, or None.
        animate: also write animation.gif (a frame per output time).
        painter: a Painter started ahead of time (None: one is started now).

    Returns:
        The files written (of FIGURES).

    Raises:
        PicturesError: the pictures' process failed (the line figures are written).
    """
    outdir = Path(outdir)
    res = Results(outdir)
    factor = res.magnification()
    painter = painter or Painter()
    try:
        painter.draw(outdir, factor, res.dim, animate)
        result = painter.finish()
    finally:
        painter.cancel()
    if log:
        log(f"fig3_deformed_contact.png, body.png: displacement magnified x {factor:g}")
        if result["frames"] is not None:
            log(f"{ANIMATION}: {result['frames']} frames")
    return [Path(f) for f in result["files"]]


class Painter:
    """The figures' processes: ``python -m vpcontact.post.pictures --wait`` (pyvista's pictures,
    PAINTER_LINE_FIGURES, the animation; it loads pyvista and matplotlib and starts OpenGL
    at once) and ``... --wait --no-pictures`` (the other line figures; it loads
    matplotlib), each waiting for its job, without MPI's variables (they are no ranks of a
    job).  Started ahead of a run, their start-up overlaps the run, and the figures are
    drawn on two cores while the run's process waits.

    Raises:
        OSError: a process cannot be started.
    """

    def __init__(self):
        self.pictures, self.lines, self._job = _figure_process(), None, None
        try:
            self.lines = _figure_process("--no-pictures")
        except OSError:
            self.cancel()
            raise

    def draw(self, outdir: Path, factor: float, dim: int, animate: bool) -> None:
        """Give the processes their jobs (they draw while the caller goes on).

        Args:
            outdir: the results directory.
            factor: the displacement magnification.
            dim: the body's dimension.
            animate: also the animation.
        """
        self._job = {"results": str(outdir), "factor": factor, "dim": dim}
        _give(self.pictures, {**self._job, "animate": animate,
                              "line": list(PAINTER_LINE_FIGURES)})
        _give(self.lines, {**self._job, "animate": False, "line": _own_line_figures()})

    def finish(self) -> dict:
        """Wait for the figures (if the line figures' process failed, they are drawn here).

        Returns:
            {"files": [...], "frames": the animation's, or None}.

        Raises:
            PicturesError: the pictures' process failed (its last error line; ``written``:
                the line figures).
        """
        job = self._job
        try:
            lines = _result(self.lines)["files"]
        except PicturesError:
            lines = [str(f) for f in draw_line_figures(Path(job["results"]),
                                                       _own_line_figures(), job["factor"])]
        try:
            pictures = _result(self.pictures)
        except PicturesError as exc:
            exc.written = [Path(f) for f in lines]
            raise
        return {"files": lines + pictures["files"], "frames": pictures["frames"]}

    def cancel(self) -> None:
        """Stop the processes that still run (a run that ends without figures, Ctrl-C while
        drawing) and remove the temporary files they were writing."""
        killed = False
        for proc in (self.pictures, self.lines):
            if proc is not None and proc.poll() is None:
                proc.kill()
                proc.communicate()
                killed = True
        if killed and self._job is not None:
            from vpcontact.post.pictures import temporary
            for name in FIGURES:
                temporary(Path(self._job["results"]) / name).unlink(missing_ok=True)


def _own_line_figures() -> list[str]:
    """The line figures of the line figures' process."""
    return [n for n in LINE_FIGURES if n not in PAINTER_LINE_FIGURES]


def _figure_process(*options):
    """Start ``python -m vpcontact.post.pictures --wait`` (with options), MPI's variables left
    out."""
    import os
    import subprocess
    import sys

    from vpcontact.post import pictures
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_", "PMI_"))}
    return subprocess.Popen([sys.executable, "-P", "-m", pictures.__name__, "--wait", *options],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)


def _give(proc, job: dict) -> None:
    """Send a figure process its job (one JSON line).

    SIGPIPE is ignored during the write: a figure process that died makes the write fail
    (BrokenPipeError) instead of raising SIGPIPE, which PETSc's signal handler, installed
    in any process that has loaded dolfinx, turns into an MPI_Abort of the caller (the
    command line ignores SIGPIPE anyway; a Python script or a test does not)."""
    import signal
    import threading

    main = threading.current_thread() is threading.main_thread()
    before = signal.signal(signal.SIGPIPE, signal.SIG_IGN) if main else None
    try:
        proc.stdin.write(json.dumps(job) + "\n")
        proc.stdin.flush()                     # communicate() closes it
    except OSError:            # it died while starting: _result reports its error
        pass
    finally:
        if main:
            signal.signal(signal.SIGPIPE, before)


def _result(proc) -> dict:
    """The files (and frames) a figure process wrote; PicturesError if it failed."""
    out, err = proc.communicate()
    if proc.returncode != 0 or not out.strip():
        lines = [x for x in err.splitlines() if x.strip()]
        raise PicturesError(lines[-1] if lines else f"exit {proc.returncode}", [])
    return json.loads(out.strip().splitlines()[-1])


# LINE_FIGURES' drawing functions, (res, path) (fig3 also takes the factor)
LINE_FIGURE_FUNCTIONS = {"fig3_deformed_contact.png": fig3_deformed_contact,
                         "fig4_tangential.png": fig4_tangential, "fig2_laws.png": fig2_laws,
                         "history.png": history, "forces.png": forces}
