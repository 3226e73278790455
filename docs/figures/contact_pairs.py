"""The figures of the two-body cases in docs/verification.md, from their results:

    ./vpcontact run cases/two_cylinders.yaml --out /tmp/two_cylinders
    ./vpcontact run cases/mindlin.yaml --out /tmp/mindlin
    .venv/bin/python docs/figures/contact_pairs.py /tmp/two_cylinders /tmp/mindlin

two_cylinders_hertz.png: the contact pressure of the last step against Hertz's half-ellipse
for the measured force (E* and R* of the two cylinders); mindlin_traction.png: the shear
traction of the last step against Cattaneo-Mindlin's, the nodes by slip_state (stick, slip,
separated).
"""
import csv
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).parents[2] / "tests"))
from references.contact_closed_forms import (  # noqa: E402
    hertz_cylinders,
    hertz_pressure,
    mindlin_shear,
    mindlin_stick_halfwidth,
)

HERE = Path(__file__).parent


def _table(out: Path) -> dict:
    with open(out / "contact.csv") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([r[k] for r in rows], dtype=float if k != "state" else object)
            for k in rows[0]}


def _force(out: Path) -> np.ndarray:
    return np.array(json.loads((out / "summary.json").read_text())["steps"][-1]
                    ["contact_force"])


def hertz(out: Path) -> None:
    """Pressure of two_cylinders (half model: P = 2 F_y) against Hertz."""
    t = _table(out)
    P = 2 * abs(_force(out)[1])
    a, p0 = hertz_cylinders(P, 1.0, 2.0, 1000.0, 0.3, 2000.0, 0.3, plane_strain=True)
    x = np.linspace(0, 1.2 * a, 300)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(x, hertz_pressure(x, a, p0), "k-", label=f"Hertz (P = {P:.3f} N/m)")
    on = t["x"] <= 1.3 * a
    ax.plot(t["x"][on], t["neg_sigma_nu"][on], "o", ms=4, label="vpcontact (mortar)")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("contact pressure [N/m^2]")
    ax.set_title("two_cylinders: R1 = 1, R2 = 2, E1 = 1000, E2 = 2000")
    ax.legend()
    fig.tight_layout()
    fig.savefig(HERE / "two_cylinders_hertz.png", dpi=100)


def mindlin(out: Path) -> None:
    """Shear traction of mindlin against Cattaneo-Mindlin (mu = 0.3)."""
    t = _table(out)
    F = _force(out)
    P, Q, mu = abs(F[1]), abs(F[0]), 0.3
    a, p0 = hertz_cylinders(P, 1.0, float("inf"), 1000.0, 0.3, 1000.0, 0.3,
                            plane_strain=True)
    c = mindlin_stick_halfwidth(a, Q, mu, P)
    x = np.linspace(-1.2 * a, 1.2 * a, 400)
    q = np.sign(np.sum(t["neg_sigma_tau"])) * mindlin_shear(x, a, c, p0, mu)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(x, q, "k-", label=f"Cattaneo-Mindlin (Q/(mu P) = {Q / (mu * P):.2f})")
    ax.plot(x, mu * hertz_pressure(x, a, p0) * np.sign(q.sum()), "k:", label="mu p")
    on = np.abs(t["x"]) <= 1.3 * a
    stick = on & (t["slip_state"] == 0)
    slip = on & (t["slip_state"] == 1)
    separated = on & (t["slip_state"] == -1)
    ax.plot(t["x"][slip], t["neg_sigma_tau"][slip], "o", ms=4, mfc="none", label="slip nodes")
    ax.plot(t["x"][stick], t["neg_sigma_tau"][stick], "o", ms=4, label="stick nodes")
    ax.plot(t["x"][separated], t["neg_sigma_tau"][separated], "x", ms=4, color="0.5",
            label="separated nodes")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("shear traction [N/m^2]")
    ax.set_title("mindlin: half-cylinder on a block, Coulomb mu = 0.3")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(HERE / "mindlin_traction.png", dpi=100)


if __name__ == "__main__":
    hertz(Path(sys.argv[1]))
    mindlin(Path(sys.argv[2]))
