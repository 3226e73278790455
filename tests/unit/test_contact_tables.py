"""The general contact laws of app/model/contact_laws.py at the numpy level: a compliance
c_nu (r^+)^m against a hand computation; the tables (compliance p(r), friction tau(rho),
slip theta(s)) against exact integration (scipy quad), the built-in laws (4.1)-(4.2) they
sample at their kinks, and the interpolation bound of a finely sampled theta(s); energy,
derivative and second derivative consistent by finite differences (numpy) and by UFL's own
derivative of the energy; c_nu(x) per node takes the nodal problem's numpy path; the case
keys and their refusals (one line, naming the key)."""
import copy

import numpy as np
import pytest
import ufl
from scipy.integrate import quad

from conftest import make_case, paper_raw
from vpcontact import kernels
from vpcontact.io.errors import CaseError
from vpcontact.model import contact_laws as laws
from vpcontact.model import contactregistry as registry
from vpcontact.model import memory_kernels
from vpcontact.solvers.nodal import NodalContact, nodal_contact_numpy

B, C1, C2, U1 = 1.0, 60.0, 60.0, 0.01                # law (4.2) of the paper's Sec. 4
FRICTION_42 = [[0.0, B], [U1, B - C1 * U1], [2 * U1, B - C1 * U1 + C2 * U1]]
NONMONOTONE = [[0.0, 1.0], [0.005, 0.55], [0.01, 0.55], [0.02, 1.15], [0.03, 0.9],
               [0.04, 1.3]]
COMPLIANCE = [[0.0, 0.0], [0.008, 0.8], [0.012, 2.0], [0.02, 2.4]]


def _slips(top, n=401):
    """Slips in (0, top] with every kink of the tables below hit exactly and approached."""
    return np.unique(np.concatenate([np.linspace(1e-7, top, n),
                                     np.array([0.005, 0.01, 0.02, 0.03, 0.04]) + 1e-9]))


# ----------------------------------------------------------------------------- closed forms
def test_power_compliance_m2_by_hand():
    """p = c_nu (r^+)^2: P = c_nu (r^+)^3 / 3, p' = 2 c_nu r^+ (by hand, m = 2)."""
    c, r = 250.0, np.array([-0.3, -1e-3, 0.0, 1e-3, 0.007, 0.5])
    law = laws.PowerCompliance(c, 2.0)
    rp = np.maximum(r, 0.0)
    assert np.allclose(law.energy(r), c * rp**3 / 3.0, rtol=1e-15, atol=0.0)
    assert np.allclose(law.derivative(r), c * rp**2, rtol=1e-15, atol=0.0)
    assert np.allclose(law.second_derivative(r), 2.0 * c * rp, rtol=1e-15, atol=0.0)
    # m = 1 is (4.1)
    one, ref = laws.PowerCompliance(c, 1.0), laws.NormalCompliance(c)
    for f in ("energy", "derivative", "second_derivative"):
        assert np.array_equal(getattr(one, f)(r), getattr(ref, f)(r)), f


def test_friction_table_primitive_is_the_exact_integral():
    """psi(rho) of a nonmonotone table equals int_0^rho tau (scipy quad, breakpoints at the
    kinks) to 1e-13, also beyond the last point (linear extrapolation)."""
    law = laws.TableFriction(NONMONOTONE)
    pts = np.asarray(NONMONOTONE)

    def tau(x):                      # independent: numpy's interpolation, extrapolated
        if x <= pts[-1, 0]:
            return np.interp(x, pts[:, 0], pts[:, 1])
        s = (pts[-1, 1] - pts[-2, 1]) / (pts[-1, 0] - pts[-2, 0])
        return pts[-1, 1] + s * (x - pts[-1, 0])
    rho = np.array([1e-7, 0.003, 0.005, 0.0075, 0.012, 0.025, 0.031, 0.04, 0.05, 0.08])
    exact = np.array([quad(tau, 0.0, x, points=pts[:, 0][pts[:, 0] < x], limit=200,
                           epsabs=1e-14, epsrel=1e-13)[0] for x in rho])
    assert np.abs(law.energy(rho) - exact).max() <= 1e-13 * np.abs(exact).max()
    assert np.allclose(law.derivative(rho), [tau(x) for x in rho], rtol=1e-14, atol=1e-15)
    assert law.m_j == pytest.approx(90.0, rel=1e-12)       # the steepest softening, -0.45/0.005


