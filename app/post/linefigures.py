"""The line figures of a run, drawn headless with matplotlib (Agg) from the files of a
results directory (app/post/results.py): solution.xdmf/.h5 (mesh and fields), contact.csv
(Gamma3 table) and summary.json (case data and step history); the pictures of the body
(body.png, fig5_vm_kappa.png, contact_pressure.png, animation.gif) are pyvista's
(app/post/pictures.py); app/post/plot.py's figure processes draw both.

- fig3_deformed_contact.png: deformed mesh at T (displacement magnified, factor printed) with
  the interface forces -sigma_nu along Gamma3 as in the paper's Fig. 3 and a scale bar; at
  nodes with u_nu = g the bar shows c_nu g (the paper plots the normal compliance part
  there);
- fig4_tangential.png: u_tau and -sigma_tau along Gamma3 with u1 marked (Fig. 4);
- fig2_laws.png: the normal and tangential contact laws of the case (Fig. 2);
- history.png: norms, max von Mises, max kappa and iterations against time;
- forces.png: the contact force and the supports' reactions against time.
In 3D fig3 shows Gamma3 seen along z.  The contact figures (fig2, fig3, fig4) are drawn
where the scene has what they show (CONTACT_FIGURES).
"""
from __future__ import annotations

from functools import partial
from pathlib import Path

import numpy as np

from vpcontact.io.files import write_replacing
from vpcontact.model.contactregistry import BOUNDS, NORMALS, chosen
from vpcontact.post.results import Results, contact_scene, round_125

LINE_FIGURES = ("fig3_deformed_contact.png", "fig4_tangential.png", "fig2_laws.png",
                "history.png", "forces.png")
DPI = 110


