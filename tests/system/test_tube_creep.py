"""Steady creep of a thick-walled tube under internal pressure p (inner radius a, outer b), a
quarter annulus in plane strain with symmetry rollers on its straight edges and no contact
section, under Norton's law eps_vp' = A sigma_eq^n (3/2) dev(sigma) / sigma_eq.

At long times the stress stops changing, the creep strain rate is compatible and, the creep
being isochoric with eps_33 = 0, the hoop stress approaches Norton's steady state
    sigma_theta(r) = p [1 + (2/n - 1)(b/r)^(2/n)] / [(b/a)^(2/n) - 1]
(3D von Mises norm with the out-of-plane stress sigma_33 = (sigma_r + sigma_theta)/2).

- ``law: norton`` in plane strain carries sigma_33 = nu (sigma_11 + sigma_22) - E eps_vp33
  (kappa = (p, eps_vp33), app/model/norton.py, app/model/planestrain.py): the run reaches
  the closed form: sigma_theta averaged over the innermost and the outermost layer of cells
  is within 0.1 % of the closed form's average over the same layer (measured: -0.067 %
  inner, -0.058 % outer; with the paper's 2D norm, sigma_33 = 0 in ||sigma||_VM, the law
  missed it by +11.6 % / -8.3 %).
- The closed form itself is checked against an independent steady state: a shooting ODE in
  r (scipy's solve_ivp) of compatible creep rates with the 3D norm and eps_vp33' = 0.
- The shipped law's rates equal the recipe written here (``PlaneStrainNorton``: the 3D E,
  nu recovered from the plane-strain moduli, G = -2 mu eps_vp' in the plane).
- Norton states no rate bound valid at every stress for n > 1: before the run its
  indicator is the bound at the data's stress scale S = p, k n A p^(n-1) 3 mu = 0.69 for 25
  steps and 2.16 for 8 (app/post/diagnostics.py); the explicit run estimates it at every
  step (app/post/ratewatch.py): 1.68 at the end of the 25-step run (3.6 after its first,
  elastic, step: the hoop stress exceeds p), above 2 in the 8-step run, which blows up.

Mesh: 24 x 24 cells per quarter (transfinite, alternating diagonals: with one diagonal
direction the P1 triangles lock under isochoric creep, measured +84 % at the inner layer on
16 x 16; the error is mostly the polygonal arc: 24 x 12 gives -0.26 %); explicit scheme,
25 steps to T = 5 (with 8 steps the run diverges, with 12 it oscillates), 1 s per run.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from vpcontact.model.laws import ViscoplasticLaw

A_IN, B_OUT, P, A_NORTON, N_NORTON = 1.0, 2.0, 1.0, 1.0e-3, 3.0
NR, NT = 24, 24
TOL = 1e-3

GEO = f"""// quarter annulus a <= r <= b, x, y >= 0 (written by tests/system/test_tube_creep.py)
a = {A_IN}; b = {B_OUT}; nr = {NR}; nt = {NT};
Point(1) = {{0, 0, 0}}; Point(2) = {{a, 0, 0}}; Point(3) = {{b, 0, 0}};
Point(4) = {{0, b, 0}}; Point(5) = {{0, a, 0}};
Line(1) = {{2, 3}}; Circle(2) = {{3, 1, 4}}; Line(3) = {{4, 5}}; Circle(4) = {{5, 1, 2}};
Curve Loop(1) = {{1, 2, 3, 4}}; Plane Surface(1) = {{1}};
Transfinite Curve{{1, 3}} = nr + 1; Transfinite Curve{{2, 4}} = nt + 1;
Transfinite Surface{{1}} Alternate;
Physical Curve("symy", 1) = {{1}}; Physical Curve("outer", 2) = {{2}};
Physical Curve("symx", 3) = {{3}}; Physical Curve("inner", 4) = {{4}};
Physical Surface("body", 10) = {{1}};
"""


def closed_form(r):
    """Norton's steady hoop stress in plane strain (module docstring)."""
    q = 2.0 / N_NORTON
    return P * (1.0 + (q - 1.0) * (B_OUT / r) ** q) / ((B_OUT / A_IN) ** q - 1.0)