def test_compliance_table_primitive_and_constant_tail():
    """P(r) of a compliance table equals int_0^r p (quad); p = 0 for r <= 0 and constant
    beyond the last point."""
    law = laws.TableCompliance(COMPLIANCE)
    pts = np.asarray(COMPLIANCE)

    def p(x):
        return np.interp(x, pts[:, 0], pts[:, 1]) if x > 0 else 0.0
    r = np.array([-0.01, 0.0, 0.004, 0.008, 0.01, 0.012, 0.015, 0.02, 0.05])
    exact = np.array([quad(p, 0.0, x, points=pts[:, 0][(pts[:, 0] > 0) & (pts[:, 0] < x)],
                           limit=200, epsabs=1e-15, epsrel=1e-13)[0] if x > 0 else 0.0
                      for x in r])
    assert np.abs(law.energy(r) - exact).max() <= 1e-13 * np.abs(exact).max()
    assert np.allclose(law.derivative(r), [p(x) for x in r], rtol=1e-14, atol=1e-15)
    assert law.derivative(np.array([0.05, 1.0])).tolist() == pytest.approx([2.4, 2.4])
    assert law.second_derivative(np.array([-1.0, 0.004, 0.05])).tolist() == \
        pytest.approx([0.0, 100.0, 0.0])


def test_tables_sampling_the_paper_laws_equal_them():
    """A friction table sampling (4.2) at its kinks is (4.2) (psi, psi', psi'' to 1e-12);
    a compliance table [[0, 0], [1, c_nu]] is (4.1) on [0, 1]."""
    table, ref = laws.TableFriction(FRICTION_42), laws.PiecewiseLinearFriction(B, C1, C2, U1)
    rho = _slips(0.06)
    for f in ("energy", "derivative", "second_derivative"):
        a, b = getattr(table, f)(rho), getattr(ref, f)(rho)
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max(), f
    assert table.m_j == pytest.approx(C1, rel=1e-12)
    normal, ref = laws.TableCompliance([[0.0, 0.0], [1.0, 100.0]]), laws.NormalCompliance(100.0)
    r = np.linspace(-0.02, 0.9, 301)
    for f in ("energy", "derivative", "second_derivative"):
        a, b = getattr(normal, f)(r), getattr(ref, f)(r)
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max(), f


def test_slip_table_interpolation_bound():
    """theta(s) = theta_inf + (1 - theta_inf) exp(-s/s0) sampled every h: the table's
    theta differs by at most h^2/8 max|theta''| = h^2 (1 - theta_inf) / (8 s0^2) (the
    linear interpolation bound; 1.1e-5 here), and is constant beyond the last point."""
    theta_inf, s0, h = 0.3, 0.002, 1e-5
    s_tab = np.arange(0.0, 0.02 + h / 2, h)
    exp_law = laws.SlipWeakening(theta_inf, s0)
    table = laws.TableSlip(np.column_stack([s_tab, exp_law.theta(s_tab)]))
    s = np.linspace(0.0, 0.02, 100003)
    bound = h**2 * (1.0 - theta_inf) / (8.0 * s0**2)
    err = np.abs(table.theta(s) - exp_law.theta(s)).max()
    print(f"slip table h = {h:g}: max |theta_table - theta| = {err:.3e} <= bound {bound:.3e}")
    assert 0.0 < err <= bound
    assert table.theta(np.array([0.5]))[0] == exp_law.theta(s_tab[-1])
    assert table.theta_max == pytest.approx(1.0)


@pytest.mark.parametrize("kind", ["exponential", "power"])
def test_memory_sum_with_b0_of_x(kind):
    """b(t, x) = b0(x) b(t): the memory sum fed with b0(x_i) u^+ (the kernel of factor 1,
    recursion or direct sum) equals xi_n = sum_j k_j b0(x_i) b(t_n - t_{j-1}) u_{j-1}^+
    summed by hand, at non-uniform steps; the kernel describes itself with b0(x)."""
    from vpcontact.model.gamma3 import MemorySum
    rng = np.random.default_rng(5)
    x = np.array([[0.0, 0.0], [0.3, 0.0], [1.0, 0.0]])
    b0 = laws.space_field("2 + 3 * x", x)
    assert b0.tolist() == [2.0, 2.9, 5.0]
    kernel = memory_kernels.FieldKernel(
        registry.memory_kernel(kind, 1.0, beta=1.5, alpha=2.0, tau=0.5), "2 + 3 * x")
    assert kernel.constants()["b0"][0] == "2 + 3 * x"
    times = np.cumsum(np.concatenate([[0.0], rng.uniform(0.05, 0.2, 6)]))
    r = rng.uniform(0.0, 0.01, (6, 3))
    total = MemorySum(kernel, 3)

    def b(t):
        return np.exp(-1.5 * t) if kind == "exponential" else (1.0 + t / 0.5) ** -2.0
    for n in range(1, 7):
        xi = total.advance(b0 * r[n - 1], times[n - 1], times[n])
        ref = sum((times[j] - times[j - 1]) * b0 * b(times[n] - times[j - 1]) * r[j - 1]
                  for j in range(1, n + 1))
        assert np.allclose(xi, ref, rtol=1e-13, atol=0.0)


