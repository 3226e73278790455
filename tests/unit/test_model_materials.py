"""The history update of a body of several materials (app/model/materials.py), in numpy:
each group's law updates only its rows, with its own m (kappa has the largest; the other
components stay 0), an elastic group keeps H and kappa, a failing group writes nothing, and
the implicit local solve by group equals each law's own on its rows."""
import numpy as np
import pytest

from vpcontact.model.laws import ViscoplasticLaw
from vpcontact.model.material import Elasticity
from vpcontact.model.materials import GroupLaws, MaterialGroup
from vpcontact.model.viscoplastic import Perzyna


class Linear(ViscoplasticLaw):
    """G = -a sigma, Gk_i = (i + 1) ||sigma||_VM: rates by hand, m of one's choice."""

    name = "linear"

    def __init__(self, elasticity, a, m, fail=False):
        super().__init__(elasticity)
        self.a, self.m, self.fail = a, m, fail

    def rates(self, t, kappa):
        if self.fail:
            raise RuntimeError("no")
        assert kappa.shape[1] == self.m
        vm = self.elasticity.von_mises(t)
        return -self.a * t, vm[:, None] * np.arange(1, self.m + 1)[None, :]


def _groups(el, laws, rows):
    return [MaterialGroup(f"g{i}", i, r, None, el, law) for i, (r, law) in
            enumerate(zip(rows, laws))]


def test_explicit_update_by_group():
    el = Elasticity(100.0, 0.3, 2)
    rng = np.random.default_rng(3)
    n = 9
    rows = [np.array([0, 4, 8]), np.array([1, 2, 7]), np.array([3, 5, 6])]
    laws = [Linear(el, 2.0, 1), Linear(el, 5.0, 3), None]
    body = GroupLaws(_groups(el, laws, rows), el)
    assert body.m == 3
    t = rng.normal(size=(n, 3))
    sigma = el.from_voigt(t).reshape(-1)
    H0 = rng.normal(size=(n, 3))
    H = el.from_voigt(H0).reshape(-1).copy()
    kappa = np.zeros((n, 3))
    kappa[:, 0] = 1.0
    k = 0.01
    body.explicit()(sigma, H, kappa, k)
    Ht = el.to_voigt(H)
    vm = el.von_mises(t)
    for r, a, m in ((rows[0], 2.0, 1), (rows[1], 5.0, 3)):
        assert np.allclose(Ht[r], H0[r] - k * a * t[r], rtol=1e-14, atol=1e-15)
        assert np.allclose(kappa[r, :m], np.eye(3)[0, :m] + k * vm[r, None] *
                           np.arange(1, m + 1), rtol=1e-14)
        assert (kappa[r, m:] == 0.0).all()
    assert np.array_equal(Ht[rows[2]], H0[rows[2]])               # elastic: H kept
    assert np.array_equal(kappa[rows[2]], np.tile([1.0, 0.0, 0.0], (3, 1)))


def test_a_failing_group_writes_nothing():
    el = Elasticity(100.0, 0.3, 2)
    rows = [np.array([0, 1]), np.array([2, 3])]
    body = GroupLaws(_groups(el, [Linear(el, 1.0, 1), Linear(el, 1.0, 1, fail=True)], rows),
                     el)
    sigma = np.ones(16)
    H, kappa = np.zeros(16), np.zeros((4, 1))
    with pytest.raises(RuntimeError):
        body.explicit()(sigma, H, kappa, 0.1)
    assert not H.any() and not kappa.any()


def test_implicit_by_group_equals_each_law():
    el1, el2 = Elasticity(100.0, 0.3, 2), Elasticity(300.0, 0.2, 2)
    p1, p2 = Perzyna(el1, 1.0, 2.0), Perzyna(el2, 3.0, 1.0)
    rows = [np.array([0, 3, 4]), np.array([1, 5]), np.array([2])]
    groups = [MaterialGroup("a", 1, rows[0], None, el1, p1),
              MaterialGroup("b", 2, rows[1], None, el2, p2),
              MaterialGroup("c", 3, rows[2], None, el2, None)]
    rng = np.random.default_rng(5)
    s_tr = 50.0 * rng.normal(size=(6, 3))
    kappa = np.full((6, 1), 5.0)
    sigma, kap, C = GroupLaws(groups, None).implicit().solve(s_tr, kappa, 0.05)
    for g in groups[:2]:
        ref = g.law.implicit().solve(s_tr[g.rows], kappa[g.rows], 0.05)
        for got, want in zip((sigma, kap, C), ref):
            assert np.array_equal(got[g.rows], want)
    assert np.array_equal(sigma[rows[2]], s_tr[rows[2]])
    assert np.array_equal(C[rows[2]][0], el2.Cmat) and kap[2, 0] == 5.0
    assert not np.allclose(sigma[rows[0]], s_tr[rows[0]])        # the law flowed


