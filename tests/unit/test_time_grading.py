"""run --tol's graded time steps (app/studies/tolerance.py): the split counts against
hand-worked cases, the new grid against the old, the ratio against its budget, and a
graded or explicit time grid accepted but explicit times with time.adaptive refused."""
import numpy as np
import pytest

from vpcontact.studies.tolerance import (
    MAX_SPLIT,
    SAFETY,
    check_tolerance_case,
    finer_in_time,
    graded_times,
    split_counts,
    time_ratio,
)


def test_uniform_errors_split_every_step_by_the_ratio():
    """m_n = the ratio, rounded up to a power of 2."""
    assert split_counts(np.full(5, 0.3), 2.0).tolist() == [2] * 5
    assert split_counts(np.full(3, 0.3), 2.5).tolist() == [4] * 3      # a power of 2


def test_a_jump_in_the_first_step_splits_it_alone():
    """l = (8, 1, 2, 0.5), ratio 4: 4 l_n / 8 = (4, 0.5, 1, 0.25) -> m_n = (4, 1, 1, 1)."""
    assert split_counts(np.array([8.0, 1.0, 2.0, 0.5]), 4.0).tolist() == [4, 1, 1, 1]
    assert split_counts(np.array([8.0, 1.0, 2.0, 4.0]), 4.0).tolist() == [4, 1, 1, 2]


def test_counts_are_capped_and_missing_errors_count_as_the_largest():
    assert split_counts(np.array([1.0, 0.1]), 50.0).tolist() == [MAX_SPLIT, 8]
    assert split_counts(np.array([1.0, np.nan, 0.0]), 3.0).tolist() == [4, 4, 1]
    assert split_counts(np.zeros(2), 2.0).tolist() == [2, 2]


def test_graded_times_keep_the_old_points_and_split_evenly():
    times = [0.0, 0.5, 0.75, 1.0]
    new = graded_times(times, [4.0, 1.0, 2.0], 2.0)         # m = (2, 1, 1)
    assert new == pytest.approx([0.0, 0.25, 0.5, 0.75, 1.0], abs=1e-15)
    assert new[-1] == 1.0
    new = graded_times(times, [1.0, 1.0, 1.0], 3.0)         # m = 4 everywhere
    assert len(new) == 13 and all(t in new for t in times)
    assert np.diff(new) == pytest.approx(np.repeat(np.diff(times) / 4, 4))


def test_time_ratio_against_its_budget():
    """tol x scale = 1: the space part 0.2 leaves 0.8 (times SAFETY) to the time part; a
    space part above half leaves half; never below 2."""
    est = {"time": 4.0, "space": 0.2, "scale": 10.0}
    assert time_ratio(est, 0.1) == pytest.approx(4.0 / (SAFETY * 0.8))
    est = {"time": 4.0, "space": 0.9, "scale": 10.0}
    assert time_ratio(est, 0.1) == pytest.approx(4.0 / (SAFETY * 0.5))
    assert time_ratio({"time": 0.1, "space": 0.1, "scale": 10.0}, 0.1) == 2.0


def test_finer_in_time_writes_times_or_doubles_an_adaptive_grid():
    raw = {"time": {"T": 1.0, "N": 2, "scheme": "explicit"}}
    local = [(0.5, 0.5, 2.0), (1.0, 0.5, 0.5)]
    new = finer_in_time(raw, local, 2.0)
    assert new["time"] == {"scheme": "explicit", "times": [0.0, 0.25, 0.5, 1.0]}
    assert raw["time"]["N"] == 2                                  # not modified
    adaptive = {"time": {"T": 1.0, "k": 0.25, "adaptive": {"max_change": 0.2}}}
    new = finer_in_time(adaptive, local, 2.0)
    assert new["time"]["N"] == 8 and new["time"]["adaptive"]["max_change"] == 0.1


def test_explicit_times_with_adaptive_steps_are_refused():
    class Case:
        source = "c.yaml"
    check_tolerance_case(Case, {"time": {"times": [0.0, 1.0]}})
    check_tolerance_case(Case, {"time": {"T": 1.0, "N": 4, "grading": 1.2}})
    with pytest.raises(Exception, match="c.yaml: time.times"):
        check_tolerance_case(Case, {"time": {"times": [0.0, 1.0], "adaptive": {}}})
