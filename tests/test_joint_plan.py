"""JointPlan: positions before, along and after its segments; no position at a NaN time."""

import numpy as np
import pytest
from pydrake.trajectories import PiecewisePolynomial

from physcap_drake.control.joint_plan import JointPlan

Q0 = np.zeros(6)
Q1 = np.array([0.6, -0.4, 0.2, 0.0, 1.0, -1.0])


def _plan() -> JointPlan:
    """From Q0 to Q1 in a straight line over 1 s, starting at 2 s of sim time."""
    line = PiecewisePolynomial.FirstOrderHold([0.0, 1.0], np.column_stack([Q0, Q1]))
    return JointPlan(2.0, Q0.copy(), (line,))


def test_positions_hold_before_follow_the_segment_and_hold_after():
    q = _plan().positions(np.array([1.0, 2.0, 2.5, 3.0, 4.0]))
    np.testing.assert_allclose(q[:, 0], Q0)  # before the start: the first position
    np.testing.assert_allclose(q[:, 2], 0.5 * (Q0 + Q1))  # half way along the line
    np.testing.assert_allclose(q[:, 3], Q1)
    np.testing.assert_allclose(q[:, 4], Q1)  # after the end: the last position


@pytest.mark.parametrize("plan", [_plan(), JointPlan.hold(Q1)], ids=["moving", "holding"])
@pytest.mark.parametrize("times", [[2.5, np.nan], [np.nan]], ids=["among_others", "alone"])
def test_a_nan_time_is_refused_not_filled_with_whatever_memory_holds(plan, times):
    with pytest.raises(ValueError, match="NaN time"):
        plan.positions(np.array(times))


def _three_segments() -> JointPlan:
    """Q0 -> Q1 in 0.3 s, a cubic back towards Q0 in 0.7 s, Q1 again in 0.45 s, from 1.37 s
    (segments whose own time does not start at 0, as a time-scaled path's need not)."""
    middle = np.column_stack([Q1, 0.5 * Q1, 0.1 * Q1])
    return JointPlan(1.37, Q0.copy(), (
        PiecewisePolynomial.FirstOrderHold([0.11, 0.41], np.column_stack([Q0, Q1])),
        PiecewisePolynomial.CubicWithContinuousSecondDerivatives([0.05, 0.25, 0.75], middle),
        PiecewisePolynomial.FirstOrderHold([0.2, 0.65], np.column_stack([0.1 * Q1, Q1]))))


def test_a_time_sampled_alone_gives_the_bits_it_gives_among_others():
    # The executor checks one time before sampling many: both must agree to the last bit,
    # at the segments' joints and a hair either side of them too.
    plan = _three_segments()
    joints = [1.37, 1.37 + 0.3, 1.37 + 0.3 + 0.7, plan.end_time]
    times = [*joints, *(np.nextafter(t, side) for t in joints for side in (0.0, 10.0)),
             0.0, 1.0, 3.5, *np.random.default_rng(3).uniform(1.3, 2.9, 40)]
    together = plan.positions(np.array(times))
    for i, t in enumerate(times):
        alone = plan.positions(np.array([t]))
        assert alone.shape == (6, 1)
        assert np.array_equal(alone[:, 0], together[:, i]), t