def test_rates_on_the_selected_cells_and_the_estimated_rate():
    """GroupLaws.rates on every cell is each group's law on its cells; on cells the body's
    elasticity selected (one cell repeated: the difference quotient of estimated_rate) it is
    that cell's law, so the estimate of the body is its group's law's own."""
    from vpcontact.model.material import CellElasticity
    from vpcontact.model.viscoplastic import PowerLaw
    from vpcontact.post.diagnostics import estimated_rate
    el1, el2 = Elasticity(100.0, 0.3, 2), Elasticity(300.0, 0.2, 2)
    rows = [np.array([0, 2, 3]), np.array([1, 4])]
    body_el = CellElasticity.from_pieces(5, [(rows[0], el1), (rows[1], el2)], 2)
    groups = [MaterialGroup("a", 1, rows[0], None, el1, Perzyna(el1, 1.0, 1.0)),
              MaterialGroup("b", 2, rows[1], None, el2, PowerLaw(el2, 1.0, 1.0, 3.0, 10.0))]
    body = GroupLaws(groups, body_el)
    assert body.relaxation_rate() is None and body.lipschitz_constant() is None
    t = 40.0 * np.random.default_rng(7).normal(size=(5, 3))
    kappa = np.ones((5, 1))
    G, Gk = body.rates(t, kappa)
    for g in groups:
        Gg, Gkg = g.law.rates(t[g.rows], kappa[g.rows])
        assert np.array_equal(G[g.rows], Gg) and np.array_equal(Gk[g.rows], Gkg)
    for cell in range(5):
        t[:] = 1.0
        t[cell] = 50.0                        # the cell of largest ||sigma||_VM
        g = next(g for g in groups if cell in g.rows)
        want = estimated_rate(g.law, t[[cell]], kappa[[cell]])
        assert want is not None
        assert estimated_rate(body, t, kappa) == pytest.approx(want, rel=1e-12)


def test_state_rate_of_a_group_with_E_per_cell_takes_its_own_cells_E():
    """The stability estimate of a body of several materials (diagnostics.state_rate) is the
    largest of its groups' estimates, each at the group's most stressed cell with THAT cell's
    E: the groups' laws share the body's per-cell elasticity, so a group's row i must select
    the body's row rows[i] (not row i, another group's cell with another E)."""
    from types import SimpleNamespace

    from vpcontact.model.material import CellElasticity
    from vpcontact.model.viscoplastic import PowerLaw
    from vpcontact.post.diagnostics import estimated_rate, state_rate
    el1, el2 = Elasticity(100.0, 0.3, 2), Elasticity(900.0, 0.2, 2)
    rows = [np.array([0, 1, 2]), np.array([3, 4])]
    body_el = CellElasticity.from_pieces(5, [(rows[0], el1), (rows[1], el2)], 2)
    groups = [MaterialGroup("soft", 1, rows[0], None, body_el, None),
              MaterialGroup("hard", 2, rows[1], None, body_el,
                            PowerLaw(body_el, 1.0, 1.0, 3.0, 10.0))]
    t = np.ones((5, 3))
    t[4] = [50.0, -20.0, 10.0]             # the hard group's most stressed cell: body row 4
    kappa = np.ones((5, 1))
    problem = SimpleNamespace(law=GroupLaws(groups, body_el), disc=SimpleNamespace(comm=None),
                              state=SimpleNamespace(kappa_cells=kappa))
    want = estimated_rate(PowerLaw(el2, 1.0, 1.0, 3.0, 10.0), t[[4]], kappa[[4]])
    other = estimated_rate(PowerLaw(el1, 1.0, 1.0, 3.0, 10.0), t[[4]], kappa[[4]])
    assert want is not None and abs(want / other - 1.0) > 0.5       # the cell's E matters
    # central differences of step 1e-6 |sigma|: round-off of ~1e-10 relative (the per-cell
    # and the homogeneous E multiply in another order)
    assert state_rate(problem, t) == pytest.approx(want, rel=1e-8)