def pyplot():
    """matplotlib's pyplot on the Agg back end (headless; loaded on first use).

    Returns:
        The matplotlib.pyplot module.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


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
    """Title (wrapped to the figure's width), tight layout, write the PNG, free the
    figure."""
    if title:
        fig.suptitle(wrap(title, fig.get_figwidth()), fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI, pil_kwargs={"compress_level": 1})    # 3x faster than 6
    plt.close(fig)


CHARS_PER_INCH = 11          # of a 10-point title (DejaVu Sans: about 6 points a character)


def wrap(title: str, width_in: float) -> str:
    """A title broken into lines that fit a width (each line of it kept: a line break in
    the title stays one).

    Args:
        title: the text.
        width_in: the width in inches.

    Returns:
        The title with line breaks.
    """
    import textwrap
    width = max(20, int(CHARS_PER_INCH * width_in))
    return "\n".join(textwrap.fill(line, width) for line in title.split("\n"))


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
    plt = pyplot()
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
        _pressure_bars(ax, res, c, factor)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]" if res.dim == 2 else "y [m] (Gamma3 seen along z)")
    if res.pairs:
        scale = "true scale" if factor == 1 else f"displacement x {factor:g}"
        title = (f"Deformed configuration at t = {res.t:g} ({scale}); contact pressure on "
                 f"the surface\n{pair_label(res)}")
    else:
        title = (f"Deformed configuration at t = {res.t:g} (displacement x {factor:g}); "
                 "contact forces on Gamma3")
    if res.dim == 3:        # Gamma3's facets only (contact_pressure.png: the pressure)
        title = (f"Deformed contact boundary Gamma3 at t = {res.t:g} (displacement x "
                 f"{factor:g}), seen along z; its contact pressure: contact_pressure.png")
    ax.set_title(wrap(title, fig.get_figwidth()), fontsize=10)
    _save(plt, fig, path)
    return factor


def pair_label(res: Results) -> str:
    """The contact pairs as "pair 0: surface -> target; ..." ("" without pairs).

    Args:
        res: the run's data.

    Returns:
        The label.
    """
    return "; ".join(f"pair {i}: {p['surface']} -> {p['target']}"
                     for i, p in enumerate(res.pairs))


def _pressure_bars(ax, res: Results, c: dict, factor: float) -> None:
    """fig3's bars -sigma_nu at the deformed Gamma3 nodes (2D), coloured by state, with a
    scale bar (FORCE_SCALE) of a round value beside them; below Gamma3 (the foundation's
    side), with contact pairs on the surface's own side (not across the other body: the
    view is the surfaces' neighbourhood, the bars scaled to it)."""
    nc = res.case.get("contact", {}).get("normal_compliance")
    g = res.case.get("contact", {}).get("g")
    force = c["neg_sigma_nu"].copy()
    bound = c["state"] == "bound"
    if nc and "law" not in nc and isinstance(g, (int, float)) \
            and not isinstance(nc.get("c_nu"), str):
        force[bound] = _normal_law(nc, g, np.array([float(g)]))[0]   # the paper's Fig. 3
    force = np.nan_to_num(force)
    xb = c["x"] + factor * c["u_x"]
    yb = c["y"] + factor * c["u_y"]
    top = max(float(np.abs(force).max()), 1e-300)
    size = max(float(np.ptp(xb)), float(np.ptp(yb)), 1e-300)
    if res.pairs:          # the surfaces and the bars on the surface's side, a margin around
        scale = 0.3 * size / top
        side = _surface_side(res, c)
        ax.set_xlim(xb.min() - 0.2 * size, xb.max() + 0.2 * size)
        ax.set_ylim(yb.min() - (0.45 if side < 0 else 0.1) * size,
                    yb.max() + (0.45 if side > 0 else 0.1) * size)
    else:
        scale, side = 0.15 * float(np.ptp(res.x[:, 1])) / top, -1.0
    states = {"bound": "touching" if res.pairs else "bound"}
    for state, colour in (("bound", "tab:red"), ("compliance", "tab:green"),
                          ("separated", "0.5")):
        m = c["state"] == state
        if m.any():
            ax.vlines(xb[m], yb[m], yb[m] + side * scale * force[m], colors=colour, lw=2,
                      label=f"-sigma_nu, {states.get(state, state)} ({int(m.sum())} nodes)")
    _force_scale(ax, xb.max() + 0.08 * size, yb[np.argmax(np.abs(force))], side * scale, top)
    ax.set_xlim(None, max(ax.get_xlim()[1], xb.max() + 0.3 * size))    # room for its label
    ax.legend(loc="upper right", fontsize=8)
    if not res.pairs:
        ax.set_ylim(min(yb.min() - scale * max(force.max(), 0) - 0.05, -0.3), None)


FORCE_SCALE = "force_scale"     # the gid of fig3's scale bar and its label


def _force_scale(ax, x: float, y: float, scale: float, top: float) -> None:
    """fig3's scale bar: a black bar of the round value round_125(top) [N/m^2] drawn as the
    force bars are (length scale x value, from y: the level of the largest), at x,
    labelled with its value."""
    ref = round_125(top)
    bar = ax.vlines([x], [y], [y + scale * ref], colors="black", lw=3,
                    label=f"scale: this bar is -sigma_nu = {ref:g} N/m^2")
    bar.set_gid(FORCE_SCALE)
    ax.text(x, y + 0.5 * scale * ref, f"  {ref:g} N/m^2", fontsize=8, gid=FORCE_SCALE,
            va="center", ha="left")


def _surface_side(res: Results, c: dict) -> float:
    """The side of the contact surface its own body lies on, along y (+1 above, -1
    below): where the cells at its nodes lie (the other body is on the other side)."""
    scale = max(1.0, float(np.ptp(res.x)))
    keys = {tuple(p) for p in np.round(np.column_stack([c["x"], c["y"]]) / scale, 8)}
    on = np.array([tuple(p) in keys for p in np.round(res.x / scale, 8)])
    cells = res.cells[on[res.cells].any(axis=1)]
    if not len(cells):
        return -1.0
    at = on[cells]                                   # each cell's vertices on the surface
    y = res.x[cells][:, :, 1]
    above = y.mean(axis=1) - (y * at).sum(axis=1) / at.sum(axis=1)
    return 1.0 if above.mean() > 0 else -1.0


def fig4_tangential(res: Results, path: Path) -> None:
    """u_tau and -sigma_tau along Gamma3 at T, with u1 marked (the paper's Fig. 4).

    Args:
        res: the run's data.
        path: the PNG file to write.
    """
    plt = pyplot()
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
        pairs = bool(res.pairs)     # two bodies: the relative displacement on the surface
        u_label = "[u]_tau . tau (relative)" if pairs else "u_tau . tau"
        axes[0].plot(x, c[key][order], "o-", ms=3, label=u_label)
        if u1:
            for s in (-u1, u1):
                axes[0].axhline(s, color="tab:red", ls="--", lw=1)
            axes[0].text(x.min(), -u1, " -u1", color="tab:red", va="bottom", fontsize=8)
        axes[0].set_ylabel(f"{u_label} [m]")
        axes[0].legend(fontsize=8)
        axes[1].plot(x, c[skey][order], "o-", ms=3, color="tab:orange",
                     label="-sigma_tau . tau")
        axes[1].set_ylabel("-sigma_tau . tau [N/m^2]")
        axes[1].legend(fontsize=8)
        if res.dim == 3:
            axes[0].set_title("3D: first tangential component, all Gamma3 nodes", fontsize=9)
    where = f"the surface ({pair_label(res)})" if res.pairs else "Gamma3"
    axes[1].set_xlabel(f"x on {'the surface' if res.pairs else 'Gamma3'} [m]")
    _save(plt, fig, path,
          f"Tangential displacement and friction stress along {where} at t = {res.t:g}")


def _normal_law(nc, g, r):
    """-sigma_nu = p(u_nu) at u_nu = r <= g: the built-in law of contact.normal_compliance
    ``nc`` chosen by its keys (``NORMALS``: c_nu u_nu^+ of (4.1), c_nu (u_nu^+)^m, the
    table, ...; None, or c_nu(x): 0) (Fig. 2a)."""
    nc = nc or {}
    spec = chosen(NORMALS, nc)
    constants = {k: v for k, v in spec.constants(nc).items() if not isinstance(v, str)}
    if not all(k in constants for k in spec.required()):    # none, or c_nu(x)
        return 0.0 * np.maximum(np.asarray(r, dtype=float), 0.0)
    return spec.build(constants, lambda name, value: value, None).derivative(r)


def _draw_bound(ax, fr) -> None:
    """Fig. 2b: |sigma_tau| = psi'(rho) of the built-in bound of contact.friction ``fr``
    chosen by its keys (``BOUNDS``: (4.2)'s b, c1, c2, u1, the friction table, ...) at slips
    rho = |u_tau| > 0, its stick interval and mark (the spec's ``drawing``)."""
    spec = chosen(BOUNDS, fr)
    constants = spec.constants(fr)
    how = spec.drawing(constants)
    rho = np.linspace(0, how.upto, 300)[1:]
    law = spec.build(constants, lambda name, value: value)
    ax.plot(rho, law.derivative(rho), color="tab:blue", label=how.label)
    ax.vlines(0, 0, how.stick, color="tab:blue", lw=3, label=how.stick_label)
    if how.mark is not None:
        ax.axvline(how.mark[0], color="tab:red", ls="--", lw=1)
        ax.text(how.mark[0], 0, f" {how.mark[1]}", color="tab:red", va="bottom")
    ax.legend(fontsize=8)
    ax.set_ylim(bottom=0)


def fig2_laws(res: Results, path: Path) -> None:
    """The case's normal law (4.1) and friction law (4.2) (the paper's Fig. 2).

    Args:
        res: the run's data.
        path: the PNG file to write.
    """
    plt = pyplot()
    contact = res.case.get("contact") or {}
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    g = contact.get("g")
    if isinstance(g, str):          # a gap field: the law at its largest value on Gamma3
        c = res.contact
        g = float(c["g"].max()) if c is not None and "g" in c else None
    if res.pairs and g is None:     # two bodies: the bound [u]_nu - d <= g of the first pair
        g = float(res.pairs[0].get("g", 0.0))
    nc = contact.get("normal_compliance")
    ax = axes[0]
    if nc and nc.get("law") == "python":        # the user's law: drawn by the user
        ax.text(0.5, 0.5, f"the user's law {nc['class']}", ha="center",
                transform=ax.transAxes)
    elif g is not None or nc:
        top = g if g else 0.02
        r = np.linspace(-0.5 * top, top, 200)
        ax.plot(r, _normal_law(nc, g, r), color="tab:blue", label="p(u_nu)")
        if g is not None:
            pg = _normal_law(nc, g, np.array([g]))[0]
            at = "[u]_nu - d = g" if res.pairs else "u_nu = g"
            ax.vlines(g, pg, pg + max(pg, 1.0), color="tab:red",
                      label=f"{at}: -sigma_nu >= c_nu g (unilateral)")
            ax.axvline(g, color="tab:red", ls=":", lw=0.8)
        ax.legend(fontsize=8)
    else:
        ax.text(0.5, 0.5, "no normal contact law", ha="center", transform=ax.transAxes)
    ax.set_xlabel("[u]_nu - d [m] (relative normal displacement)" if res.pairs else
                  "u_nu [m]")
    ax.set_ylabel("-sigma_nu [N/m^2]")
    ax.set_title("normal law (4.1)", fontsize=10)
    fr = contact.get("friction")
    ax = axes[1]
    if fr and fr.get("law") == "python":
        ax.text(0.5, 0.5, f"the user's law {fr['class']}", ha="center",
                transform=ax.transAxes)
    elif fr and "coulomb" in fr:
        ax.text(0.5, 0.5, f"Coulomb: |sigma_tau| <= mu p_n, mu = {fr['coulomb']['mu']:g}",
                ha="center", transform=ax.transAxes)
    elif fr:
        _draw_bound(ax, fr)
    else:
        ax.text(0.5, 0.5, "frictionless", ha="center", transform=ax.transAxes)
    ax.set_xlabel("|[u]_tau| [m] (relative)" if res.pairs else "|u_tau| [m]")
    ax.set_ylabel("|sigma_tau| [N/m^2]")
    ax.set_title("nonmonotone friction law (4.2)", fontsize=10)
    on = f", {pair_label(res)}" if res.pairs else ""
    _save(plt, fig, path,
          f"Contact laws of case {res.summary.get('case')}{on} (the paper's Fig. 2)")


def history(res: Results, path: Path) -> None:
    """Norms, max von Mises stress, max kappa and iterations against time.

    Args:
        res: the run's data.
        path: the PNG file to write.

    Returns:
        None (the figure is written to ``path``).
    """
    plt = pyplot()
    steps = res.summary.get("steps", [])
    t = np.array([s["t"] for s in steps])
    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True)

    def col(k):
        return np.array([s[k] for s in steps])
    if len(t):
        ax = axes[0, 0]
        root = "m" if res.dim == 2 else "m^(3/2)"        # the square root of the measure
        ax.plot(t, col("norm_u_V"), "o-", ms=2, label="||u||_V")
        ax.set_ylabel(f"||u||_V = ||eps(u)||_L2 [{root}]")
        ax2 = ax.twinx()
        ax2.plot(t, col("norm_sigma_Q"), "s-", ms=2, color="tab:orange", label="||sigma||_Q")
        ax2.set_ylabel(f"||sigma||_Q [N/m^2 x {root}]")
        lines = list(ax.get_lines()) + list(ax2.get_lines())   # two y-axes: one legend
        ax.legend(lines, [x.get_label() + (" (left axis)" if x.axes is ax else
                                           " (right axis)") for x in lines], fontsize=8)
        ax.set_title("norms", fontsize=10)
        axes[0, 1].plot(t, col("max_vm"), "o-", ms=2)
        axes[0, 1].set_title("max ||sigma||_VM [N/m^2]", fontsize=10)
        axes[1, 0].plot(t, col("max_kappa"), "o-", ms=2, color="tab:green")
        axes[1, 0].set_title(f"max kappa{_kappa_unit(res.case)}", fontsize=10)
        axes[1, 1].vlines(t, 0, col("newton_iterations"), color="tab:purple",
                          lw=max(0.5, min(4.0, 300 / len(t))))      # one artist per panel
        axes[1, 1].set_title("Newton / Gamma3 iterations per step", fontsize=10)
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    _save(plt, fig, path, f"History of run {res.summary.get('case')} "
                          f"({res.summary.get('status')})")


