"""`physcap bench perception`: RGB-D perception against the simulator's ground truth.

Design notes: docs/design/bench.md.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

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
    points = episode.api.locator.camera.back_project(cols, rows, depth[rows, cols])
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
        station = episode.robot.station
        context = station.GetMyContextFromRoot(episode.api.simulator.get_context())
        images = episode.api.locator.images(
            station.GetOutputPort(ports.CAMERA_RGB).Eval(context).data,
            station.GetOutputPort(ports.CAMERA_DEPTH).Eval(context).data, None)
        results = []
        for name, xy, visible, label_index in _truths(episode):
            try:
                seen = episode.api.locator.locate(name, images)
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
