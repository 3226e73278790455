"""The cost of a user's scene against the built-in rectangle of the same size (`bench`).

The paper case runs twice with the fast solver: on the built-in n x n rectangle, and as a
user scene: the same unit square rotated by 30 degrees, written as a gmsh .geo (transfinite,
the same triangles), read through mesh.file, its boundary groups named, tractions rotated,
Gamma3's normals computed from the mesh and the Gamma3 problem solved in rotated nodal
frames.  Both are whole processes timed from outside (a warm-up run first, the fastest of
``repeat`` runs counts); the ratio is measured in the same bench run.  The two solve the same
problem rotated, so their final ||u||_V agree to the solver's tolerance (the difference is
reported).
"""
from __future__ import annotations

import math
from pathlib import Path

import yaml

from vpcontact.case import load_raw
from vpcontact.io.files import atomic_write
from vpcontact.studies.benchref import REFERENCE_TEXT, References, reference_cells

ANGLE = 30.0
_GEO = """// The unit square rotated by {angle} degrees about the origin, n x n transfinite.
Point(1) = {{0, 0, 0}};
Point(2) = {{{c}, {s}, 0}};
Point(3) = {{{cms}, {spc}, 0}};
Point(4) = {{{ms}, {c}, 0}};
Line(1) = {{1, 2}};
Line(2) = {{2, 3}};
Line(3) = {{3, 4}};
Line(4) = {{4, 1}};
Curve Loop(1) = {{1, 2, 3, 4}};
Plane Surface(1) = {{1}};
Transfinite Curve{{1, 2, 3, 4}} = {m};
Transfinite Surface{{1}} = {{1, 2, 3, 4}} Right;
Physical Curve("bottom", 2) = {{1}};
Physical Curve("right", 3) = {{2}};
Physical Curve("top", 4) = {{3}};
Physical Curve("left", 1) = {{4}};
Physical Surface("body", 10) = {{1}};
"""


def write_scene(case: Path, outdir: Path, n: int) -> Path:
    """Write the rotated paper scene (scene.geo and scene.yaml) into ``outdir``.

    Args:
        case: the paper case file (a built-in unit square).
        outdir: the directory to write into.
        n: cells per side.

    Returns:
        The scene's case file.
    """
    c, s = math.cos(math.radians(ANGLE)), math.sin(math.radians(ANGLE))
    outdir.mkdir(parents=True, exist_ok=True)
    atomic_write(outdir / "scene.geo", _GEO.format(angle=ANGLE, c=repr(c), s=repr(s),
                                                   cms=repr(c - s), spc=repr(s + c),
                                                   ms=repr(-s), m=n + 1))
    raw = load_raw(case)
    raw["name"] = "scene"
    raw["mesh"] = {"file": "scene.geo", "dim": 2}
    raw["boundaries"] = {"clamped": ["left"], "contact": ["bottom"]}
    raw["loads"]["traction"] = {side: [c * v[0] - s * v[1], s * v[0] + c * v[1]]
                                for side, v in raw["loads"].get("traction", {}).items()}
    atomic_write(outdir / "scene.yaml", yaml.safe_dump(dict(raw), sort_keys=False))
    return outdir / "scene.yaml"


def scene_rows(case: Path, outdir: Path, n: int, N: int, run, repeat: int = 1,
               log=print, references: References | None = None) -> list[dict]:
    """Time the built-in rectangle and the rotated user scene of the same size.

    Args:
        case: the paper case file.
        outdir: the bench directory (runs go to its ``runs``).
        n: cells per side (dofs 2 (n + 1)^2).
        N: time steps.
        run: bench's runner: run(case, out, overrides) -> (wall s, summary dict).
        repeat: timed runs of each (the fastest counts).
        log: called with one line per run.
        references: the bench run's reference solves (benchref.py; None: a new set).

    Returns:
        Two rows (builtin, scene), each with its wall time, also as ratios to the reference
        solve on its mesh; the scene row carries the ratio scene / builtin and the relative
        difference of the final ||u||_V.
    """
    references = references or References(log=log)
    scene = write_scene(case, outdir / "runs" / "scene", n)
    common = [f"time.N={N}", f"output.every={N}", "solver.method=fast"]
    rows = []
    for kind, path, over in (("builtin", case, [f"mesh.n={n}"]), ("scene", scene, [])):
        out = outdir / "runs" / f"scene_{kind}_n{n}_N{N}"
        try:
            run(path, out, over + ["time.N=1", "output.every=1", "solver.method=fast"])
            runs = [run(path, out, over + common) for _ in range(repeat)]
        except RuntimeError as exc:
            rows.append({"kind": kind, "n": n, "N": N,
                         "failed": str(exc).strip().splitlines()[-1][:300]})
            continue
        wall, s = min(runs, key=lambda r: r[0])
        rows.append({"kind": kind, "n": n, "N": N, "dofs": s["mesh"]["dofs"], "wall_s": wall,
                     "wall_runs_s": [r[0] for r in runs], "setup_s": s["setup_s"],
                     "loop_s": s["loop_s"], "newton_total": s["newton_iterations_total"],
                     "final_norm_u_V": s["steps"][-1]["norm_u_V"]})
        references.attach(rows[-1], path, over)
        log(f"  scene {kind:8s} n = {n}, N = {N}: {wall:.2f} s whole process, set-up "
            f"{s['setup_s']:.2f} s, steps {s['loop_s']:.2f} s")
    if len(rows) == 2 and not any("failed" in r for r in rows):
        b, u = rows
        u["ratio_scene_vs_builtin"] = u["wall_s"] / b["wall_s"]
        u["norm_u_V_rel_diff"] = abs(u["final_norm_u_V"] - b["final_norm_u_V"]) \
            / abs(b["final_norm_u_V"])
    return rows


def markdown(rows: list[dict]) -> list[str]:
    """bench.md's section of the scene rows.

    Args:
        rows: scene_rows' rows.

    Returns:
        The lines.
    """
    lines = ["", "## A user's scene against the built-in rectangle", "",
             f"The paper case on the built-in n x n rectangle and on the same square rotated by "
             f"{ANGLE:g} degrees, read from a gmsh .geo (mesh.file, named groups, computed "
             "normals, rotated nodal frames), fast solver; whole process, fastest of the "
             "repeats; difference = relative difference of the final ||u||_V. " + REFERENCE_TEXT,
             "", "| mesh | n | N | dofs | wall s | set-up s | steps s | Newton | scene / "
             "built-in | difference | reference s | wall / ref |", "|" + "---|" * 12]
    for r in rows:
        if "failed" in r:
            lines.append(f"| {r['kind']} | {r['n']} | {r['N']} | failed: {r['failed']} |"
                         + " |" * 8)
            continue
        ratio = r.get("ratio_scene_vs_builtin")
        diff = r.get("norm_u_V_rel_diff")
        lines.append(f"| {r['kind']} | {r['n']} | {r['N']} | {r['dofs']} | {r['wall_s']:.2f} | "
                     f"{r['setup_s']:.2f} | {r['loop_s']:.2f} | {r['newton_total']} | "
                     f"{f'{ratio:.2f}' if ratio else '-'} | {f'{diff:.1e}' if diff else '-'} | "
                     f"{' | '.join(reference_cells(r, ('wall_ratio',)))} |")
    return lines