def _kappa_unit(case: dict) -> str:
    """" [unit]" of kappa for the laws of a case (each built-in law's LawSpec.kappa_unit:
    perzyna, power: a stress, N/m^2; norton, chaboche: their accumulated strain p,
    dimensionless), "" for a user's law or laws of both kinds."""
    from vpcontact.model.lawregistry import DEFAULT_LAW, LAWS
    materials = [case.get("material") or {}, *(case.get("materials") or {}).values()]
    laws = {(m.get("viscoplastic") or {}).get("law", DEFAULT_LAW)
            for m in materials if m.get("viscoplastic")}
    units = {LAWS[law].kappa_unit if law in LAWS else None for law in laws}
    return f" [{units.pop()}]" if len(units) == 1 and None not in units else ""


ROUNDING = 1e-9      # forces.png: each axis spans at least +-ROUNDING x the largest force


def forces(res: Results, path: Path) -> None:
    """The force resultants on the body against time: the foundation's (contact_force; two
    bodies: each pair's on its surface's and its target's body, pair_forces) and each
    Dirichlet group's reaction, per component (a held indentation shows the contact force
    relaxing).

    Args:
        res: the run's data.
        path: the PNG file to write.
    """
    plt = pyplot()
    steps = [s for s in res.summary.get("steps", []) if "reactions" in s]
    dim = res.dim
    fig, axes = plt.subplots(1, dim, figsize=(5 * dim, 4.2), sharex=True)
    t = np.array([s["t"] for s in steps])
    series = {}
    if any("pair_forces" in s for s in steps):      # two bodies: the force on each
        for i, pair in enumerate(steps[-1]["pair_forces"]):
            for side in ("surface", "target"):
                series[f"contact on {pair[side]} (pair {i} {side})"] = [
                    s["pair_forces"][i][f"on_{side}"] for s in steps]
    elif any("contact_force" in s for s in steps):
        series["contact (foundation)"] = [s.get("contact_force", [0.0] * dim) for s in steps]
    for name in (steps[-1]["reactions"] if steps else {}):
        series[f"reaction on {name}"] = [s["reactions"][name] for s in steps]
    top = max([float(np.nanmax(np.abs(np.asarray(v, dtype=float)), initial=0.0))
               for v in series.values()], default=0.0)
    for i, ax in enumerate(axes):
        for label, values in series.items():
            ax.plot(t, np.asarray(values)[:, i], "o-", ms=2, label=label)
        ax.axhline(0.0, color="0.7", lw=0.8)
        if top > 0:          # a component that is rounding (1e-15 of the forces) stays flat
            low, high = ax.get_ylim()
            ax.set_ylim(min(low, -ROUNDING * top), max(high, ROUNDING * top))
        ax.set_xlabel("t [s]")
        ax.set_ylabel(f"F_{'xyz'[i]} [N{'/m' if dim == 2 else ''}]")
    if series:
        axes[0].legend(fontsize=8)
    else:
        axes[0].text(0.5, 0.5, "no supports or contact", ha="center",
                     transform=axes[0].transAxes)
    bodies = "bodies" if res.pairs else "body"
    _save(plt, fig, path, f"Forces on the {bodies}, run {res.summary.get('case')}")


