"""An episode's PerceptionSystem read through its ports now (test helpers)."""

from __future__ import annotations

from physcap_drake.agent.observation import Observation, observation_of
from physcap_drake.perception.perception_system import SIZES_PORT


def perception_context(episode):
    """The perception system's Context in the episode's simulator's."""
    return episode.perception.GetMyContextFromRoot(episode.api.simulator.get_context())


def look(episode) -> list:
    """The objects in view now (SeenObject, left to right)."""
    return list(episode.look().objects)


def observed(episode) -> Observation:
    """What the agent observes now: the view and its steady sizes, from the ports."""
    context = perception_context(episode)
    view = episode.perception.look(context)
    sizes = episode.perception.GetOutputPort(SIZES_PORT).Eval(context)
    return observation_of(view.objects, sizes, view.rgb, 0.0)


def module(episode):
    """The perception module in the perception's Context (with its memory)."""
    return episode.perception.memory(perception_context(episode)).module
