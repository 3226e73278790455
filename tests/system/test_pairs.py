"""Two bodies in contact (contact.pairs), against independent references:

- symmetry: two mirror-image blocks (mirror meshes, checked here) pressed together by
  mirror-image displacements of their outer sides, frictionless, with normal compliance c
  and the bound [u]_nu <= g, equal one block against a rigid plane at the mid-plane with
  compliance 2 c and the bound u_nu <= g / 2 (node to segment: on matching meshes it is
  exact), to 1e-8 of the displacement, 2D and 3D;
- a rigid limit: with Coulomb friction and a shear, the upper block on a lower block 1e6
  times stiffer (the default mortar rule) equals the block on the rigid foundation to 1e-5;
- the contact patch test: two stacked blocks of non-matching meshes (cells 1/7 and 1/4)
  under a uniform compression: the mortar rule gives the uniform interface pressure
  E' eps (plane strain, sigma_xx = 0) to 1e-9 with the finer side as the surface and to
  5e-4 with the coarser one (3D, cells 1/5 and 1/3: 5e-4); the node-to-segment rule misses
  it by more than 2 %;
- the refusals of contact.pairs.
"""
import numpy as np
import pytest

from conftest import make_case, run_case
from vpcontact.post.quantities import contact_table

E, NU, C, G, DELTA = 1000.0, 0.3, 500.0, 0.004, 0.003
E_PLANE = E / (1 - NU ** 2)

_BLOCK_2D = """
Point({a}) = {{0, 0, 0}}; Point({b}) = {{1, 0, 0}}; Point({c}) = {{1, {s}, 0}};
Point({d}) = {{0, {s}, 0}};
Line({a}) = {{{a}, {b}}}; Line({b}) = {{{b}, {c}}}; Line({c}) = {{{c}, {d}}};
Line({d}) = {{{d}, {a}}};
Curve Loop({a}) = {{{a}, {b}, {c}, {d}}}; Plane Surface({a}) = {{{a}}};
Transfinite Curve {{{a}, {b}, {c}, {d}}} = 7;
Transfinite Surface {{{a}}} = {{{a}, {b}, {c}, {d}}} Right;
Physical Surface("{name}", {a}) = {{{a}}};
Physical Curve("{name}_inner", {a}) = {{{a}}}; Physical Curve("{name}_outer", {c}) = {{{c}}};
Physical Curve("{name}_sides", {b}) = {{{b}, {d}}};
"""


def _geo_2d(path, bodies):
    """Blocks [0, 1] x [0, s] (s = +1 upper, -1 lower: mirror images, corners listed in
    mirrored order so the transfinite meshes are mirror images)."""
    text = "Geometry.AutoCoherence = 0;\n" + "".join(
        _BLOCK_2D.format(a=10 * i + 1, b=10 * i + 2, c=10 * i + 3, d=10 * i + 4, s=s,
                         name=name) for i, (name, s) in enumerate(bodies))
    path.write_text(text)
    return str(path)


# the Kuhn subdivision of the unit cube into 6 tetrahedra (conforming between cubes)
_KUHN = [(0, 1, 3, 7), (0, 1, 5, 7), (0, 2, 3, 7), (0, 2, 6, 7), (0, 4, 5, 7), (0, 4, 6, 7)]


def _cube_msh(bodies, n=3) -> str:
    """A gmsh 2.2 .msh of unit cubes [0, 1]^2 x [0, s] (s = +1 upper, -1 lower: the lower
    one the mirror image of the upper, node for node), n^3 hexahedra of 6 tetrahedra each,
    groups <name> (cells), <name>_inner (z = 0), <name>_outer (z = s), <name>_sides."""
    nodes, tets, tris = [], [], []
    for b, (_, s) in enumerate(bodies):
        g = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1) + len(nodes) + 1
        nodes += [(i / n, j / n, s * k / n) for i in range(n + 1) for j in range(n + 1)
                  for k in range(n + 1)]
        for i, j, k in np.ndindex(n, n, n):
            corner = [g[i + a, j + c, k + e] for e in (0, 1) for c in (0, 1) for a in (0, 1)]
            tets += [(10 * b + 1, [corner[v] for v in t]) for t in _KUHN]
        for _, t in tets[-6 * n ** 3:]:
            for face in ([t[0], t[1], t[2]], [t[0], t[1], t[3]], [t[0], t[2], t[3]],
                         [t[1], t[2], t[3]]):
                xs = np.array([nodes[v - 1] for v in face])
                for role, axis, val in ((2, 0, 0.0), (2, 0, 1.0), (2, 1, 0.0), (2, 1, 1.0),
                                        (1, 2, 0.0), (3, 2, float(s))):
                    if np.allclose(xs[:, axis], val):
                        tris.append((10 * b + 1 + role, face))
    phys = [(3, 10 * b + 1, name) for b, (name, _) in enumerate(bodies)]
    phys += [(2, 10 * b + 1 + r, f"{name}_{w}") for b, (name, _) in enumerate(bodies)
             for r, w in ((1, "inner"), (2, "sides"), (3, "outer"))]
    out = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", str(len(phys))]
    out += [f'{d} {t} "{nm}"' for d, t, nm in phys] + ["$EndPhysicalNames", "$Nodes",
                                                          str(len(nodes))]
    out += [f"{i} {x!r} {y!r} {z!r}" for i, (x, y, z) in enumerate(nodes, 1)]
    elems = [(2, t, f) for t, f in tris] + [(4, t, f) for t, f in tets]
    out += ["$EndNodes", "$Elements", str(len(elems))]
    out += [f"{i} {kind} 2 {tag} {tag} " + " ".join(map(str, f))
            for i, (kind, tag, f) in enumerate(elems, 1)]
    return "\n".join(out + ["$EndElements"]) + "\n"


