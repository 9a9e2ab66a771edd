"""The PerceptionSystem through its ports: one look per frame (Drake's cache), its memory in
its Context (a clone carries it), the sizes held across the looks that read them; and, on a
rendered scene, get_object_pose and the AgentSystem (its observation and the camera looks
of its robot calls) seeing the same objects from its one output."""

from __future__ import annotations

import numpy as np
import pytest
from perception_inputs import module, perception_context
from pydrake.common.value import AbstractValue
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U

from physcap_drake.app.episode import make_episode
from physcap_drake.perception.perception_system import (
    SIZES_PORT,
    VIEW_PORT,
    PerceptionSystem,
)
from physcap_drake.perception.seen_object import SeenObject
from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.robot_calls import GraspPoint, InView, Locate
from physcap_drake.station import ports

W, H = 8, 6


class Remembering:
    """A perception module that sees one object per distinct red value in the colour image
    (left to right) and names each new one in the order it first saw it (its memory)."""

    input_ports = (ports.CAMERA_RGB, ports.CAMERA_DEPTH)
    camera = None  # no sizes are read of these objects

    def __init__(self):
        self.names: dict[int, str] = {}
        self.looks = 0

    def look(self, images):
        self.looks += 1
        rgb = np.asarray(images[ports.CAMERA_RGB])
        seen = []
        for column in range(rgb.shape[1]):
            red = int(rgb[0, column, 0])
            if red and red not in self.names:
                self.names[red] = f"object {len(self.names) + 1}"
            if red and not any(s.name == self.names[red] for s in seen):
                mask = np.zeros(rgb.shape[:2], bool)
                mask[:, column] = True
                seen.append(SeenObject(VisibleObject(self.names[red], "can", "red"), mask,
                                       float(column), H / 2, np.array([0.3, 0.01 * red, 0.05]),
                                       0.1, np.zeros((3, 2))))
        return seen

    def known(self):
        return [VisibleObject(name, "can", "red") for name in self.names.values()]


def _rgb(*reds: int) -> AbstractValue:
    image = ImageRgba8U(W, H)
    for column, red in enumerate(reds):
        image.mutable_data[:, column, 0] = red
    return AbstractValue.Make(image)


@pytest.fixture
def fed():
    system = PerceptionSystem(Remembering())
    context = system.CreateDefaultContext()
    system.GetInputPort(ports.CAMERA_DEPTH).FixValue(context, ImageDepth32F(W, H))
    system.GetInputPort(ports.CAMERA_RGB).FixValue(context, _rgb(10, 20))
    return system, context


def test_one_look_per_frame_until_an_input_changes(fed):
    system, context = fed
    first = system.GetOutputPort(VIEW_PORT).Eval(context)
    assert [s.name for s in first.objects] == ["object 1", "object 2"]
    assert system.GetOutputPort(VIEW_PORT).Eval(context) is first
    assert system.memory(context).module.looks == 1
    system.GetInputPort(ports.CAMERA_RGB).FixValue(context, _rgb(30, 10))
    second = system.GetOutputPort(VIEW_PORT).Eval(context)
    assert system.memory(context).module.looks == 2
    # The memory named the red-10 object before: it keeps its name, the new one is third.
    assert [s.name for s in second.objects] == ["object 3", "object 1"]
    assert [k.name for k in second.known] == ["object 1", "object 2", "object 3"]
    assert second.frame != first.frame


def test_the_memory_is_in_the_context_a_clone_carries_it(fed):
    system, context = fed
    system.GetOutputPort(VIEW_PORT).Eval(context)
    clone = context.Clone()
    fresh = system.CreateDefaultContext()
    for other in (clone, fresh):
        system.GetInputPort(ports.CAMERA_DEPTH).FixValue(other, ImageDepth32F(W, H))
        system.GetInputPort(ports.CAMERA_RGB).FixValue(other, _rgb(20))
    assert [s.name for s in system.GetOutputPort(VIEW_PORT).Eval(clone).objects] == [
        "object 2"]
    assert [s.name for s in system.GetOutputPort(VIEW_PORT).Eval(fresh).objects] == [
        "object 1"]
    assert system.memory(context).module.looks == 1  # the clone's looks are its own


def test_the_view_keeps_its_images_as_they_were_looked_at(fed):
    system, context = fed
    view = system.GetOutputPort(VIEW_PORT).Eval(context)
    system.GetInputPort(ports.CAMERA_RGB).FixValue(context, _rgb(99, 99))
    assert view.rgb[0, 0, 0] == 10 and view.rgb.shape == (H, W, 4)
    assert view.depth.shape == (H, W)


@pytest.fixture(scope="module")
def episode():
    built = make_episode("identify_empty_can", 0, with_agent=True)
    yield built
    built.close()


def test_get_object_pose_and_the_agent_see_the_same_objects_from_one_look(episode):
    counting = module(episode)
    looks = []
    original = counting.look
    counting.look = lambda images: looks.append(1) or original(images)
    try:
        agent = episode.robot.agent
        context = agent.GetMyContextFromRoot(episode.api.simulator.get_context())
        observation = agent.observation(context)

        def answer(action):  # the agent's answer to a look of its code's robot calls
            return agent._answer(context, agent.state(context), action, 0.0)[1]

        view = episode.look()
        assert observation.names() == [s.name for s in view.objects]
        assert len(observation.names()) >= 4
        assert [s.name for s in answer(InView())] == observation.names()
        for seen in view.objects:
            np.testing.assert_array_equal(episode.api.get_object_pose(seen.name),
                                          seen.grasp_point)
            np.testing.assert_array_equal(answer(GraspPoint(seen.name)), seen.grasp_point)
            assert answer(Locate(seen.name)) is seen
        with pytest.raises(ValueError, match="basket"):
            answer(GraspPoint("green basket"))
        # The agent, its code's looks, get_object_pose and the judge: one output.
        assert len(looks) == 1
        sizes = episode.perception.GetOutputPort(SIZES_PORT).Eval(
            perception_context(episode))
        assert [round(g.top_z, 3) for g in sizes] == [o.height_m for o in observation.objects]
    finally:
        counting.look = original