def steady_state_3d(r_eval):
    """The steady hoop stress written independently of the closed form: with the radial
    velocity v, eps_theta' = v / r and eps_r' = v' equal the creep rates, eps_33' = 0 makes
    sigma_33 = (s_r + s_theta)/2, so (3/2) dev gives A s^(n-1) (3/4)(s_theta - s_r) and
    -A s^(n-1) (3/4)(s_theta - s_r), s = (sqrt(3)/2) |s_theta - s_r| the 3D von Mises norm;
    equilibrium s_r' = (s_theta - s_r) / r; s_r(a) = -p, s_r(b) = 0 by shooting on v(a)."""
    n = N_NORTON

    def rate(d):                                  # the creep rate eps_theta' of d = st - sr
        return A_NORTON * (np.sqrt(3.0) / 2.0 * abs(d)) ** (n - 1) * 0.75 * d

    def difference(v, r):                         # d with rate(d) = v / r
        return brentq(lambda d: rate(d) - v / r, -100.0, 100.0, xtol=1e-14)

    def rhs(r, y):
        v, sr = y
        d = difference(v, r)
        return [-rate(d), d / r]

    def solve(v0):
        return solve_ivp(rhs, (A_IN, B_OUT), [v0, -P], rtol=1e-11, atol=1e-13,
                         dense_output=True)
    v0 = brentq(lambda v: solve(v).y[1, -1], 1e-6, 100.0, xtol=1e-14)
    sol = solve(v0).sol
    return np.array([sol(r)[1] + difference(sol(r)[0], r) for r in r_eval])


class PlaneStrainNorton(ViscoplasticLaw):
    """Norton's law in plane strain with the out-of-plane stress, written here independently
    of app/model/norton.py (a law of the Python API):
    kappa = (p, eps_vp33); with isochoric creep and eps_33 = 0, sigma_33 = nu (sigma_11 +
    sigma_22) - E eps_vp33 (E, nu the 3D constants); eps_vp' = A s^n (3/2) dev(sigma) / s
    with s the 3D von Mises norm; G = -2 mu eps_vp' in the plane (tr eps_vp' = 0)."""

    m = 2
    name = "norton with sigma_33 (test)"

    def __init__(self, elasticity, A: float, n: float):
        super().__init__(elasticity)
        self.A, self.n = A, n
        self.nu = elasticity.nu / (1.0 + elasticity.nu)       # from the plane-strain moduli
        self.E = elasticity.E * (1.0 - self.nu ** 2)

    def constants(self):
        """Returns: A, n."""
        return {"A": (self.A, "Pa^-n s^-1"), "n": (self.n, "-")}

    def rates(self, t, kappa):
        """G (n, 3) and (p', eps_vp33') (n, 2)."""
        s33 = self.nu * (t[:, 0] + t[:, 1]) - self.E * kappa[:, 1]
        mean = (t[:, 0] + t[:, 1] + s33) / 3.0
        d11, d22, d33, d12 = t[:, 0] - mean, t[:, 1] - mean, s33 - mean, t[:, 2]
        s = np.sqrt(1.5 * (d11 ** 2 + d22 ** 2 + d33 ** 2 + 2.0 * d12 ** 2))
        f = 1.5 * self.A * s ** (self.n - 1.0)
        G = -(self.E / (1.0 + self.nu)) * f[:, None] * np.stack([d11, d22, d12], axis=1)
        return G, np.stack([self.A * s ** self.n, f * d33], axis=1)


def _tube_case(folder, steps: int):
    """The case: the .geo in ``folder``, explicit scheme, ``steps`` steps to T = 5."""
    from vpcontact.case import validate
    raw = {"name": "tube", "mesh": {"file": "tube.geo"},
           "material": {"E": 1000.0, "nu": 0.3, "plane": "strain",
                        "viscoplastic": {"law": "norton", "A": A_NORTON, "n": N_NORTON}},
           "boundaries": {"clamped": []},
           "loads": {"pressure": {"inner": P},
                     "displacement": {"symy": [None, 0.0], "symx": [0.0, None]}},
           "time": {"T": 5.0, "N": steps}}
    return validate(raw, str(folder / "tube.yaml"))


@pytest.fixture(scope="module")
def tube_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("tube")
    (folder / "tube.geo").write_text(GEO)
    return folder


@pytest.fixture(scope="module")
def tube_case(tube_folder):
    return _tube_case(tube_folder, 25)


def _run(case, law=None):
    """(the hoop stress, the centroid radius, the area) per cell at T, summary.json."""
    from mpi4py import MPI

    from vpcontact.simulation import Simulation
    sim = Simulation(case, MPI.COMM_SELF, law=law)
    summary = sim.run().as_dict()
    assert summary["status"] == "completed"
    p = sim.problem
    nc = p.disc.mesh.topology.index_map(2).size_local
    xy = p.disc.mesh.geometry.x[:, :2][p.disc.mesh.geometry.dofmap.array.reshape(-1, 3)[:nc]]
    x = xy.mean(axis=1)
    e1, e2 = xy[:, 1] - xy[:, 0], xy[:, 2] - xy[:, 0]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    sig = p.sigma.x.array.reshape(-1, 2, 2)[:nc]
    th = np.arctan2(x[:, 1], x[:, 0])
    s, c = np.sin(th), np.cos(th)
    hoop = sig[:, 0, 0] * s * s + sig[:, 1, 1] * c * c - 2.0 * sig[:, 0, 1] * s * c
    return hoop, np.hypot(x[:, 0], x[:, 1]), area, summary


