"""Valid robot calls that used to hurt the arm and the scene (issue 43), in simulation, with the
contact results and the objects' speeds read after every simulator step: the robot never
presses on the table or the tray with more than 15 N and never throws an object faster than
0.5 m/s; the harmful motion is refused or stopped."""

from __future__ import annotations

import numpy as np
import pytest

from physcap_drake.app.episode import make_episode
from physcap_drake.control.requests import MoveGripper, MoveToPose, SkillState
from physcap_drake.robot_api import CLIENT

#: Most force of the robot on the table or the tray, N; fastest an object may move, m/s.
MAX_FURNITURE_FORCE = 15.0
MAX_OBJECT_SPEED = 0.5
ROBOT = ("piper", "piper_gripper")
FURNITURE = ("table", "tray")


class Watched:
    """An episode's robot driven through its `robot.request` port, its world watched after
    every simulator step: the largest robot–furniture contact force (N) and object speed
    (m/s) so far, with the pair or body they were seen on."""

    def __init__(self, task: str, seed: int):
        self.episode = make_episode(task, seed)
        self.plant = plant = self.episode.plant
        self._robot = {plant.GetModelInstanceByName(name) for name in ROBOT}
        self._furniture = {plant.GetModelInstanceByName(name) for name in FURNITURE}
        self._objects = [plant.get_body(index) for index in plant.GetFloatingBaseBodies()
                         if plant.get_body(index).model_instance() not in self._furniture]
        self.force, self.speed = (0.0, ""), (0.0, "")

    def _watch(self, root) -> None:
        plant = self.plant
        context = plant.GetMyContextFromRoot(root)
        contacts = plant.get_contact_results_output_port().Eval(context)
        for i in range(contacts.num_point_pair_contacts()):
            info = contacts.point_pair_contact_info(i)
            bodies = (plant.get_body(info.bodyA_index()), plant.get_body(info.bodyB_index()))
            models = {body.model_instance() for body in bodies}
            force = float(np.linalg.norm(info.contact_force()))
            if models & self._robot and models & self._furniture and force > self.force[0]:
                self.force = (force, " and ".join(body.name() for body in bodies))
        for body in self._objects:
            speed = float(np.linalg.norm(
                plant.EvalBodySpatialVelocityInWorld(context, body).translational()))
            if speed > self.speed[0]:
                self.speed = (speed, body.name())

    def request(self, action) -> SkillState:
        """Runs `action` until it is answered, watching every step; how it ended."""
        robot, clock = self.episode.robot, self.episode.api.clock
        request = robot.send(clock, CLIENT, action)
        port = robot.status_output

        def answered(root) -> bool:
            self._watch(root)
            return port.Eval(root).finished(request)

        assert clock.run_until(answered, timeout=30.0)
        self.status = port.Eval(clock.context)
        return self.status.state

    def locate(self, name: str) -> np.ndarray:
        return self.episode.api.get_object_pose(name)

    def assert_unharmed(self) -> None:
        assert self.force[0] <= MAX_FURNITURE_FORCE, f"{self.force[0]:.1f} N on {self.force[1]}"
        assert self.speed[0] <= MAX_OBJECT_SPEED, f"{self.speed[1]} at {self.speed[0]:.2f} m/s"


@pytest.fixture
def blue_cube_scene():
    watched = Watched("find_blue_cube", 0)
    yield watched
    watched.episode.close()


def test_a_gripper_pressed_onto_a_cup_is_stopped_at_once_and_lifts_off_gently(
        blue_cube_scene):
    """The open gripper sent through a cup's top: its palm used to press on the cup for the
    2 s the motion was given past its planned end; it is stopped where it is as soon as it
    falls behind its plan, and the next motion lifts off from there."""
    scene = blue_cube_scene
    cup = scene.locate("large cup 1")
    assert scene.request(MoveGripper(0.1, 15.0, "open_gripper")) is SkillState.SUCCEEDED
    assert scene.request(MoveToPose(cup + [0.0, 0.0, 0.12])) is SkillState.SUCCEEDED
    assert scene.request(MoveToPose([cup[0], cup[1], 0.01])) is SkillState.FAILED
    assert "blocked" in scene.status.message and "stopped where it is" in scene.status.message
    assert scene.status.finished_at - scene.status.started_at < 1.0  # not 2 s past the end
    assert scene.request(MoveToPose(cup + [0.0, 0.0, 0.15])) is SkillState.SUCCEEDED
    scene.assert_unharmed()


def test_a_held_cube_is_not_driven_into_the_table(blue_cube_scene):
    """A cube held 25 mm below the fingertips used to be pressed into the table with 51 N
    by goto_pose(z = 6 mm), which 'succeeded'; it is refused, naming what would collide."""
    scene = blue_cube_scene
    cube = scene.locate("blue cube 1")
    scene.request(MoveGripper(0.1, 15.0, "open_gripper"))
    assert scene.request(MoveToPose(cube, None, 0.12)) is SkillState.SUCCEEDED
    assert scene.request(MoveGripper(0.0, 15.0, "close_gripper")) is SkillState.SUCCEEDED
    assert scene.request(MoveToPose(cube + [0.0, 0.0, 0.05])) is SkillState.SUCCEEDED
    assert scene.request(MoveToPose([cube[0] + 0.02, cube[1], 0.006])) is SkillState.REFUSED
    assert "held object" in scene.status.message and "table" in scene.status.message
    # Set down as high as it stood: allowed.
    assert scene.request(MoveToPose(cube + [0.02, 0.0, 0.0])) is SkillState.SUCCEEDED
    scene.assert_unharmed()


def test_a_low_move_across_the_tray_is_refused(blue_cube_scene):
    """Fingertips 15 mm above the table, across the tray (walls 23 mm high): the motion
    used to 'succeed' after striking it; it is refused, naming the tray."""
    scene = blue_cube_scene
    assert scene.request(MoveToPose([0.30, -0.10, 0.015])) is SkillState.SUCCEEDED
    assert scene.request(MoveToPose([0.30, -0.44, 0.015])) is SkillState.REFUSED
    assert "tray" in scene.status.message
    scene.assert_unharmed()
