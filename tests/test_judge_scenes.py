"""The camera judge against the simulator's ground truth on rendered final scenes: the
task's answer put into its container by a test's hand (the simulated world settles for a
second), seen through the emulated RealSense (stereo depth faults) by RGB-D perception."""

from __future__ import annotations

import pytest
from pydrake.math import RigidTransform

from physcap_drake.app.episode import make_episode

#: (task, seed, container body, where the answer is dropped: offset from the container's
#: middle, m, and the ground truth's verdict, and words the camera's reason holds).
SCENES = [
    # Dropped against the tray's wall, the avocado settles leaning on its rim: its middle
    # over the tray, its side past the wall.
    ("pick_ripe_avocado", 0, "tray", (0.111, 0.085), False, "hangs over the edge of the "
                                                            "brown tray"),
    ("pick_ripe_avocado", 0, "tray", (0.05, 0.04), True, "alone in the brown tray"),
    ("identify_empty_can", 0, "tray", (0.0, 0.0), True, "alone in the brown tray"),
    ("identify_empty_can", 0, "tray", (0.1, 0.0), True, "alone in the brown tray"),
    ("empty_cup", 0, "basket", (0.0, 0.0), True, "alone in the"),
]


@pytest.mark.parametrize(("task", "seed", "container", "offset", "truth", "words"), SCENES)
def test_the_camera_judge_agrees_with_the_ground_truth(task, seed, container, offset, truth,
                                                       words):
    episode = make_episode(task, seed, perception="rgbd", judge="perception")
    try:
        plant, simulator = episode.plant, episode.api.simulator
        context = plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
        X_container = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName(container))
        plant.SetFreeBodyPose(context, episode.instance.body_of(plant, episode.instance.answer),
                              RigidTransform(X_container.translation() + [*offset, 0.03]))
        simulator.AdvanceTo(simulator.get_context().get_time() + 1.0)
        ground_truth, verdict = episode.ground_truth(), episode.check()
        assert ground_truth.success is truth, ground_truth.reason
        assert verdict.success is truth, (verdict.reason, ground_truth.reason)
        assert words in verdict.reason
    finally:
        episode.close()