# ----------------------------------------------------------------------------- consistency
GENERAL_LAWS = [
    (laws.PowerCompliance(120.0, 2.5), np.linspace(-0.01, 0.03, 37)),
    (laws.PowerCompliance(80.0, 1.0), np.linspace(-0.01, 0.03, 37)),
    (laws.TableCompliance(COMPLIANCE), np.linspace(-0.01, 0.03, 37)),
    (laws.TableFriction(NONMONOTONE), np.linspace(1e-4, 0.06, 41)),
]


def _off_kinks(x, kinks, h):
    """The points farther than 2 h from every kink (finite differences are exact there up
    to round-off for a piecewise quadratic energy)."""
    keep = np.ones(len(x), bool)
    for k in kinks:
        keep &= np.abs(x - k) > 2 * h
    return x[keep]


@pytest.mark.parametrize("law, x", GENERAL_LAWS, ids=["power2.5", "power1", "compliance",
                                                      "friction"])
def test_derivatives_by_finite_differences(law, x):
    """derivative = d energy / dx and second_derivative = d derivative / dx by central
    differences (away from the kinks, where a one-sided law has no second derivative)."""
    h = 1e-7
    kinks = [0.0] + [p[0] for p in COMPLIANCE + NONMONOTONE]
    x = _off_kinks(x, kinks, h)
    d1 = (law.energy(x + h) - law.energy(x - h)) / (2 * h)
    d2 = (law.derivative(x + h) - law.derivative(x - h)) / (2 * h)
    scale1 = np.abs(law.derivative(x)).max()
    scale2 = np.abs(law.second_derivative(x)).max()
    assert np.abs(d1 - law.derivative(x)).max() <= 1e-6 * scale1
    assert np.abs(d2 - law.second_derivative(x)).max() <= 1e-5 * scale2


@pytest.mark.parametrize("law, x", GENERAL_LAWS, ids=["power2.5", "power1", "compliance",
                                                      "friction"])
def test_ufl_energy_differentiates_to_the_numpy_derivatives(law, x):
    """The same law written on a UFL variable: UFL's derivatives of its energy equal the
    numpy derivative and second derivative (one definition serves both back ends)."""
    for xi in x[::4]:
        v = ufl.variable(ufl.as_ufl(float(xi)))
        e = law.energy(v)
        d1, d2 = ufl.diff(e, v), ufl.diff(ufl.diff(e, v), v)
        ev = [float(expr(())) for expr in (e, d1, d2)]
        ref = [float(law.energy(np.array([xi]))[0]), float(law.derivative(np.array([xi]))[0]),
               float(law.second_derivative(np.array([xi]))[0])]
        for a, b in zip(ev, ref):
            assert a == pytest.approx(b, rel=1e-12, abs=1e-12 * max(1.0, abs(b)))


def test_nodal_contact_with_general_laws():
    """The nodal energy of the general laws (the condensed solver's numpy path): gradient
    and Hessian blocks against central differences of the energy; c_nu per node (an
    array) is taken by numpy even with the compiled module, and a constant array equals
    the number."""
    rng = np.random.default_rng(3)
    nu, w, delta = np.array([0.0, 0.0, -1.0]), rng.uniform(0.5, 1.5, 5), 1e-7
    y = rng.uniform(-0.02, 0.02, (5, 3))
    law = laws.ContactLaw(normal=laws.PowerCompliance(rng.uniform(50, 150, 5), 2.0),
                          friction=laws.TableFriction(NONMONOTONE),
                          norm=laws.RegularisedNorm(delta))
    theta = rng.uniform(0.3, 1.0, 5)
    e, g, H = nodal_contact_numpy(y, nu, law, None, theta, w)
    h = 1e-7
    for i in range(5):
        for a in range(3):
            yp, ym = y.copy(), y.copy()
            yp[i, a] += h
            ym[i, a] -= h
            ep, gp, _ = nodal_contact_numpy(yp, nu, law, None, theta, w)
            em, gm, _ = nodal_contact_numpy(ym, nu, law, None, theta, w)
            assert (ep - em) / (2 * h) == pytest.approx(g[i, a], rel=1e-6, abs=1e-9)
            assert np.allclose((gp[i] - gm[i]) / (2 * h), H[i, :, a], rtol=1e-5, atol=1e-6)
    c = np.full(5, 100.0)
    per_node = NodalContact(w, nu, laws.ContactLaw(normal=laws.NormalCompliance(c)),
                            kernels.load())
    number = NodalContact(w, nu, laws.ContactLaw(normal=laws.NormalCompliance(100.0)))
    assert per_node.mod is None
    for a, b in zip(per_node.evaluate(y), number.evaluate(y)):
        assert np.array_equal(a, b)


