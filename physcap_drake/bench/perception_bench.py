"""`physcap bench perception`: RGB-D perception against the simulator's ground truth.

Design notes: docs/design/bench.md.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.math import RigidTransform

from physcap_drake.app.episode import BASKET, TRAY, Episode, make_episode
from physcap_drake.perception.colors import matches
from physcap_drake.perception.grasp import grasp_point_from_points
from physcap_drake.perception.phrases import PointingError
from physcap_drake.station import ports, scene_snapshot

#: The rendering sensor inside the station behind an emulated RealSense named "camera".
_SENSOR = "render_camera_camera"


@dc.dataclass
class LocatedObject:
    """One object: its name in the task, the grasp point error (m), and what perception
    said it looks like against what it is ("" when they agree)."""

    task: str
    seed: int
    name: str
    error_m: float
    seen_as: str
    mismatch: str


def _truths(episode: Episode) -> list[tuple[str, np.ndarray, object]]:
    """(name, true x y, the task's VisibleObject) of every object in view and container."""
    plant, context = scene_snapshot(episode.robot.station, episode.api.simulator.get_context())
    found = []
    for obj in episode.instance.objects:
        if obj.hidden.get("under"):
            continue
        body = episode.instance.body_of(plant, obj.visible.name)
        found.append((obj.visible.name, plant.EvalBodyPoseInWorld(context, body)
                      .translation()[:2], obj.visible, int(body.index())))
    for container in (TRAY, BASKET):
        if plant.HasBodyNamed(container.category):
            body = plant.GetBodyByName(container.category)
            found.append((container.name, plant.EvalBodyPoseInWorld(context, body)
                          .translation()[:2], container, int(body.index())))
    return found


def _true_grasp_height(episode: Episode, label_index: int) -> float:
    """The grasp rule's height for the object's true top (perfect depth at its mask)."""
    station = episode.robot.station
    sensor = station.GetSubsystemByName(_SENSOR)
    context = sensor.GetMyContextFromRoot(episode.api.simulator.get_context())
    depth = sensor.depth_image_32F_output_port().Eval(context).data[:, :, 0]
    label = sensor.label_image_output_port().Eval(context).data[:, :, 0]
    rows, cols = np.nonzero((label == label_index) & np.isfinite(depth))
    points = episode.camera.back_project(cols, rows, depth[rows, cols])
    return float(grasp_point_from_points(points)[0][2])


def _mismatch(seen, truth) -> str:
    problems = []
    if seen.category != truth.category:
        problems.append(f"category {seen.category} (is {truth.category})")
    if not matches(seen.color, truth.color) and not matches(truth.color, seen.color):
        problems.append(f"colour {seen.color} (is {truth.color})")
    if seen.straw != truth.straw:
        problems.append("straw seen" if seen.straw else "straw missed")
    if seen.size != truth.size:
        problems.append(f"size {seen.size or 'none'} (is {truth.size or 'none'})")
    return ", ".join(problems)


def bench_episode(task: str, seed: int) -> list[LocatedObject]:
    """Locates every visible object of one episode's first view (see the design notes)."""
    episode = make_episode(task, seed, perception="rgbd")
    try:
        view = episode.look()
        results = []
        for name, xy, visible, label_index in _truths(episode):
            try:
                seen = episode.api.locator.locate(name, view)
            except PointingError as error:
                results.append(LocatedObject(task, seed, name, float("inf"), "",
                                             f"not found: {error}"))
                continue
            truth = np.array([*xy, _true_grasp_height(episode, label_index)])
            results.append(LocatedObject(
                task, seed, name, float(np.linalg.norm(seen.grasp_point - truth)),
                seen.name, _mismatch(seen.visible, visible)))
        return results
    finally:
        episode.close()


def summarize(results: list[LocatedObject]) -> dict:
    """Per task and overall: objects, worst and mean grasp-point error (mm), objects not
    found and attribute mismatches."""
    def figures(items: list[LocatedObject]) -> dict:
        errors = [r.error_m for r in items if np.isfinite(r.error_m)]
        return {"objects": len(items), "not_found": sum(not np.isfinite(r.error_m)
                                                        for r in items),
                "worst_error_mm": round(1000 * max(errors, default=0.0), 2),
                "mean_error_mm": round(1000 * float(np.mean(errors)) if errors else 0.0, 2),
                "attribute_mismatches": sum(bool(r.mismatch) for r in items)}

    tasks = sorted({r.task for r in results})
    return {"tasks": {t: figures([r for r in results if r.task == t]) for t in tasks},
            "all": figures(results),
            "mismatches": [dc.asdict(r) for r in results if r.mismatch]}


#: Where the oracle sets objects down, relative to the container's floor centre (x, y, m):
#: one after the other, each look after one more.
SLOTS = {"tray": ((-0.08, -0.04), (0.08, -0.04), (0.0, 0.05)),
         "basket": ((-0.06, 0.0), (0.06, 0.0))}
#: A floor this thick under what stands in the container, m.
FLOORS = {"tray": 0.008, "basket": 0.004}
#: A seen object stands for a true one whose centre is this near its grasp point, m.
MATCH_DISTANCE = 0.03
#: Label pixels for a true object to count as in view.
IN_VIEW_PIXELS = 200
#: Truly upright below this tilt, deg (as the tasks judge it); "tilted" / "lying" above.
UPRIGHT_DEG = 10.0


@dc.dataclass
class LookAfterMoves:
    """One look after the oracle moved `moved` objects into the container: true objects in
    view, merges (one seen object for several true ones, or a container for any), phantoms
    (seen objects for no true one), identity switches (a true object under another name
    than at first), objects not found and stance errors, each with what it was."""

    task: str
    seed: int
    moved: int
    in_view: int
    merges: list[str]
    phantoms: list[str]
    switches: list[str]
    not_found: list[str]
    state_errors: list[str]


def _in_view(episode) -> dict[str, tuple[np.ndarray, float]]:
    """True objects the camera shows now: name -> (x y, tilt in degrees)."""
    plant, context = scene_snapshot(episode.robot.station, episode.api.simulator.get_context())
    station = episode.robot.station
    label = station.GetOutputPort(ports.CAMERA_LABEL).Eval(
        station.GetMyContextFromRoot(episode.api.simulator.get_context())).data
    found = {}
    for obj in episode.instance.objects:
        body = episode.instance.body_of(plant, obj.visible.name)
        if int((label == int(body.index())).sum()) < IN_VIEW_PIXELS:
            continue
        pose = plant.EvalBodyPoseInWorld(context, body)
        tilt = np.degrees(np.arccos(np.clip(pose.rotation().matrix()[2, 2], -1.0, 1.0)))
        found[obj.visible.name] = (pose.translation()[:2], float(tilt))
    return found


def _look(episode):
    return list(episode.look().objects)


def _compare(task, seed, moved, truths, seen, first_names, upright_kinds) -> LookAfterMoves:
    # Containers take part: a true object matched to one was merged into it.
    objects = list(seen)
    matched: dict[str, list[str]] = {s.name: [] for s in objects}
    containers = {s.name for s in seen if s.area is not None}
    result = LookAfterMoves(task, seed, moved, len(truths), [], [], [], [], [])
    for name, (xy, tilt) in truths.items():
        near = min(objects, key=lambda s: np.linalg.norm(s.grasp_point[:2] - xy),
                   default=None)
        if near is None or np.linalg.norm(near.grasp_point[:2] - xy) > MATCH_DISTANCE:
            result.not_found.append(name)
            continue
        matched[near.name].append(name)
        if first_names.setdefault(name, near.name) != near.name:
            result.switches.append(f"{name}: '{first_names[name]}' now '{near.name}'")
        upright = tilt < UPRIGHT_DEG
        if near.visible.category in upright_kinds and near.state and (
                (near.state == "upright") != upright):
            result.state_errors.append(f"{name}: seen {near.state} {near.tilt_deg:.0f}°, "
                                       f"is tilted {tilt:.0f}°")
    for seen_name, names in matched.items():
        if len(names) > 1 or (names and seen_name in containers):
            result.merges.append(f"'{seen_name}' for {', '.join(names)}")
        elif not names and seen_name not in containers:
            result.phantoms.append(seen_name)
    return result


def bench_moves(task: str, seed: int, tell: bool = True) -> list[LookAfterMoves]:
    """The first view, and a look after each object the oracle sets down in the container
    (SLOTS; sim-only teleports, nothing simulated between), compared with the truth. With
    `tell`, the oracle tells perception where it set the object down, under the name
    perception gave it at first (as the robot would after `place_in`)."""
    from physcap_drake.perception.object_state import STANDING_KINDS

    episode = make_episode(task, seed, perception="rgbd")
    try:
        plant, context = episode.plant, episode.plant_context
        kind = "tray" if plant.HasBodyNamed("tray") else "basket"
        floor = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName(kind)).translation()
        movable = [o for o in episode.instance.objects if not o.hidden.get("under")]
        first_names: dict[str, str] = {}
        looks = [_compare(task, seed, 0, _in_view(episode), _look(episode), first_names,
                          STANDING_KINDS)]
        for count, (obj, slot) in enumerate(zip(movable, SLOTS[kind], strict=False), 1):
            body = episode.instance.body_of(plant, obj.visible.name)
            pose = plant.EvalBodyPoseInWorld(context, body)
            plant.SetFreeBodyPose(context, body, RigidTransform(pose.rotation(), [
                floor[0] + slot[0], floor[1] + slot[1],
                pose.translation()[2] + floor[2] + FLOORS[kind]]))
            if tell and obj.visible.name in first_names:
                memory = episode.perception.memory(episode.perception.GetMyContextFromRoot(
                    episode.api.simulator.get_context()))
                memory.module.memory.set_down(first_names[obj.visible.name], floor[:2] + slot)
            looks.append(_compare(task, seed, count, _in_view(episode), _look(episode),
                                  first_names, STANDING_KINDS))
        return looks
    finally:
        episode.close()


def summarize_moves(looks: list[LookAfterMoves]) -> dict:
    """Per task and overall: looks, and the merges, phantoms, identity switches, objects
    not found and stance errors over them (first views included, moved == 0)."""
    def figures(items):
        return {"looks": len(items), **{key: sum(len(getattr(i, key)) for i in items)
                                        for key in ("merges", "phantoms", "switches",
                                                    "not_found", "state_errors")}}

    tasks = sorted({look.task for look in looks})
    return {"tasks": {t: figures([x for x in looks if x.task == t]) for t in tasks},
            "all": figures(looks),
            "problems": [dc.asdict(x) for x in looks if any(
                getattr(x, k) for k in ("merges", "phantoms", "switches", "not_found",
                                        "state_errors"))]}