def _ring_errors(run, reference):
    """The relative error of sigma_theta averaged over the innermost and the outermost layer
    of cells (r in [a, a + dr] and [b - dr, b]) against the reference's average over the
    same layer, int s r dr / int r dr (Gauss-Legendre, 8 points)."""
    hoop, r, area, _ = run
    dr = (B_OUT - A_IN) / NR
    xg, wg = np.polynomial.legendre.leggauss(8)
    out = {}
    for name, r0 in (("inner", A_IN), ("outer", B_OUT - dr)):
        ring = (r > r0) & (r < r0 + dr)
        rq = r0 + 0.5 * dr * (xg + 1.0)
        exact = np.sum(wg * rq * reference(rq)) / np.sum(wg * rq)
        out[name] = float(np.sum(hoop[ring] * area[ring]) / np.sum(area[ring]) / exact - 1.0)
    return out


@pytest.fixture(scope="module")
def norton_run(tube_case):
    """law norton in plane strain, 25 steps."""
    return _run(tube_case)


def test_norton_closed_form(norton_run):
    """law norton in plane strain (sigma_33 carried) reaches the closed form."""
    err = _ring_errors(norton_run, closed_form)
    print(f"tube, law norton in plane strain: relative error of sigma_theta vs the closed "
          f"form: inner {err['inner']:+.2e}, outer {err['outer']:+.2e}")
    assert abs(err["inner"]) <= TOL and abs(err["outer"]) <= TOL, err


def test_closed_form_is_the_steady_state():
    """The closed form equals the steady state of the shooting ODE (3D norm, eps_vp33' = 0)."""
    r = np.linspace(A_IN, B_OUT, 7)
    np.testing.assert_allclose(steady_state_3d(r), closed_form(r), rtol=1e-8)


def test_the_shipped_law_is_the_recipe(tube_case):
    """The rates of law norton in plane strain (G, p', eps_vp33') equal PlaneStrainNorton's
    on random stresses and out-of-plane creep strains, n = 3 and n = 1."""
    from vpcontact.forms.elasticity import plane_strain_moduli
    from vpcontact.model.lawregistry import viscoplastic_law
    from vpcontact.model.material import Elasticity
    case = tube_case
    el = Elasticity(*plane_strain_moduli(case.material.E, case.material.nu), 2)
    rng = np.random.default_rng(3)
    t, kappa = rng.normal(size=(20, 3)), rng.normal(size=(20, 2)) * 1e-3
    for n in (N_NORTON, 1.0):
        vp = case.material.viscoplastic
        vp = replace(vp, constants={**vp.constants, "n": n})
        shipped = viscoplastic_law(vp, el, case.material.plane)
        G, Gk = shipped.rates(t, kappa)
        Gr, Gkr = PlaneStrainNorton(el, A_NORTON, n).rates(t, kappa)
        assert shipped.m == 2
        np.testing.assert_allclose(G, Gr, rtol=0, atol=1e-13 * np.abs(Gr).max())
        np.testing.assert_allclose(Gk, Gkr, rtol=0, atol=1e-13 * np.abs(Gkr).max())


def test_the_estimated_indicator_follows_the_explicit_limit(tube_folder, norton_run):
    """Norton states no rate bound valid at every stress: before the run its bound at the
    data's stress scale S = p, k r(S) = k n A p^(n-1) 3 mu, is 0.69 at 25 steps (stable)
    and 2.16 at 8 steps (unstable); the run estimates k r at every step (app/post/
    ratewatch.py).  At 25 steps the steady state's is below the explicit limit 2 (the run
    converges); at 8 steps it exceeds it and the run blows up."""
    from mpi4py import MPI

    from vpcontact.simulation import run
    d = norton_run[3]["diagnostics"]
    rate = N_NORTON * A_NORTON * P ** (N_NORTON - 1) * 3 * 1000.0 / (2 * 1.3)   # r(S = p)
    assert d["indicator_source"] == "stress_scale" and d["stress_scale"] == pytest.approx(P)
    assert d["stability_indicator"] == pytest.approx(0.2 * rate, rel=1e-12)      # 0.692
    assert d["explicit_stable"] is True
    assert d["estimated_indicator_last"] < 2.0 < d["estimated_indicator_max"]
    assert d["estimated_indicator_step"] == 1               # the elastic response: stiffest
    res = run(_tube_case(tube_folder, 8), MPI.COMM_SELF)
    coarse = res.summary["diagnostics"]
    print(f"tube, estimated k r: 25 steps: last {d['estimated_indicator_last']:.3g}, "
          f"largest {d['estimated_indicator_max']:.3g}; 8 steps: {res.summary['status']}, "
          f"at step {coarse['estimated_indicator_step']}: {coarse['estimated_indicator_max']:.3g}")
    assert coarse["estimated_indicator_max"] > 2.0
    assert coarse["stability_indicator"] == pytest.approx(0.625 * rate, rel=1e-12)  # 2.16
    assert coarse["explicit_stable"] is False
    assert res.status == "diverged"
