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
from physcap_drake.scenario_errors import ScenarioError
from physcap_drake.station import ports
from physcap_drake.tasks.answer_hidden import answer_shows
from physcap_drake.tasks.registry import TASKS, get_task

app = typer.Typer(help="The evaluation tasks in simulation.", no_args_is_help=True)

TaskName = Annotated[str, typer.Argument(help=f"One of: {', '.join(TASKS)}; or a task file "
                                                 "(docs/task_files.md).")]


def _task_or_exit(name: str):
    try:
        return get_task(name)
    except KeyError as error:
        fail(error.args[0])
    except ScenarioError as error:
        fail(str(error))


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
          oracle_only: Annotated[bool, typer.Option(
              "--oracle-only", help="Skip the wrong solutions (half the time).")] = False,
          json_path: JsonOut = None) -> None:
    """Check a task with scripted right and wrong solutions.

    On each seed: the answer cannot be told by looking (at least two plausible objects,
    and the same scene whichever is the answer); the oracle solution (it knows the answer:
    for testing the task, not the agent) passes the task's success check; a deliberately
    wrong one (an object that looks like the answer) fails it. Exit code 1 if any of these
    does not hold. --json writes one row per seed (seed, answer, answer_shows, oracle,
    wrong: success, reason, skill_error, robot_time_s).
    """
    solver = _task_or_exit(task)
    try:
        seed_list = parse_seeds(seeds)
    except ValueError as error:
        fail(str(error))
    rows = []
    with trial_progress(f"{task} (oracle{'' if oracle_only else ' and wrong'})",
                        len(seed_list)) as advance:
        for seed in seed_list:
            row = {"seed": seed, "answer": solver.instance(seed).answer,
                   "answer_shows": answer_shows(solver, seed),
                   "oracle": _scripted(task, solver, seed, wrong=False)}
            if not oracle_only:
                row["wrong"] = _scripted(task, solver, seed, wrong=True)
            rows.append(row)
            advance(_passed(row))
    console.print(_table(task, rows))
    passed = sum(_passed(r) for r in rows)
    console.print(f"passed {passed}/{len(rows)} seeds: oracle success "
                  f"{sum(r['oracle']['success'] for r in rows)}/{len(rows)}"
                  + ("" if oracle_only else ", wrong answer failed "
                     f"{sum(not r['wrong']['success'] for r in rows)}/{len(rows)}")
                  + f", answer hidden {sum(not r['answer_shows'] for r in rows)}/{len(rows)}")
    if json_path is not None:
        save_json(json_path, rows)
    if passed < len(rows):
        raise typer.Exit(1)


def _scripted(task: str, solver, seed: int, wrong: bool) -> dict:
    """One episode of the scripted solution (`wrong`: a wrong answer) and its verdict."""
    episode = make_episode(task, seed)
    crashed = False
    try:
        solver.solve(episode.instance, episode.api, wrong=wrong)
        result = episode.check()
        success, reason = result.success, result.reason
    except SkillError as error:
        success, reason, crashed = False, f"skill error: {error}", True
    finally:
        robot_time = episode.api.robot_time
        episode.close()
    return {"success": success, "reason": reason, "skill_error": crashed,
            "robot_time_s": robot_time}


def _passed(row: dict) -> bool:
    return (row["oracle"]["success"] and not row["answer_shows"]
            and ("wrong" not in row or not row["wrong"]["success"]))


def _table(task: str, rows: list[dict]) -> Table:
    table = Table(title=f"{task}: scripted solutions")
    for column in ("seed", "answer", "hidden", "oracle", "wrong", "oracle reason"):
        table.add_column(column)
    for row in rows:
        oracle, wrong = row["oracle"], row.get("wrong")
        table.add_row(str(row["seed"]), row["answer"],
                      "yes" if not row["answer_shows"] else f"no: {row['answer_shows']}",
                      f"{'success' if oracle['success'] else 'FAIL'} "
                      f"({oracle['robot_time_s']:.1f} s)",
                      "-" if wrong is None else ("fails" if not wrong["success"] else
                                                 f"SUCCEEDS: {wrong['reason']}"),
                      oracle["reason"])
    return table
