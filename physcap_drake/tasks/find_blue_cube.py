"""find_blue_cube: three blue cubes, one hidden under one of two large paper cups.

Success: all three cubes in the camera's view, no cup knocked over, and every cup that was
moved (lifted to look under it) standing upright on the table or the wooden tray, not left in
the gripper, on another object or on its side.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

from physcap_drake.perception.offline_pointer import MIN_PIXELS
from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.station import ports
from physcap_drake.tasks.ground_truth import (
    STAY_TOLERANCE,
    check_upright_and_resting,
    choose_answer,
    displacement,
    tilt,
)
from physcap_drake.tasks.placement import TRAY_FLOOR, PlaceCheck, move_to_tray
from physcap_drake.tasks.task_instance import SceneObject, TaskInstance
from physcap_drake.tasks.tray_tasks import TRAY_BOTTOM

#: The cups stand in a row behind the visible cubes (world frame, m), each jittered.
CUP_X, CUP_Y = 0.44, (0.33, 0.18, 0.03)
CUBE_X, CUBE_Y = 0.30, (0.255, 0.105)
JITTER = 0.008
#: A cup is lifted at half its height (m); it counts as knocked over past this tilt (rad).
CUP_GRASP_HEIGHT = {"large": 0.065, "small": 0.033}
KNOCKED_OVER = np.radians(30.0)
#: This task's own number in its random streams.
STREAM = 17


@dc.dataclass(frozen=True)
class FindBlueCube:
    name: str = "find_blue_cube"
    scenario_file: str = "find_blue_cube.yaml"
    prompt: str = ("Three blue cubes of the same size are somewhere on the table, but only two "
                   "are in sight. Find the third one so that all three cubes can be seen by "
                   "the camera. Lift a cup straight up to look under it and put lifted cups "
                   "on the wooden tray; do not knock any cup over.")

    def instance(self, seed: int, answer: str = "") -> TaskInstance:
        rng = np.random.default_rng((seed, STREAM))
        sizes = list(rng.permutation(["large", "large", "small"]))
        cups, large_count = [], 0
        for index, (size, y) in enumerate(zip(sizes, CUP_Y, strict=True)):
            if size == "large":
                large_count += 1
                name = f"large cup {large_count}"  # numbered left to right in the image
            else:
                name = "small cup"
            xy = (CUP_X + rng.uniform(-JITTER, JITTER), y + rng.uniform(-JITTER, JITTER))
            cups.append(SceneObject(f"cup_{index}", f"objects/paper_cup_{size}",
                                    VisibleObject(name, "cup", "white", size=size), xy))
        answer = choose_answer(seed, STREAM, [c.visible.name for c in cups
                                              if c.visible.size == "large"], answer, self.name)
        hiding = next(c for c in cups if c.visible.name == answer)
        cups = [dc.replace(c, hidden={"hides_cube": c is hiding}) for c in cups]
        cubes = [SceneObject(f"cube_{i}", "scene/cube_5cm",
                             VisibleObject(f"blue cube {i + 1}", "cube", "blue"),
                             (CUBE_X + rng.uniform(-JITTER, JITTER),
                              y + rng.uniform(-JITTER, JITTER)), yaw=rng.uniform(-0.3, 0.3))
                 for i, y in enumerate(CUBE_Y)]
        cubes.append(SceneObject("cube_2", "scene/cube_5cm",
                                 VisibleObject("blue cube 3", "cube", "blue"), hiding.xy,
                                 hidden={"under": answer}))
        return TaskInstance(self.name, seed, self.prompt, tuple(cups + cubes), answer)

    def check(self, episode) -> PlaceCheck:
        """Ground truth: no cup knocked over, every moved cup upright on the table or the
        tray, and all three cubes seen by the camera."""
        instance, plant, plant_context = episode.instance, episode.plant, episode.plant_context
        station = episode.robot.station
        station_context = station.GetMyContextFromRoot(episode.api.simulator.get_context())
        tray = plant.GetBodyByName("tray")
        for obj in instance.objects:
            if obj.visible.category != "cup":
                continue
            body = instance.body_of(plant, obj.visible.name)
            angle = tilt(plant, plant_context, body)
            if angle > KNOCKED_OVER:
                return PlaceCheck(False, f"the {obj.visible.name} was knocked over "
                                         f"({np.degrees(angle):.0f}°)")
            if displacement(plant, plant_context, body, obj.xy) > STAY_TOLERANCE:
                misplaced = check_upright_and_resting(instance, plant, plant_context,
                                                      obj.visible.name, tray, TRAY_FLOOR)
                if misplaced is not None:
                    return PlaceCheck(False, misplaced.reason + " after it was lifted")
        label = station.GetOutputPort(ports.CAMERA_LABEL).Eval(station_context).data
        for obj in instance.objects:
            if obj.visible.category == "cube":
                index = int(instance.body_of(plant, obj.visible.name).index())
                pixels = int((label == index).sum())
                if pixels < MIN_PIXELS:
                    return PlaceCheck(False, f"the camera does not see {obj.visible.name} "
                                             f"({pixels} pixels)")
        return PlaceCheck(True, "all three cubes are in sight, no cup was knocked over and "
                                "the lifted cups stand upright")

    def solve(self, instance: TaskInstance, api, wrong: bool = False) -> None:
        """Lift the cup that hides the cube (with `wrong`, the other large cup) and put it
        on the tray."""
        cups = [o for o in instance.objects if o.visible.category == "cup"]
        target = next(c for c in cups if (c.visible.name == instance.answer) != wrong
                      and c.visible.size == "large")
        height = CUP_GRASP_HEIGHT[target.visible.size]
        move_to_tray(api, np.array([*target.xy, height]), height, TRAY_BOTTOM)
