"""`physcap task ...`: look at a task's scene, and check the task with scripted solutions."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import cv2
import numpy as np
import typer
from rich.table import Table

from physcap_drake.app.episode import make_episode
from physcap_drake.commands.common import console, fail, save_json, trial_progress
from physcap_drake.commands.options import JsonOut
from physcap_drake.control.errors import SkillError
from physcap_drake.perception.offline_pointer import PointingError
from physcap_drake.station import ports
from physcap_drake.tasks.registry import TASKS, get_task

app = typer.Typer(help="The evaluation tasks in simulation.", no_args_is_help=True)

TaskName = Annotated[str, typer.Argument(help=f"One of: {', '.join(TASKS)}.")]


def _task_or_exit(name: str):
    try:
        return get_task(name)
    except KeyError as error:
        fail(error.args[0])


def parse_seeds(text: str) -> list[int]:
    """"0-9" -> 0..9; "1,4,7" -> [1, 4, 7]; "3" -> [3]. Raises ValueError naming the text."""
    seeds = []
    for part in text.split(","):
        low, _, high = part.partition("-")
        try:
            seeds.extend(range(int(low), int(high or low) + 1))
        except ValueError:
            raise ValueError(f"--seeds {text!r}: expected seeds like 0-9, 1,4,7 or 3") from None
    if not seeds:
        raise ValueError(f"--seeds {text!r} names no seed (write low-high with low <= high)")
    return seeds


@app.command("show")
def show(task: TaskName, seed: Annotated[int, typer.Option("--seed", min=0)] = 0,
         png: Annotated[Path | None, typer.Option("--png", help="Save the labelled camera "
                                                   "view here.")] = None) -> None:
    """Show a task's scene: its objects and prompt.

    Prints the episode's prompt and objects with the grasp point the camera-based locator
    finds for each, and with --png saves the camera view with each object's name drawn
    where it was found.
    """
    _task_or_exit(task)
    episode = make_episode(task, seed)
    console.print(f"[bold]{task}[/], seed {seed}: {episode.instance.prompt}")
    station = episode.robot.station
    context = station.GetMyContextFromRoot(episode.api.simulator.get_context())
    image = station.GetOutputPort(ports.CAMERA_RGB).Eval(context).data[:, :, :3].copy()
    image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    for index, obj in enumerate(episode.instance.objects):
        try:
            grasp = episode.api.get_object_pose(obj.visible.name)
        except PointingError:
            console.print(f"  {obj.visible.name:18s} ({obj.visible.describe()}): not in view")
            continue
        console.print(f"  {obj.visible.name:18s} ({obj.visible.describe()}): grasp point "
                      f"{np.round(grasp, 3).tolist()} m")
        u, v = episode.camera.project(grasp)[0]
        cv2.circle(image, (int(u), int(v)), 3, (255, 255, 255), -1)
        text_v = 20 + 16 * index  # one line per object at the top, joined to its point
        cv2.line(image, (int(u), int(v)), (int(u), text_v + 3), (255, 255, 255), 1)
        cv2.putText(image, obj.visible.name, (int(u) + 3, text_v),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.4, (40, 40, 40), 1, cv2.LINE_AA)
    if png is not None:
        cv2.imwrite(str(png), image)
        console.print(f"saved {png}")


@app.command("check")
def check(task: TaskName,
          seeds: Annotated[str, typer.Option("--seeds", help="e.g. 0-9 or 1,3,5")] = "0-9",
          wrong: Annotated[bool, typer.Option(
              "--wrong", help="Run a deliberately wrong solution instead (it must fail).")] = False,
          json_path: JsonOut = None) -> None:
    """Check a task with a scripted solution.

    Runs the oracle solution (it knows the answer: for testing the task, not the agent) on
    each seed and reports whether the task's success check passes; with --wrong, a
    deliberately wrong solution that must fail. --json writes one row per seed (seed,
    answer, success, skill_error, reason, robot_time_s).
    """
    solver = _task_or_exit(task)
    try:
        seed_list = parse_seeds(seeds)
    except ValueError as error:
        fail(str(error))
    rows = []
    with trial_progress(f"{task} ({'wrong' if wrong else 'oracle'})",
                        len(seed_list)) as advance:
        for seed in seed_list:
            episode = make_episode(task, seed)
            crashed = False
            try:
                solver.solve(episode.instance, episode.api, wrong=wrong)
                result = episode.check()
                success, reason = result.success, result.reason
            except SkillError as error:
                success, reason, crashed = False, f"skill error: {error}", True
            rows.append({"seed": seed, "answer": episode.instance.answer, "success": success,
                         "skill_error": crashed, "reason": reason,
                         "robot_time_s": episode.api.robot_time})
            advance(success)
    table = Table(title=f"{task}: {'wrong' if wrong else 'oracle'} solution")
    for column in ("seed", "answer", "success", "robot time (s)", "reason"):
        table.add_column(column)
    for row in rows:
        table.add_row(str(row["seed"]), row["answer"], "yes" if row["success"] else "no",
                      f"{row['robot_time_s']:.1f}", row["reason"])
    console.print(table)
    errors = sum(r["skill_error"] for r in rows)
    console.print(f"success {sum(r['success'] for r in rows)}/{len(rows)}"
                  + (f" ({errors} ended in a skill error, not by the success check)"
                     if errors else ""))
    if json_path is not None:
        save_json(json_path, rows)