def _geo_3d(path, bodies):
    path = path.with_suffix(".msh")
    path.write_text(_cube_msh(bodies))
    return str(path)


def _raw(mesh_file, dim, materials, contact, loads, N=1):
    elastic = {"E": E, "nu": NU, **({"plane": "strain"} if dim == 2 else {})}
    return {"mesh": {"file": mesh_file, "dim": dim},
            "materials": {name: {**elastic, **m} for name, m in materials.items()},
            "boundaries": {"clamped": []}, "contact": contact, "loads": loads,
            "time": {"T": 1.0, "N": N}, "solver": {"method": "snes_vi"}}


def _push(dim: int, sign: int) -> list:
    """The outer side's displacement: -sign DELTA (1 + x) normal to it (nonuniform: part of
    the interface reaches the bound, part stays in the compliance)."""
    return [0.0] * (dim - 1) + [f"{-sign * DELTA!r} * (1 + x) * t"]


def _upper_u(result, dim: int) -> dict:
    """u at the upper block's nodes (y or z >= 0), keyed by rounded coordinates."""
    p = result.problem
    x = p.disc.V.tabulate_dof_coordinates()[:, :dim]
    u = p.u.x.array.reshape(-1, dim)
    keep = x[:, -1] >= 0
    # the interface y = 0 has a node of each body: the upper one is where u_y < 0 ...
    out = {}
    for xi, ui in zip(x[keep], u[keep]):
        key = tuple(np.round(xi, 9) + 0.0)
        out.setdefault(key, []).append(ui)
    return out


def _mirror_pair_and_plane(tmp_path, dim):
    geo = _geo_2d if dim == 2 else _geo_3d
    pair_file = geo(tmp_path / f"pair{dim}.geo", [("upper", 1), ("lower", -1)])
    one_file = geo(tmp_path / f"one{dim}.geo", [("upper", 1)])
    laws = {"normal_compliance": {"c_nu": C}}
    pair = _raw(pair_file, dim, {"upper": {}, "lower": {}},
                {"pairs": [{"surface": "upper_inner", "target": "lower_inner", "g": G,
                            "rule": "node_to_segment", **laws}]},
                {"displacement": {"upper_outer": _push(dim, 1),
                                  "lower_outer": _push(dim, -1)}})
    down = [0.0] * (dim - 1) + [-1.0]
    plane = _raw(one_file, dim, {"upper": {}},
                 {"g": G / 2, "direction": down, "normal_compliance": {"c_nu": 2 * C}},
                 {"displacement": {"upper_outer": _push(dim, 1)}})
    plane["boundaries"]["contact"] = ["upper_inner"]
    return pair, plane


