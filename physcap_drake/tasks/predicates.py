"""The success predicates a task file may ask for, judged from the simulator's ground truth
(never shown to agents): the answer alone in the destination, the others where they stood,
objects not knocked over and upright once moved, objects in the camera's view.
"""

from __future__ import annotations

import numpy as np

from physcap_drake.perception.offline_pointer import MIN_PIXELS
from physcap_drake.station import ports
from physcap_drake.tasks.ground_truth import (
    STAY_TOLERANCE,
    check_others_stayed,
    check_upright_and_resting,
    displacement,
    near_container,
    tilt,
)
from physcap_drake.tasks.placement import PlaceCheck, check_in_tray

#: An object counts as knocked over past this tilt, rad.
KNOCKED_OVER = np.radians(30.0)


def check_success(success, destination, episode, radius_of) -> PlaceCheck:
    """The first predicate of `success` (task_file.Success) that fails, in the order: time
    limit, answer alone in the destination, upright, all visible, others stay.
    `radius_of(obj)`: an object's reach around its axis, m."""
    instance, plant, context = episode.instance, episode.plant, episode.plant_context
    container = plant.GetBodyByName(destination.body)
    robot_time = episode.api.robot_time
    if success.time_limit_s and robot_time > success.time_limit_s:
        return PlaceCheck(False, f"over the time limit ({robot_time:.0f} s > "
                                 f"{success.time_limit_s:.0f} s)")
    said = []
    if success.answer_alone_in_destination:
        failed = answer_alone_in(instance, plant, context, container, destination,
                                 success.answer_upright, radius_of)
        if failed:
            return failed
        said.append(f"the {instance.answer} alone is in the {destination.name}")
    if success.upright:
        failed = not_knocked_over(instance, plant, context, success.upright, container,
                                  destination.floor_m)
        if failed:
            return failed
        said.append(f"no {success.upright} was knocked over and the lifted ones stand "
                    "upright")
    if success.all_visible:
        failed = all_in_view(episode, success.all_visible)
        if failed:
            return failed
        said.append(f"every {success.all_visible} is in sight")
    if success.others_stay:
        failed = check_others_stayed(instance, plant, context)
        if failed:
            return failed
        said.append("the others stand where they stood")
    return PlaceCheck(True, "; ".join(said) or "nothing to check")


def answer_alone_in(instance, plant, context, container, destination, upright: bool,
                    radius_of) -> PlaceCheck | None:
    """A failed check if the answer is not wholly in the container (upright there if
    `upright`) or another object is in it; `radius_of(obj)`: its reach around its axis, m."""
    inner_half = np.array(destination.inner_half_m)
    for obj in instance.objects:
        body = instance.body_of(plant, obj.visible.name)
        if obj.visible.name == instance.answer:
            inside = check_in_tray(plant, context, body, container, radius_of(obj), upright,
                                   inner_half=inner_half, floor=destination.floor_m,
                                   label=obj.visible.name, container=destination.name)
            if not inside.success:
                return PlaceCheck(False, f"the {obj.visible.name} (the answer) is not in the "
                                         f"{destination.name}: {inside.reason}")
        elif near_container(plant, context, body, container, inner_half):
            return PlaceCheck(False, f"the {obj.visible.name} is in the {destination.name}, "
                                     f"but the answer was the {instance.answer}")
    return None


def not_knocked_over(instance, plant, context, category: str, container,
                     floor: float) -> PlaceCheck | None:
    """A failed check if an object of `category` is tilted past KNOCKED_OVER, or was moved
    and does not stand upright on the table or in the container."""
    for obj in instance.objects:
        if obj.visible.category != category:
            continue
        body = instance.body_of(plant, obj.visible.name)
        angle = tilt(plant, context, body)
        if angle > KNOCKED_OVER:
            return PlaceCheck(False, f"the {obj.visible.name} was knocked over "
                                     f"({np.degrees(angle):.0f}°)")
        if displacement(plant, context, body, obj.xy) > STAY_TOLERANCE:
            misplaced = check_upright_and_resting(instance, plant, context, obj.visible.name,
                                                  container, floor)
            if misplaced is not None:
                return PlaceCheck(False, misplaced.reason + " after it was lifted")
    return None


def all_in_view(episode, category: str) -> PlaceCheck | None:
    """A failed check naming the first object of `category` the camera's label image shows
    in fewer than MIN_PIXELS pixels."""
    instance, plant = episode.instance, episode.plant
    station = episode.robot.station
    station_context = station.GetMyContextFromRoot(episode.api.simulator.get_context())
    label = station.GetOutputPort(ports.CAMERA_LABEL).Eval(station_context).data
    for obj in instance.objects:
        if obj.visible.category == category:
            index = int(instance.body_of(plant, obj.visible.name).index())
            pixels = int((label == index).sum())
            if pixels < MIN_PIXELS:
                return PlaceCheck(False, f"the camera does not see {obj.visible.name} "
                                         f"({pixels} pixels)")
    return None
