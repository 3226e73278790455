"""The scaling model (app/studies/scaling.py) on runs made from a known model: the fit
recovers its exponents and serial parts, the prediction its times, and the phase that
stops scaling first is the one with a serial part."""
import numpy as np
import pytest

from vpcontact.studies import scaling

EXPONENT = {p: 1.0 + 0.05 * k for k, p in enumerate(scaling.PHASES)}
SERIAL = dict.fromkeys(scaling.PHASES, 0.0) | {"outputs": 0.3, "Jacobian assembly": 0.05}
BASE = {p: 10.0 + k for k, p in enumerate(scaling.PHASES)}   # seconds at 1e5 dofs


def _run(dofs, ranks):
    row = {p: BASE[p] * (dofs / 1e5) ** EXPONENT[p]
           * (SERIAL[p] + (1 - SERIAL[p]) / ranks) for p in scaling.PHASES}
    row.update(dofs=dofs, ranks=ranks, cg=int(round(500 * (dofs / 1e5) ** 0.2)))
    return row


def _summary(row):
    """A summary.json with the row's times, the inverse of scaling.phases."""
    petsc = {"Krylov solves": row["Krylov solves"],
             "preconditioner set-up": row["preconditioner set-up"],
             "residual assembly": row["residual assembly"],
             "Jacobian assembly": row["Jacobian assembly"]}
    loop = sum(petsc.values()) + row["other SNES work"] + row["outputs"]
    return {"phases": {"petsc": petsc, "stages": {"solve": loop - row["outputs"],
                                                  "outputs": row["outputs"]}},
            "setup_s": row["set-up"], "loop_s": loop,
            "wall_s": row["set-up"] + loop + row["before the loop"],
            "mesh": {"dofs": row["dofs"]}, "mpi_ranks": row["ranks"],
            "steps": [{"linear_iterations": row["cg"]}]}


def test_fit_recovers_the_model_and_predicts_its_times():
    rows = [scaling.phases(_summary(_run(d, r))) for d in (1e5, 3e5, 8e5) for r in (1, 2)]
    model = scaling.fit(rows)
    assert model["ref"]["dofs"] == 8e5
    for p in scaling.PHASES:
        assert model["exponent"][p] == pytest.approx(EXPONENT[p], rel=1e-9)
        assert model["serial"][p] == pytest.approx(SERIAL[p], abs=1e-9)
    assert model["cg_exponent"] == pytest.approx(0.2, rel=0.01)
    at = scaling.predict(model, 6.4e6, 64)
    want = _run(6.4e6, 64)
    for p in scaling.PHASES:
        extra = 0.0 if p != "Krylov solves" else \
            want["cg"] * scaling.ALPHA * (2 * np.log2(64) + scaling.HALOS)
        assert at[p] == pytest.approx(want[p] + extra, rel=1e-3)
    assert at["total"] == pytest.approx(sum(at[p] for p in scaling.PHASES))


def test_the_phase_with_a_serial_part_stops_scaling_first():
    rows = [_run(d, r) for d in (1e5, 8e5) for r in (1, 2)]
    phase, ranks = scaling.first_to_stop(scaling.fit(rows), 6.4e6)
    assert phase == "outputs"
    # efficiency 1 / (P (s + (1 - s) / P)) < 1/2 from P = 4 (s = 0.3: 1 / 1.9) on, and
    # outputs take >= 10% of the total once the other phases have divided
    assert 4 <= ranks <= 64


def test_fit_refuses_too_few_runs():
    with pytest.raises(ValueError, match="two sizes"):
        scaling.fit([_run(1e5, 1), _run(1e5, 2)])