@pytest.mark.parametrize("dim, scheme", [(2, None), (3, None), (2, "implicit")])
def test_mirror_pair_equals_rigid_plane(tmp_path, dim, scheme):
    """(2D implicit: both blocks Perzyna, the right-end-point scheme: the pair's Newton
    matrix is P^T J P with the algorithmic tangent J assembled at every iteration.)"""
    pair, plane = _mirror_pair_and_plane(tmp_path, dim)
    if scheme is not None:
        law = {"viscoplastic": {"lambda1": 100.0, "lambda2": 100.0, "kappa0": 2.0}}
        for raw in (pair, plane):
            raw["time"].update(scheme=scheme, N=3)
            for m in raw["materials"].values():
                m.update(law)
    two = run_case(make_case(pair))
    one = run_case(make_case(plane))
    assert two.status == one.status == "completed"
    gap = contact_table(one.problem)["u_nu"]
    assert (gap > 0.99 * G / 2).any() and (gap < 0.9 * G / 2).any()   # bound and compliance
    ref = _upper_u(one, dim)
    got = _upper_u(two, dim)
    scale = max(np.abs(v).max() for vs in ref.values() for v in vs)
    worst = 0.0
    for key, (u_ref,) in ref.items():
        # at the interface the pair's mesh has both bodies' nodes: the upper one is the
        # mirror image of the lower one (same x, opposite normal component)
        cand = got[key]
        best = min(np.abs(c - u_ref).max() for c in cand)
        worst = max(worst, best)
    assert worst <= 1e-8 * scale
    # the lower block is the mirror image of the upper one
    p = two.problem
    x = p.disc.V.tabulate_dof_coordinates()[:, :dim]
    u = p.u.x.array.reshape(-1, dim)
    flip = np.ones(dim)
    flip[-1] = -1
    lower = x[:, -1] < -1e-9
    for xi, ui in zip(x[lower], u[lower]):
        mirrored = ref[tuple(np.round(xi * flip, 9) + 0.0)][0] * flip
        assert np.abs(ui - mirrored).max() <= 1e-8 * scale


def test_stiff_lower_body_is_the_rigid_foundation(tmp_path):
    """Coulomb friction, compliance and the bound, pressed and sheared: the upper block on
    a lower block 1e6 times stiffer (mortar) equals the block on the rigid foundation."""
    pair_file = _geo_2d(tmp_path / "stiff.geo", [("upper", 1), ("lower", -1)])
    one_file = _geo_2d(tmp_path / "one.geo", [("upper", 1)])
    laws = {"normal_compliance": {"c_nu": 2 * C}, "friction": {"coulomb": {"mu": 0.3}}}
    push = {"upper_outer": [f"{0.5 * DELTA!r} * t", f"{-DELTA!r} * (1 + x) * t"]}
    pair = _raw(pair_file, 2, {"upper": {}, "lower": {"E": 1e6 * E}},
                {"pairs": [{"surface": "upper_inner", "target": "lower_inner", "g": G / 2}],
                 **laws}, {"displacement": push}, N=2)
    pair["boundaries"]["clamped"] = ["lower_outer"]
    plane = _raw(one_file, 2, {"upper": {}}, {"g": G / 2, "direction": [0.0, -1.0], **laws},
                 {"displacement": push}, N=2)
    plane["boundaries"]["contact"] = ["upper_inner"]
    two, one = run_case(make_case(pair)), run_case(make_case(plane))
    assert two.status == one.status == "completed"
    # Coulomb's second fixed-point solve cycles in plain Newton (between 0.42 and 0.50):
    # stopped once the residual repeats itself, not after 50 (214 iterations before, 171)
    assert sum(s["newton_iterations"] for s in two.summary["steps"]) <= 190
    tab = contact_table(one.problem)
    assert (tab["slip_state"] == 1).any() and (np.abs(tab["u_tau"]) > 1e-4).any()
    ref, got = _upper_u(one, 2), _upper_u(two, 2)
    scale = max(np.abs(v).max() for vs in ref.values() for v in vs)
    worst = max(min(np.abs(c - u_ref).max() for c in got[key])
                for key, (u_ref,) in ref.items())
    assert worst <= 1e-5 * scale


def _patch(surface: str, target: str, rule: str, dim: int = 2):
    """The interface pressure of the patch test relative to E' eps, minus 1, per node."""
    from pathlib import Path
    mesh = str(Path(__file__).parents[1] / "data" / f"patch{dim}d.geo")
    free = [None] * dim
    hold = {f"{body}_left": [0.0] + free[1:] for body in ("lower", "upper")}
    if dim == 3:
        hold.update({f"{body}_front": [None, 0.0, None] for body in ("lower", "upper")})
    raw = _raw(mesh, dim, {"upper": {}, "lower": {}},
               {"pairs": [{"surface": surface, "target": target, "rule": rule}]},
               {"displacement": {"lower_bottom": free[1:] + [0.0], **hold,
                                 "upper_top": free[1:] + ["-0.01 * t"]}})
    result = run_case(make_case(raw))
    assert result.status == "completed"
    tab = contact_table(result.problem)
    assert (tab["u_nu"] > -1e-12).all()                 # every node on the bound
    return tab["neg_sigma_nu"] / ((E_PLANE if dim == 2 else E) * 0.005) - 1.0


