"""The scaling figure of docs/performance.md (section 7, "Scaling model"), from the table of
per-phase times in that section (the re-measured one, the first table after its heading):

    .venv/bin/python docs/figures/scaling.py

scaling.png: left, the measured whole-process time and the two largest phases (Krylov
solves, preconditioner set-up) of box3d, 8 steps, SNES VI with CG + GAMG, against the dofs
on 1 and 2 ranks, with the model's serial extrapolation to n = 128; right, the model's
prediction of every phase at n = 128 (6,440,067 dofs) against the ranks, fitted as the
section says (serial runs n = 24-64, the two-rank run at n = 64; app/studies/scaling.py).
The script prints the predicted totals: the section's table's to the rounding of the
measured times the table shows (0.1 s; the parts s_p come from ratios of such times), within 2%.
"""
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).parents[2]
sys.path.insert(0, str(ROOT))
from app.studies.scaling import PHASES, first_to_stop, fit, predict  # noqa: E402

HERE = Path(__file__).parent
HEADING = "### Scaling model"
N128 = 6_440_067                     # box3d n = 128: 3 (n + 1)^3
RANKS = (1, 2, 4, 8, 16, 32, 64, 128, 256)
# the table's columns after n, dofs, ranks (docs/performance.md)
COLUMNS = ("whole", "set-up", "before the loop", "Krylov solves", "preconditioner set-up",
           "residual assembly", "Jacobian assembly", "other SNES work", "outputs", "newton",
           "cg", "set-ups", "peak")


def measured_rows(doc: Path) -> list[dict]:
    """The rows of the first table after HEADING in ``doc``.

    Args:
        doc: docs/performance.md.

    Returns:
        One dict per run: n, dofs, ranks and COLUMNS.
    """
    lines = doc.read_text().splitlines()
    start = lines.index(HEADING)
    rows, inside = [], False
    for line in lines[start:]:
        if line.startswith("| n | dofs | ranks"):
            inside = True
            continue
        if inside and line.startswith("|---"):
            continue
        if inside and not line.startswith("|"):
            break
        if inside:
            cells = [c.strip().replace(",", "") for c in line.strip("|").split("|")]
            row = dict(zip(("n", "dofs", "ranks"), map(int, cells[:3])))
            row.update(zip(COLUMNS, map(float, cells[3:])))
            rows.append(row)
    return rows


def main() -> None:
    """Draw scaling.png and print the model's predicted totals at n = 128."""
    rows = measured_rows(ROOT / "docs" / "performance.md")
    model = fit([r for r in rows if r["n"] >= 24])
    at = {p: predict(model, N128, p) for p in RANKS}
    print("predicted totals at n = 128:",
          ", ".join(f"{p} ranks {at[p]['total']:.1f} s" for p in (1, 16, 64, 256)))
    stop = first_to_stop(model, N128)
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.6))
    for ranks, marker in ((1, "o"), (2, "s")):
        mine = sorted((r for r in rows if r["ranks"] == ranks), key=lambda r: r["dofs"])
        dofs = [r["dofs"] for r in mine]
        for key, color in (("whole", "k"), ("Krylov solves", "tab:blue"),
                           ("preconditioner set-up", "tab:orange")):
            left.loglog(dofs, [r[key] for r in mine], marker + ("-" if ranks == 1 else "--"),
                        color=color, ms=4, label=f"{key}, {ranks} rank{'s' * (ranks > 1)}")
    serial = [r for r in rows if r["ranks"] == 1 and r["n"] >= 24]
    x = np.geomspace(serial[0]["dofs"], N128, 20)
    left.loglog(x, [predict(model, int(n), 1)["total"] for n in x], ":", color="0.4",
                label="model, 1 rank")
    left.set_xlabel("dofs")
    left.set_ylabel("time [s]")
    left.set_title("measured (box3d, 8 steps, SNES VI, CG + GAMG)", fontsize=10)
    left.legend(fontsize=7)
    for p in PHASES + ("total",):
        right.loglog(RANKS, [at[r][p] for r in RANKS], "k-" if p == "total" else "-",
                     lw=2 if p == "total" or (stop and p == stop[0]) else 1, label=p)
    if stop:
        right.axvline(stop[1], color="0.6", lw=0.8)
        right.text(stop[1], right.get_ylim()[1], f" {stop[0]}: below half\n its efficiency",
                   fontsize=7, va="top")
    right.set_xlabel("MPI ranks")
    right.set_ylabel("predicted time [s]")
    right.set_title(f"model, n = 128 ({N128:,} dofs)", fontsize=10)
    right.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    fig.savefig(HERE / "scaling.png", dpi=110)


if __name__ == "__main__":
    main()
