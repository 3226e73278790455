"""The boundary layer's nodal forces (app/model/layer.py) against an assembly of the bulk
residual form (sigma, eps(v)) - f_n(v) over every cell, at the nodes the records read
(Dirichlet groups, Gamma3, the pairs' targets); and the loads assembled once when they do
not change with t (app/model/loadvector.py)."""
import copy

import numpy as np
import pytest
from dolfinx import fem
from petsc4py import PETSc

from conftest import ROOT, make_case, paper_raw, validate_raw
from vpcontact.model.pairs import surface_nodes
from vpcontact.observers import Observer
from vpcontact.post.quantities import bulk_residual


def _assembled(problem) -> np.ndarray:
    """(sigma, eps(v)) - f_n(v) over every cell, by dolfinx (owned nodes, d)."""
    b = fem.petsc.assemble_vector(fem.form(problem.forms.bulk_residual))
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    out = b.array_r.reshape(-1, problem.disc.dim).copy()
    b.destroy()
    return out


def _layer_nodes(problem) -> np.ndarray:
    """The owned nodes where the layer's r is exact."""
    d, owned = problem.disc.dim, problem.disc.V.dofmap.index_map.size_local
    nodes = [grp.dofs // d for grp in problem.disc.dirichlet.groups]
    if problem.disc.gamma3 is not None:
        nodes.append(problem.disc.gamma3.nodes)
    for pair in problem.case.contact.pairs:
        target = surface_nodes(problem.disc, pair.target)
        nodes.append(target[target < owned])
    return np.unique(np.concatenate(nodes))


class _Compare(Observer):
    """The largest relative difference of every step."""

    def __init__(self):
        self.errors = []

    def step(self, sim, record):
        p = sim.problem
        nodes = _layer_nodes(p)
        ref = _assembled(p)[nodes]
        self.errors.append(np.abs(bulk_residual(p)[nodes] - ref).max() / np.abs(ref).max())


def _run(case):
    from mpi4py import MPI

    from vpcontact.simulation import run
    obs = _Compare()
    res = run(case, MPI.COMM_WORLD, [obs])
    assert res.status == "completed" and len(obs.errors) == case.time.N
    return res, max(obs.errors)


def _raw(name, **time):
    from vpcontact.case import load_raw
    raw = load_raw(ROOT / "cases" / f"{name}.yaml")
    raw["time"].update(time)
    return raw


def test_paper_case_layer_equals_assembly_and_loads_assembled_once():
    res, err = _run(make_case(mesh={"n": 8}, time={"N": 4}, solver={"method": "fast"}))
    assert err < 1e-12
    assert res.problem.load_vector.timed is False
    assert res.problem.load_vector.assemblies == 1       # constant tractions: once per run


def test_time_dependent_loads_are_assembled_at_every_step():
    raw = _raw("memory", N=4)                             # top traction from a table in t
    raw["mesh"]["n"] = 8
    res, err = _run(validate_raw(raw))
    assert err < 1e-12
    assert res.problem.load_vector.timed is True
    assert res.problem.load_vector.assemblies == 4       # the steps (t0's none: no solve)


def test_implicit_variant():
    raw = copy.deepcopy(paper_raw())
    raw["mesh"]["n"] = 8
    raw["time"].update(N=3, scheme="implicit")
    raw["solver"]["method"] = "snes_vi"
    res, err = _run(validate_raw(raw))
    assert res.problem.implicit and err < 1e-12


@pytest.mark.parametrize("name, time", [("orthotropic_box", {"N": 2}),
                                        ("box3d", {"N": 2}),
                                        ("punch_on_substrate", {"N": 3, "T": 0.15})])
def test_scenes(name, time):
    """Anisotropic E in 3D; the 3D box; two bodies with Coulomb friction (its fixed point
    reads the forces between solves), materials, a pressure ramp and prescribed
    displacements."""
    from vpcontact.case import load_case
    sets = [f"time.{k}={v}" for k, v in time.items()] + (["mesh.n=4"] if name == "box3d" else [])
    _, err = _run(load_case(ROOT / "cases" / f"{name}.yaml", overrides=sets))
    assert err < 1e-11