# ----------------------------------------------------------------------------- case keys
def _contact(**keys):
    raw = paper_raw()
    for key, value in keys.items():
        section, _, sub = key.partition("__")
        if value is None:
            raw["contact"].pop(section, None)
        elif sub:
            raw["contact"].setdefault(section, {})[sub] = copy.deepcopy(value)
        else:
            raw["contact"][section] = copy.deepcopy(value)
    return raw


def test_case_keys_and_the_laws_they_build():
    """The new keys reach the Case (not default-filled: the paper's Case keeps None) and
    contact_law builds the general laws from them."""
    paper = make_case(paper_raw()).contact
    assert (paper.normal.m, paper.normal.table, paper.friction.table) == \
        (None, None, None)
    case = make_case(_contact(normal_compliance={"table": COMPLIANCE},
                              friction={"table": NONMONOTONE,
                                        "slip": {"table": [[0.0, 1.0], [0.01, 0.5]]}},
                              memory={"b0": "2 + x", "beta": 1.0}))
    c = case.contact
    assert c.c_nu is None and c.compliance and c.normal.table[1] == (0.008, 0.8)
    assert c.friction.b is None and c.friction.slip.table == ((0.0, 1.0), (0.01, 0.5))
    assert c.memory.b0 == "2 + x"
    law = registry.contact_law(c, 1e-7)
    assert isinstance(law.normal, laws.TableCompliance)
    assert isinstance(law.friction, laws.TableFriction)
    assert isinstance(registry.slip_law(c.friction.slip), laws.TableSlip)
    power = make_case(_contact(normal_compliance={"c_nu": "100 + 10 * x", "m": 2})).contact
    law = registry.contact_law(power, 1e-7, x=np.array([[0.0, 0.0], [0.5, 0.0]]))
    assert isinstance(law.normal, laws.PowerCompliance) and law.normal.m == 2.0
    assert law.normal.c_nu.tolist() == [100.0, 105.0]


@pytest.mark.parametrize("contact, key", [
    ({"normal_compliance": {"c_nu": 100.0, "table": COMPLIANCE}},
     "contact.normal_compliance.table"),
    ({"normal_compliance": {"table": [[0.0, 0.0], [0.01, 1.0], [0.02, 0.5]]}},
     "contact.normal_compliance.table"),
    ({"normal_compliance": {"table": [[0.0, 0.1], [0.01, 1.0]]}},
     "contact.normal_compliance.table"),
    ({"normal_compliance": {"table": [[0.001, 0.0], [0.01, 1.0]]}},
     "contact.normal_compliance.table"),
    ({"normal_compliance": {"table": COMPLIANCE, "m": 2}}, "contact.normal_compliance.m"),
    ({"normal_compliance": {"c_nu": 100.0, "m": 0.5}}, "contact.normal_compliance.m"),
    ({"normal_compliance": {"m": 2}}, "contact.normal_compliance.c_nu"),
    ({"normal_compliance": {"c_nu": "100 - 1000 * x"}}, "contact.normal_compliance.c_nu"),
    ({"normal_compliance": {"c_nu": "100 * t"}}, "contact.normal_compliance.c_nu"),
    ({"friction__table": NONMONOTONE}, "contact.friction.table"),
    ({"friction": {"table": [[0.0, 0.0], [0.01, 1.0]]}}, "contact.friction.table"),
    ({"friction": {"table": [[0.0, 1.0], [0.01, 1.0], [0.005, 1.0]]}},
     "contact.friction.table"),
    ({"friction": {"table": [[0.0, 1.0], [0.01, 0.5], [0.02, 0.4]]}},
     "contact.friction.table"),
    ({"friction": {"table": [[0.0, 1.0], [0.01, -0.5], [0.02, 1.0]]}},
     "contact.friction.table"),
    ({"friction": {"b": 1.0, "c1": 60.0, "c2": 60.0}}, "contact.friction.u1"),
    ({"friction__slip": {"table": [[0.0, 1.0], [0.01, 1.2]]}},
     "contact.friction.slip.table"),
    ({"friction__slip": {"table": [[0.0, 1.0], [0.01, 0.5]], "s0": 0.002}},
     "contact.friction.slip.table"),
    ({"friction__slip": {"theta_inf": 0.3}}, "contact.friction.slip.s0"),
    ({"memory": {"b0": "1 - 10 * x", "beta": 1.0}}, "contact.memory.b0"),
])
def test_refusals(contact, key):
    """Each inconsistent contact law is refused in one line naming the key."""
    with pytest.raises(CaseError) as info:
        make_case(_contact(**contact))
    msg = str(info.value)
    print(msg)
    assert key in msg and "\n" not in msg
