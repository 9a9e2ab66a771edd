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
def test_a_nan_time_is_refused_not_filled_with_whatever_memory_holds(plan):
    with pytest.raises(ValueError, match="NaN time"):
        plan.positions(np.array([2.5, np.nan]))
