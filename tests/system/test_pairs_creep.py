"""Creep of a viscoplastic punch on an elastic substrate under a held load
(cases/punch_on_substrate.yaml, coarse: mesh.size 3, 8 steps of k = 0.08):

- the punch is held vertically only by the contact pair (the rigid-motion rule of
  app/model/dirichlet.py): the run is accepted and logs it;
- under the held load the contact area grows (the bound nodes never decrease and end with
  more than at the end of the ramp), the pressure relaxes near the fillet (the peak at the
  moving contact edge drops when a node enters and never again reaches its value at the
  end of the ramp; inside the ramp's contact zone the largest pressure falls by > 15 %), and every
  step is in vertical equilibrium: the contact force on the punch equals the pressure's
  resultant p(t) w plus the punch's weight rho g |punch| (the area summed from the mesh's
  triangles here), to the solver's tolerance;
- mpirun -n 2 equals the serial run: u at every vertex at T to 1e-8 relative (at this
  mesh size the partitioner puts the punch on one rank and splits the substrate's target
  facets between both: 31 / 0 surface facets, 9 / 29 target facets, checked when written);
- the rule: a part that carries no pair group is still refused with the message of a case
  without pairs, and so is a part whose pair leads to no held part.
"""
import h5py
import numpy as np
import pytest
import yaml

from conftest import ROOT, make_case, run_cli
from vpcontact.io.errors import CaseError
from vpcontact.io.output import gather_contact_table
from vpcontact.model.dirichlet import check_rigid_motions
from vpcontact.observers import Observer
from vpcontact.post.quantities import contact_table

CASE = ROOT / "cases" / "punch_on_substrate.yaml"
SETS = {"mesh.size": 3.0, "time.T": 0.64, "time.N": 8}
W, P, RAMP, RHO_G = 0.5, 2.0, 0.1, 0.01      # the case's half-width, pressure, ramp, weight


class _Contact(Observer):
    """The gathered contact table and the contact force of every step."""

    def __init__(self):
        self.steps = []

    def step(self, sim, record):
        c = sim.case.contact
        data = gather_contact_table(sim.comm, contact_table(sim.problem), c.g,
                                    compliance=c.compliance)
        self.steps.append((sim.t, data, np.array(record["contact_force"])))


def _raw() -> dict:
    raw = yaml.safe_load(CASE.read_text())
    raw["mesh"]["file"] = str(ROOT / "cases" / raw["mesh"]["file"])
    raw["mesh"]["size"] = SETS["mesh.size"]
    raw["time"].update(T=SETS["time.T"], N=SETS["time.N"])
    return raw


@pytest.fixture(scope="module")
def serial():
    """The coarse case run in this process, with its contact table per step."""
    from mpi4py import MPI

    from vpcontact.simulation import run
    obs = _Contact()
    result = run(make_case(_raw()), MPI.COMM_WORLD, [obs])
    assert result.status == "completed"
    return result, obs.steps


def _punch_area(problem) -> float:
    """|punch| from the mesh: the triangles of the cells tagged "punch"."""
    body = problem.disc.body
    cells = body.cell_tags.indices[body.cell_tags.values == body.cell_groups["punch"]]
    geo = problem.disc.mesh.geometry
    tri = geo.x[np.array([geo.dofmap.links(c) for c in cells])][:, :, :2]
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    return float(np.sum(np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])) / 2)


def test_contact_grows_pressure_relaxes_equilibrium(serial):
    result, steps = serial
    t = np.array([s[0] for s in steps])
    bound = np.array([np.sum(s[1]["state"] == "bound") for s in steps])
    peak = np.array([s[1]["neg_sigma_nu"].max() for s in steps])
    held = np.flatnonzero(t >= RAMP)
    assert np.all(np.diff(bound) >= 0)
    assert bound[-1] > bound[held[0]]
    grown = held[bound[held] > bound[held[0]]]
    assert np.all(peak[grown] < peak[held[0]])          # after the area grew: never above
    first = steps[held[0]][1]                           # inside the contact of the ramp's end
    inner = first["x"] < first["x"][first["state"] == "bound"].max() - 1e-9
    assert steps[-1][1]["neg_sigma_nu"][inner].max() < 0.85 * first["neg_sigma_nu"][inner].max()
    weight = RHO_G * _punch_area(result.problem)
    for ti, _, force in steps:
        load = P * W * min(ti / RAMP, 1.0) + weight
        assert force[1] == pytest.approx(load, rel=1e-9)


def test_mpirun_equals_serial(serial, tmp_path):
    result, _ = serial
    out = tmp_path / "np2"
    sets = [a for k, v in SETS.items() for a in ("--set", f"{k}={v}")]
    proc = run_cli(["run", CASE, "--out", out, "--quiet", *sets], nprocs=2)
    assert proc.returncode == 0, proc.stderr
    with h5py.File(out / "solution.h5", "r") as f:
        last = max(f["Function/u"].keys(), key=lambda k: float(k.replace("_", ".")))
        x2, u2 = f["Mesh/mesh/geometry"][:, :2], f[f"Function/u/{last}"][:, :2]
    V = result.problem.disc.V
    x1 = V.tabulate_dof_coordinates()[:, :2]
    u1 = result.problem.u.x.array.reshape(-1, 2)
    # the punch's and the substrate's nodes on y = 0 may share coordinates: ties by u
    order = [np.lexsort((u[:, 0], u[:, 1], np.round(x[:, 1], 9), np.round(x[:, 0], 9)))
             for x, u in ((x1, u1), (x2, u2))]
    np.testing.assert_array_equal(np.round(x1[order[0]], 9), np.round(x2[order[1]], 9))
    scale = np.abs(u1).max()
    np.testing.assert_allclose(u2[order[1]], u1[order[0]], rtol=0, atol=1e-8 * scale)


def _pair_facets(disc, *names) -> list:
    return [tuple(disc.facets[n] if n in disc.facets else disc.body.facet_tags.indices[
        disc.body.facet_tags.values == disc.body.groups[n]] for n in names)]


def test_rule_only_for_parts_tied_to_a_held_part(serial, caplog):
    """The punch (free in y) passes with its pair, with an INFO line; without the pair, or
    with a 'pair' that does not touch the punch, the same refusal as before; with the
    substrate's clamp dropped too, neither part is held and the punch is refused."""
    disc = serial[0].problem.disc
    V, fixed = disc.V, disc.dirichlet.fixed
    pairs = _pair_facets(disc, "punch_bottom", "substrate_top_contact")
    with caplog.at_level("INFO", logger="vpcontact"):
        check_rigid_motions(V, fixed, "src", pairs)
    assert "(like translation y) held only by contact pair 0 (contact.pairs[0])" in caplog.text
    with pytest.raises(CaseError) as plain:
        check_rigid_motions(V, fixed, "src")
    assert "boundaries.clamped / loads.displacement: the prescribed displacements leave 1 " \
        "rigid motion(s) of part" in str(plain.value)
    assert "(like translation y)" in str(plain.value)
    elsewhere = _pair_facets(disc, "substrate_top_free", "substrate_top_contact")
    with pytest.raises(CaseError) as other:
        check_rigid_motions(V, fixed, "src", elsewhere)
    assert str(other.value) == str(plain.value)
    loose = fixed.copy()
    loose[disc.dirichlet.clamped_nodes] = False
    with pytest.raises(CaseError) as none:
        check_rigid_motions(V, loose, "src")
    with pytest.raises(CaseError) as both:
        check_rigid_motions(V, loose, "src", pairs)
    assert str(both.value) == str(none.value)
