"""Parts of the time loop without a solve: the one rule of solver.method auto
(choose_method) and the step control's state() / load_state()."""
import pytest

from conftest import make_case
from vpcontact.model.stepping import AdaptiveSteps, FixedSteps
from vpcontact.solvers import AUTO_FAST_MAX_GAMMA3_DOFS, choose_method


@pytest.mark.parametrize("dofs, expected", [(0, "condensed"),
                                            (AUTO_FAST_MAX_GAMMA3_DOFS, "condensed"),
                                            (AUTO_FAST_MAX_GAMMA3_DOFS + 1, "snes_vi")])
def test_auto_picks_fast_up_to_the_dense_limit(dofs, expected):
    case = make_case(solver={"method": "auto"})
    assert choose_method(case, dofs) == expected


def test_auto_picks_snes_vi_where_fast_does_not_apply():
    """The implicit history scheme makes the bulk problem nonlinear: never fast."""
    case = make_case(solver={"method": "auto"}, time={"T": 1.0, "N": 4, "scheme": "implicit"})
    assert choose_method(case, 2) == "snes_vi"


@pytest.mark.parametrize("method, chosen", [("fast", "condensed"), ("snes_vi", "snes_vi")])
def test_an_explicit_method_is_kept(method, chosen):
    case = make_case(solver={"method": method})
    assert choose_method(case, 10 * AUTO_FAST_MAX_GAMMA3_DOFS) == chosen


def test_fixed_steps_state_round_trip():
    st = FixedSteps([0.0, 0.25, 0.5, 1.0])
    st.accept(0.25, 3)
    saved = st.state()
    assert saved == {"adaptive": False, "n": 1, "k": None, "decisions": []}
    st.accept(0.25, 3)
    again = FixedSteps([0.0, 0.25, 0.5, 1.0])
    again.load_state(saved)
    assert again.n == 1 and again.next_k(0.25) == 0.25 and again.next_t(0.25, 0.25) == 0.5


def test_adaptive_steps_state_round_trip():
    st = AdaptiveSteps(1.0, 0.25, rate=None, scheme="implicit", grow=2.0, max_change=0.1)
    st.accept(st.next_k(0.0), 0.05)                 # a small change: k grows to 0.5
    st.reject(0.5, "injected")                      # k back to 0.25
    saved = st.state()
    assert saved["adaptive"] and saved["n"] is None and saved["k"] == 0.25
    assert [d["accepted"] for d in saved["decisions"]] == [True, False]
    st.accept(0.25, 0.9)
    assert len(saved["decisions"]) == 2             # the state is a copy
    other = AdaptiveSteps(1.0, 0.125, rate=None, scheme="implicit")
    other.load_state(saved)
    assert other.k == 0.25 and other.decisions == saved["decisions"]
    assert other.next_k(0.25) == 0.25
