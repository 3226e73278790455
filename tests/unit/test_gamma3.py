"""Memory term and accumulated slip on Gamma3."""
from types import SimpleNamespace

import numpy as np
import pytest

from vpcontact.model.contact_laws import SlipWeakening, StaticKineticSlip
from vpcontact.model.contactregistry import memory_kernel
from vpcontact.model.gamma3 import (
    MemorySum,
    NodewiseSlip,
    SlipPath,
    SlipSum,
    build_gamma3_history,
)


def _steps(rng, n=40):
    k = rng.uniform(0.001, 0.2, n)          # non-uniform steps
    return np.concatenate([[0.0], np.cumsum(k)])


def test_recursion_equals_direct_sum_on_nonuniform_steps():
    rng = np.random.default_rng(0)
    t = _steps(rng)
    kern = memory_kernel("exponential", b0=3.0, beta=2.5)
    rec, direct = MemorySum(kern, 7, recursion=True), MemorySum(kern, 7, recursion=False)
    r_hist = []
    for n in range(1, len(t)):
        r = np.maximum(rng.normal(size=7), 0.0)
        r_hist.append(r)
        a = rec.advance(r, t[n - 1], t[n])
        b = direct.advance(r, t[n - 1], t[n])
        # the definition, term by term
        ref = sum((t[j] - t[j - 1]) * 3.0 * np.exp(-2.5 * (t[n] - t[j - 1])) * r_hist[j - 1]
                  for j in range(1, n + 1))
        np.testing.assert_allclose(a, ref, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(b, ref, rtol=1e-13, atol=1e-15)
    assert rec.stored_steps == 0 and direct.stored_steps == len(t) - 1


@pytest.mark.parametrize("kind,kw", [("power", {"alpha": 0.7, "tau": 0.3}),
                                     ("table", {"table": [[0, 1.0], [0.5, 0.2], [2, 0.0]]})])
def test_general_kernels_direct_sum(kind, kw):
    rng = np.random.default_rng(1)
    t = _steps(rng, 15)
    kern = memory_kernel(kind, b0=2.0, **kw)
    mem = MemorySum(kern, 3)
    assert not mem.recursion
    rs = [np.abs(rng.normal(size=3)) for _ in range(len(t) - 1)]
    for n in range(1, len(t)):
        xi = mem.advance(rs[n - 1], t[n - 1], t[n])
    n = len(t) - 1
    ref = sum((t[j] - t[j - 1]) * kern(t[n] - t[j - 1]) * rs[j - 1] for j in range(1, n + 1))
    np.testing.assert_allclose(xi, ref, rtol=1e-13)
    with pytest.raises(ValueError, match="recursion"):
        MemorySum(kern, 3, recursion=True)


def test_slip_sum_and_theta():
    slip = SlipSum(2, SlipWeakening(theta_inf=0.4, s0=0.01))
    np.testing.assert_allclose(slip.theta(), 1.0)
    slip.advance(np.array([0.01, 0.0]), 0.5)
    slip.advance(np.array([0.03, 0.0]), 0.25)
    np.testing.assert_allclose(slip.s, [0.5 * 0.01 + 0.25 * 0.03, 0.0])
    np.testing.assert_allclose(slip.theta()[0], 0.4 + 0.6 * np.exp(-0.0125 / 0.01))
    assert slip.theta()[1] == 1.0


@pytest.mark.parametrize("recursion", [True, False])
def test_memory_state_round_trip(recursion):
    """state() after n steps, more steps, load_state(): the next steps repeat exactly, for
    the recursion and for the direct sum (whose stored u_nu^+ history is part of the state)."""
    rng = np.random.default_rng(2)
    t = _steps(rng, 12)
    rs = [np.abs(rng.normal(size=4)) for _ in range(len(t) - 1)]
    mem = MemorySum(memory_kernel("exponential", b0=1.5, beta=0.8), 4, recursion=recursion)
    for n in range(1, 6):
        mem.advance(rs[n - 1], t[n - 1], t[n])
    saved = mem.state()
    first = [mem.advance(rs[n - 1], t[n - 1], t[n]).copy() for n in range(6, len(t))]
    assert mem.stored_steps == (0 if recursion else len(t) - 1)
    mem.load_state(saved)
    assert mem.stored_steps == (0 if recursion else 5)
    np.testing.assert_array_equal(mem.xi, saved["xi"])
    again = [mem.advance(rs[n - 1], t[n - 1], t[n]).copy() for n in range(6, len(t))]
    np.testing.assert_array_equal(np.array(again), np.array(first))
    fresh = MemorySum(memory_kernel("exponential", b0=1.5, beta=0.8), 4, recursion=recursion)
    fresh.load_state(saved)                    # into another object: the same state
    assert fresh.state()["t_prev"] == saved["t_prev"] and fresh.state()["k"] == saved["k"]


def test_slip_state_round_trip():
    slip = SlipSum(3, SlipWeakening(theta_inf=0.4, s0=0.1))
    slip.advance(np.array([1.0, 2.0, 3.0]), 0.1)
    saved = slip.state()
    slip.advance(np.array([5.0, 5.0, 5.0]), 0.2)
    slip.load_state(saved)
    expected = 0.1 * np.array([1.0, 2.0, 3.0])
    np.testing.assert_array_equal(slip.s, expected)
    saved["s"][:] = 0.0                        # the state is a copy
    np.testing.assert_array_equal(slip.s, expected)


def test_slip_path_by_hand():
    """u_tau of two nodes (2D vectors) at t_0..t_3: (0,0) -> (3,4) -> (3,4) -> (0,0) and
    (1,0) -> (1,0) -> (1,2) -> (1,2): increments 5, 0, 5 and 0, 2, 0 (the first from u_0),
    accumulated 5, 5, 10 and 0, 2, 2; before step 1 the increment is 0; the state
    round-trips (a copy) and None restarts the path."""
    u = [np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([[3.0, 4.0], [1.0, 0.0]]),
         np.array([[3.0, 4.0], [1.0, 2.0]]), np.array([[0.0, 0.0], [1.0, 2.0]])]
    path = SlipPath(2)
    np.testing.assert_array_equal(path.increment(u[0]), [0.0, 0.0])
    incs, totals = [], []
    for n in range(1, 4):
        path.advance(u[n - 1])                     # before step n: u_{n-1,tau}
        incs.append(path.increment(u[n]))
        totals.append(path.accumulated(u[n]))
    np.testing.assert_allclose(incs, [[5.0, 0.0], [0.0, 2.0], [5.0, 0.0]], rtol=0, atol=1e-15)
    np.testing.assert_allclose(totals, [[5.0, 0.0], [5.0, 2.0], [10.0, 2.0]], rtol=0,
                               atol=1e-15)
    np.testing.assert_array_equal(path.accumulated(u[3][[1]], np.array([1])), [2.0])
    saved = path.state()
    path.advance(u[3])
    path.load_state(saved)
    saved["length"][:] = -1.0                      # the state is a copy
    np.testing.assert_allclose(path.accumulated(u[3]), [10.0, 2.0], rtol=0, atol=1e-15)
    path.load_state(None)
    np.testing.assert_array_equal(path.increment(u[3]), [0.0, 0.0])


def test_slip_states_codes():
    """slip_threshold = max(10 delta, 1e-9 u_scale); slip above it, stick at or below,
    separated (-1) at p_n <= 1e-6 max p_n whatever the increment."""
    from vpcontact.post.quantities import SLIP_CODES, slip_states, slip_threshold
    assert SLIP_CODES == {"separated": -1, "stick": 0, "slip": 1}
    assert slip_threshold(1e-8, 1.0) == 10 * 1e-8 and slip_threshold(1e-8, 1e3) == 1e-9 * 1e3
    p = np.array([1.0, 1.0, 1.0, 1e-7, 1e-7, 0.0])
    inc = np.array([0.0, 1e-7, 1.01e-7, 1.0, 0.0, 1.0])
    np.testing.assert_array_equal(slip_states(p, inc, 1e-7, 1.0), [0, 0, 1, -1, -1, -1])


class _Field:
    """A stand-in for the problem's NodalField: keeps the values set."""

    def __init__(self):
        self.values = None

    def set(self, values):
        self.values = np.array(values)


def _problem(u_nodes, normal):
    """What Gamma3History reads of the problem: u (contact_u), the Gamma3 nodes and normals,
    the nodal fields xi and theta."""
    u = SimpleNamespace(x=SimpleNamespace(array=np.asarray(u_nodes, dtype=float).ravel()))
    values = np.asarray(u_nodes, dtype=float).reshape(len(u_nodes), -1)
    disc = SimpleNamespace(gamma3_local_nodes=np.arange(len(u_nodes)),
                           frames=SimpleNamespace(normal=np.asarray(normal, dtype=float)),
                           dim=2)
    return SimpleNamespace(u=u, contact_u=lambda: values, disc=disc, xi=_Field(), theta=_Field())


def _case(memory=None, slip=None):
    friction = SimpleNamespace(b=1.0, c1=60.0, c2=60.0, u1=0.01, slip=slip)
    contact = SimpleNamespace(memory=memory, friction=friction)
    contact.sections = (contact,)            # one set of laws (Contact.sections)
    return SimpleNamespace(contact=contact)


def test_history_built_from_the_case_laws():
    """build_gamma3_history: the case's kernel and theta(s) laws, the sum it asks for, and
    one step of xi_n = k b(t_n - t_{n-1}) u_nu^+ and s_n = k |u_tau| from u_{n-1}."""
    assert build_gamma3_history(_case(), _problem([[0.0, 0.0]], [[0.0, -1.0]])) is None
    memory = SimpleNamespace(kernel="power", b0=2.0, constants={"alpha": 0.7, "tau": 0.3},
                             sum="auto")
    slip = SimpleNamespace(law="weakening", constants={"theta_inf": 0.4, "s0": 0.01})
    u = [[0.003, -0.002], [-0.001, 0.005]]               # u_nu = -u_y: 0.002, -0.005
    problem = _problem(u, [[0.0, -1.0], [0.0, -1.0]])
    history = build_gamma3_history(_case(memory, slip), problem)
    assert history.memory.kernel == memory_kernel("power", 2.0, alpha=0.7, tau=0.3)
    assert not history.memory.recursion and history.slip.law == SlipWeakening(0.4, 0.01)
    assert np.array_equal(problem.theta.values, [1.0, 1.0])
    history.advance(0.5, 0.75)
    b = 2.0 * (1.0 + 0.25 / 0.3) ** -0.7                  # b(t_n - t_{n-1})
    np.testing.assert_allclose(problem.xi.values, [0.25 * b * 0.002, 0.0], rtol=1e-15)
    np.testing.assert_allclose(history.slip.s, [0.25 * 0.003, 0.25 * 0.001], rtol=1e-15)
    np.testing.assert_allclose(problem.theta.values,
                               0.4 + 0.6 * np.exp(-history.slip.s / 0.01), rtol=1e-15)
    memory.sum, memory.kernel, memory.constants = "direct", "exponential", {"beta": 0.0}
    direct = build_gamma3_history(_case(memory, None), _problem(u, [[0.0, -1.0]] * 2))
    assert not direct.memory.recursion and direct.slip is None


def test_nodewise_slip_of_pairs_with_different_laws():
    """Laws per pair: theta(s) of each pair's law on its nodes, 1 on the nodes of a pair
    without one; theta_max the largest (closed forms of the two laws)."""
    s = np.array([0.0, 0.02, 0.5, 0.1, 3.0])
    first = np.array([True, True, False, False, False])
    second = np.array([False, False, True, True, False])
    theta = NodewiseSlip(5, [(first, SlipWeakening(0.4, 0.01)),
                             (second, StaticKineticSlip(0.5, 0.3, 0.2))]).theta(s)
    expected = [1.0, 0.4 + 0.6 * np.exp(-2.0),       # theta_inf + (1 - theta_inf) e^(-s/s0)
                0.3 / 0.5, 1.0 - (1.0 - 0.3 / 0.5) * 0.5,   # mu(s) / mu_s, past and within L
                1.0]                                 # no slip law
    assert np.allclose(theta, expected, rtol=1e-14)
    assert NodewiseSlip(5, [(first, SlipWeakening(0.4, 0.01))]).theta_max == 1.0
