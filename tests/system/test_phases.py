"""Where the loop's time goes (app/post/phases.py): summary.json's ``phases`` has every stage
of the loop and PETSc's events in the solves, consistent with the run's own clocks: the
stages lie within the loop's time, PETSc's residual and Jacobian callbacks within the solve
stage, the solve stage within the steps' solve times; the run log prints them."""
from conftest import make_case, run_case
from vpcontact.post.phases import PETSC_EVENTS, STAGES, phase_lines


def test_phases_of_a_snes_vi_run():
    s = run_case(make_case(mesh={"n": 8}, time={"T": 1.0, "N": 3})).summary
    phases = s["phases"]
    assert list(phases["stages"]) == list(STAGES)
    assert list(phases["petsc"]) == [name for name, _ in PETSC_EVENTS]
    stages, petsc = phases["stages"], phases["petsc"]
    assert all(v >= 0 for v in (*stages.values(), *petsc.values()))
    assert sum(stages.values()) <= s["loop_s"]
    # the solve stage is inside the steps' wall times (which also hold the history stages)
    assert 0 < stages["solve"] <= sum(st["wall_s"] for st in s["steps"])
    assert stages["viscoplastic history"] > 0 and stages["contact history"] == 0.0
    assert stages["records"] > 0                    # the norms and forces of every step
    # SNES VI's callbacks (our assembly) and its linear solves lie inside the solve stage
    assert 0 < petsc["residual assembly"] + petsc["Jacobian assembly"] <= stages["solve"]
    assert 0 < petsc["Krylov solves"] <= stages["solve"]
    lines = phase_lines(phases)
    assert lines[0].startswith("time per stage of the loop: viscoplastic history ")
    assert "residual assembly" in lines[1] and "contact history" not in lines[0]