# the contact figures, drawn where the scene has what they show (results.ContactScene):
# the laws where there is a contact boundary, the forces along it where there are some
CONTACT_FIGURES = {"fig2_laws.png": lambda scene: scene.boundary,
                   "fig3_deformed_contact.png": lambda scene: scene.forces,
                   "fig4_tangential.png": lambda scene: scene.forces}


def draw_line_figures(outdir: Path, names, factor: float, res=None) -> list[Path]:
    """Draw line figures (each to a temporary file, then renamed), the contact figures
    only where the scene has a contact boundary and forces (CONTACT_FIGURES; one that is
    not drawn is removed if an earlier plot left it).

    Args:
        outdir: the results directory.
        names: which (of LINE_FIGURES).
        factor: fig3's displacement magnification.
        res: the run's Results (None: read).

    Returns:
        The files written.
    """
    res = Results(outdir) if res is None else res
    scene = contact_scene(outdir)
    written = []
    for name in names:
        if not CONTACT_FIGURES.get(name, lambda _: True)(scene):
            (Path(outdir) / name).unlink(missing_ok=True)      # an earlier plot's
            continue
        options = {"factor": factor} if name.startswith("fig3") else {}
        path = Path(outdir) / name
        write_replacing(path, partial(LINE_FIGURE_FUNCTIONS[name], res, **options))
        written.append(path)
    return written


# LINE_FIGURES' drawing functions, (res, path) (fig3 also takes the factor)
LINE_FIGURE_FUNCTIONS = {"fig3_deformed_contact.png": fig3_deformed_contact,
                         "fig4_tangential.png": fig4_tangential, "fig2_laws.png": fig2_laws,
                         "history.png": history, "forces.png": forces}
