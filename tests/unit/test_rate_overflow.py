"""Law constants whose rates overflow a float, and laws that raise where their rate is
estimated: the stability diagnostics (app/post/diagnostics.py, the laws' ``rate_at_stress``)
answer with an infinite rate or a failure of the estimate, never a numpy error.

The references are closed forms: 20^299 = 10^389 and (19e90)^200 exceed the largest float
(1.8e308), so r(S) = n A S^(n-1) lambda_1 of Norton's law and Chaboche's phi'(S - k) (...)
are infinite; 10 / 1e-90 = 1e91 to the power 99 overflows the power law's factor."""
import math

import numpy as np
import pytest

from vpcontact.model.chaboche import Chaboche
from vpcontact.model.material import Elasticity
from vpcontact.model.norton import Norton
from vpcontact.model.viscoplastic import PowerLaw
from vpcontact.post.diagnostics import Diagnostics, estimated_rate

EL = Elasticity(1000.0, 0.4, 2)
STATE = np.array([[10.0, -2.0, 3.0]])             # one cell, ||sigma||_VM about 12.5


def test_norton_rate_at_stress_overflows_to_infinity():
    """A = 1e-3, n = 300 at S = 20 Pa (the probe's case d04): infinite, not None (None sent
    the diagnostics on to an estimate that raised LinAlgError on the non-finite Jacobian);
    S = 0 still gives None (no flow), a moderate S its finite value."""
    law = Norton(EL, 1e-3, 300)
    assert law.rate_at_stress(20.0) == math.inf
    assert law.rate_at_stress(0.0) is None
    mu = 1000.0 / (2 * 1.4)
    assert Norton(EL, 1e-3, 2).rate_at_stress(20.0) == pytest.approx(2 * 1e-3 * 20 * 3 * mu,
                                                                    rel=1e-12)


def test_chaboche_rate_at_stress_overflows_to_infinity():
    """n = 200, K = 1e-90 (k = 1, S = 20): ((S - k)/K)^n overflows, and with C = gamma = b
    = 0 the term max(gamma, b) phi is 0 inf = NaN: the rate is infinite, not NaN or None;
    below the yield stress it is None (no flow)."""
    law = Chaboche(EL, k=1.0, K=1e-90, n=200, C=0.0, gamma=0.0, Q=0.0, b=0.0)
    assert law.rate_at_stress(20.0) == math.inf
    assert law.rate_at_stress(0.5) is None


@pytest.mark.parametrize("law", [Norton(EL, 1e-3, 300), PowerLaw(EL, 1.0, 1.0, 100, 1e-90)],
                         ids=["norton", "power"])
def test_estimated_rate_of_overflowing_rates_is_infinite(law):
    """The finite-difference Jacobian of rates that overflow at the state is not finite:
    the estimate is infinite (it raised numpy's LinAlgError: 'Array must not contain infs
    or NaNs', an internal error of the run)."""
    with np.errstate(over="ignore", invalid="ignore"):
        G, _ = law.rates(STATE, np.zeros((1, law.m)))
    assert not np.isfinite(G).all()                   # the premise: G overflows here
    assert estimated_rate(law, STATE, np.zeros((1, law.m))) == math.inf


class _Raising(Norton):
    """Norton's law whose rates raise (a law failing at the estimated state)."""

    def rates(self, t, kappa):
        raise RuntimeError("no rates here")


def test_estimated_rate_of_a_law_that_raises():
    """The law's error becomes RateEstimateError with its message (the run's rate watch
    warns, the next explicit update fails the step); with a communicator of one rank too."""
    from mpi4py import MPI

    from vpcontact.post.diagnostics import RateEstimateError
    for comm in (None, MPI.COMM_SELF):
        with pytest.raises(RateEstimateError, match="^no rates here$"):
            estimated_rate(_Raising(EL, 1e-3, 2), STATE, np.zeros((1, 1)), comm=comm)


def test_an_infinite_indicator_says_no_step_is_stable():
    """The warning of an infinite indicator: unstable for every time step (it said "errors
    can grow by up to infx per step")."""
    d = Diagnostics("explicit", 0.25, None, math.inf, 2.0, False, 1.0, None, 0.0, None, None,
                    None, rate_estimate=math.inf, indicator_source="stress_scale",
                    stress_scale=20.0)
    [(level, text)] = d.messages()
    assert level == "warning"
    assert "k_max r_max = 0.25 x inf = inf" in text
    assert "unstable where the stresses reach S (the run estimates it at every step) for " \
           "every time step" in text and "infx" not in text


class _PeerFailed:
    """Rank 0 of two seen from one process; rank 1's estimate failed with ``message``."""

    size, rank = 2, 0

    def __init__(self, message: str):
        self.message = message

    def allreduce(self, value, op):
        from mpi4py import MPI
        assert op == MPI.MIN                     # only the failure flag: no rate is reduced
        return min(value, 1)

    def bcast(self, obj, root):
        assert root == 1
        return self.message


def test_estimated_rate_fails_on_every_rank_when_one_rank_fails():
    """The law fails in the cells of rank 1 only: rank 0, whose estimate succeeded, raises
    too, with rank 1's message (it waited before in the reduction of the rates while rank 1
    raised: a hang under mpirun)."""
    from vpcontact.post.diagnostics import RateEstimateError
    with pytest.raises(RateEstimateError, match=r"^boom \(on rank 1 of 2\)$"):
        estimated_rate(Norton(EL, 1e-3, 2), STATE, np.zeros((1, 1)), comm=_PeerFailed("boom"))