def test_contact_patch_test():
    """Uniform compression of two stacked blocks of non-matching meshes: the interface
    pressure is E' eps everywhere (eps = 0.01 / 2; E' = E / (1 - nu^2) in plane strain,
    E in 3D, the lateral sides free)."""
    assert np.abs(_patch("lower_top", "upper_bottom", "mortar")).max() <= 1e-9
    assert np.abs(_patch("upper_bottom", "lower_top", "mortar")).max() <= 5e-4
    assert np.abs(_patch("upper_bottom", "lower_top", "node_to_segment")).max() >= 0.02
    # 3D: the composite rule is not exact inside the surface triangles (2.1e-4 measured)
    assert np.abs(_patch("lower_top", "upper_bottom", "mortar", dim=3)).max() <= 5e-4


def test_restart_of_touching_bodies(tmp_path):
    """Two bodies touching at the start share interface coordinates: a checkpoint tells
    their nodes apart (the pair label), and a run restarted from step 2 (memory, slip
    friction, a viscoplastic upper block: every history) equals the uninterrupted run."""
    import shutil
    from pathlib import Path

    import yaml

    from conftest import cli_in_process, contact_rows
    raw = {"name": "touching",
           "mesh": {"file": str(Path(__file__).parents[1] / "data" / "patch2d.geo"),
                    "dim": 2},
           "materials": {"lower": {"E": E, "nu": NU, "plane": "strain"},
                         "upper": {"E": E, "nu": NU, "plane": "strain", "viscoplastic":
                                   {"lambda1": 50.0, "lambda2": 50.0, "kappa0": 0.5}}},
           "boundaries": {"clamped": ["lower_bottom"]},
           "contact": {"pairs": [{"surface": "lower_top", "target": "upper_bottom",
                                  "g": 0.002}],
                       "normal_compliance": {"c_nu": 2000.0}, "memory": {"b0": 100.0},
                       "friction": {"b": 0.5, "c1": 20.0, "c2": 20.0, "u1": 0.001,
                                    "slip": {"theta_inf": 0.5, "s0": 0.001}}},
           "loads": {"displacement": {"upper_left": [0.0, None], "upper_top": [
               "0.004 * t", "-0.01 * t"]}},
           "time": {"T": 1.0, "N": 4}, "output": {"checkpoint_every": 2}}
    case = tmp_path / "touching.yaml"
    case.write_text(yaml.safe_dump(raw))
    full, again = tmp_path / "full", tmp_path / "again"
    assert cli_in_process(["run", case, "--out", full, "--no-plots"]) == 0
    first = tmp_path / "first"
    shutil.copytree(full, first)
    (first / "checkpoint_000004.npz").unlink()
    assert cli_in_process(["run", case, "--restart", first, "--out", again,
                           "--no-plots"]) == 0
    (s1, a), (s2, b) = contact_rows(full), contact_rows(again)
    assert s1 == s2 and np.abs(a - b).max() <= 1e-12 * np.abs(a).max()


def test_a_runaway_iterate_is_not_converged():
    """The punch of punch_on_substrate without its symmetry roller: sideways only friction
    holds it, and with p_n = 0 in Coulomb's first iterate the Newton matrix is singular, so
    an iterate runs away (|u| ~ 1e10).  The residual's round-off floor, which grows with
    |x|, must not call that converged (it did: the run completed with |u_x| = 6.7e10 and
    half the load carried); the step goes on to the equilibrium: the contact force equals
    the pressure times the punch's half-width plus its weight (both in the case file)."""
    from pathlib import Path

    import yaml
    path = Path(__file__).parents[2] / "cases" / "punch_on_substrate.yaml"
    raw = yaml.safe_load(path.read_text())
    raw["mesh"]["file"] = str(path.parent / raw["mesh"]["file"])
    raw["mesh"]["size"] = 4.0
    raw["time"] = {"T": 0.1, "N": 2}
    raw["loads"]["displacement"] = {"substrate_sym": [0.0, None]}
    result = run_case(make_case(raw))
    assert result.status == "completed"
    u = result.problem.u.x.array
    assert np.abs(u).max() < 1e-2
    # the punch 0.5 x 0.5 less its corner under the fillet of radius 0.05, rho g = 0.01
    weight = 0.01 * (0.25 - (1 - np.pi / 4) * 0.05 ** 2)
    for step, pressure in zip(result.summary["steps"], (1.0, 2.0)):    # ramp to 2 Pa at 0.1
        assert abs(step["contact_force"][1] - (0.5 * pressure + weight)) < 1e-6


@pytest.mark.parametrize("name", ["two_cylinders", "mindlin", "punch_on_substrate"])
def test_shipped_pair_cases_validate_to_themselves(name):
    """The studies re-validate case.raw: a case whose pairs' laws were lifted into the
    contact section and whose boundaries.contact lists the surfaces is the same case."""
    from pathlib import Path

    from vpcontact.case import load_case, validate
    case = load_case(Path(__file__).parents[2] / "cases" / f"{name}.yaml")
    assert case.contact.pairs and validate(case.raw, case.source) == case
