"""Fingertip inverse kinematics on the planning model: answers depend only on the request."""

from __future__ import annotations

import numpy as np
import pytest

from physcap_drake.control.errors import SkillRefused
from physcap_drake.control.ik import FingertipGoal, solve_fingertip_ik, tilt_from_vertical
from physcap_drake.control.planning_model import PlanningModel
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario

HOME_REACH = np.array([0.0, 1.2, -1.2, 0.0, 0.9, 0.0])  # rad: out over the table


@pytest.fixture(scope="module")
def model() -> PlanningModel:
    scenario = load_scenario(stations_dir() / "piper_table.yaml")
    config = scenario.station
    return PlanningModel(scenario.directives, config.arm_model, config.gripper_model)


def solve(model: PlanningModel, position) -> np.ndarray:
    return solve_fingertip_ik(model, FingertipGoal(np.array(position)), HOME_REACH,
                              opening=0.05, collision_margin=0.01, limit_margin=0.05)


def test_a_solution_puts_the_fingertip_on_the_target_nearly_pointing_down(model):
    q = solve(model, [0.35, 0.05, 0.10])
    pose = model.tcp_pose(q)
    np.testing.assert_allclose(pose.translation(), [0.35, 0.05, 0.10], atol=1e-4)
    # The top-down preference is a cost traded against the pull to the seed: 3° here.
    assert tilt_from_vertical(pose.rotation()) < np.radians(5.0)


def test_solves_share_a_context_without_influencing_each_other(model):
    # Every solve evaluates in the same scratch context of the model: what an earlier solve
    # left in it must not change a later answer, to the last bit.
    first = solve(model, [0.35, 0.05, 0.10])
    solve(model, [0.25, -0.20, 0.25])
    with pytest.raises(SkillRefused, match="out of reach"):
        solve(model, [0.90, 0.60, 0.05])
    np.testing.assert_array_equal(solve(model, [0.35, 0.05, 0.10]), first)
