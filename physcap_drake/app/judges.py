"""Judges: who decides an episode's success — the simulator's ground truth, the final camera
view, or the operator at the rig. Each has `verdict(episode)` (success and reason).

Design notes: docs/design/app.md.
"""

from __future__ import annotations

from collections.abc import Callable

from physcap_drake.agent.reference.task_reading import read_task
from physcap_drake.app.episode_description import JudgeKind
from physcap_drake.perception.judge import Verdict, judge_placement, judge_uncovered
from physcap_drake.tasks.registry import get_task


class SimulatorJudge:
    """The task's success check on the simulated world's ground truth. Raises RuntimeError
    on a station without a simulated world."""

    kind = JudgeKind.SIMULATOR

    def verdict(self, episode):
        return get_task(episode.instance.task).check(episode)


class CameraJudge:
    """The outcome as the camera sees it now (perception/judge.py): the task's object alone
    in its container, or enough of the sought objects in view (the task's goal as the
    reference reasoner reads it; the object the task is about is its pinned or drawn
    answer)."""

    kind = JudgeKind.PERCEPTION

    def verdict(self, episode) -> Verdict:
        goal = read_task(episode.instance.prompt)
        view = episode.look()
        seen = list(view.objects)
        if goal.kind == "hidden":
            return judge_uncovered(seen, goal.sought, goal.count)
        return judge_placement(seen, list(view.known), episode.instance.answer,
                               goal.destination, goal.subject)


class OperatorJudge:
    """The operator's verdict, asked with `ask()` once the episode is over and the arm
    holds (None: nobody to ask; asking then raises ValueError)."""

    kind = JudgeKind.OPERATOR

    def __init__(self, ask: Callable[[], Verdict] | None = None):
        self._ask = ask

    def verdict(self, episode) -> Verdict:
        if self._ask is None:
            raise ValueError("judge 'operator' needs someone to ask (operator=...)")
        return self._ask()


def judge_of(kind: JudgeKind, operator: Callable[[], Verdict] | None = None):
    """The judge of `kind` (`operator`: how the operator is asked)."""
    if kind == JudgeKind.OPERATOR:
        return OperatorJudge(operator)
    return CameraJudge() if kind == JudgeKind.PERCEPTION else SimulatorJudge()
