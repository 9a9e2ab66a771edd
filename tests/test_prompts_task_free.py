"""The prompts speak of no particular task: rendered for a task unlike the four shipped ones,
no role's text names those tasks' objects, properties or visual cues; rendered for two shipped
tasks at the same station, every request differs only in the task's text and its objects."""

from __future__ import annotations

import re

import cv2
import numpy as np
import pytest

from physcap_drake.agent.code_api import CodeAPI
from physcap_drake.agent.history import StepRecord
from physcap_drake.agent.observation import ObjectInView, Observation
from physcap_drake.agent.prompts import AgentContext, PromptBook, object_line
from physcap_drake.agent.schemas import Candidate
from physcap_drake.agent.world_facts import WorldFacts
from physcap_drake.knowledge import KnowledgeEntry
from physcap_drake.tasks.registry import TASKS

#: What sets each shipped task apart, as its prompt and objects word it (the prompts of a task
#: must get these from the task, never from a template): the task names, the objects' kinds
#: ("can" as a noun only: the verb is everywhere), their destinations, their visible marks and
#: the properties they hide. `test_the_word_list_is_the_shipped_tasks` ties each to a task.
TASK_WORDS = {
    "identify_empty_can": r"identify_empty_can",
    "pick_ripe_avocado": r"pick_ripe_avocado",
    "empty_cup": r"empty_cup",
    "find_blue_cube": r"find_blue_cube",
    "avocado": r"\bavocados?\b",
    "can": r"\bcans\b|\b(?:a|an|the|soda|full|empty|red|green|blue|black) can\b",
    "soda": r"\bsoda\b",
    "cup": r"\bcups?\b",
    "cube": r"\bcubes?\b",
    "tray": r"\btrays?\b",
    "wooden": r"\bwooden\b",
    "basket": r"\bbaskets?\b",
    "straw": r"\bstraws?\b",
    "lid": r"\blids?\b",
    "ripe": r"\b(?:un)?ripe\b",
    "empty can": r"\bempty (?:can|cup)s?\b",
}
#: The visual rules that tell those tasks' answers apart, which the prompts used to spell out
#: (an opened can may be empty, a dark skin is ripe, a cup standing mouth down hides what is
#: under it): what a model must judge from the image and the task, not be told per task.
TASK_CUES = {"sealed": r"\bsealed\b", "opened": r"\bopened\b", "fruit": r"\bfruits?\b",
             "skin": r"\bskins?\b", "mouth down": r"\bmouth down\b"}

#: The same station for every rendering: the PiPER's 0.100 m gripper, its workspace, and the
#: default camera behind the arm.
WORLD = WorldFacts(0.100, 0.0765, (0.08, -0.50, 0.005), (0.70, 0.50, 0.60),
                   "-y (to the arm's right)", "+x (away from the arm)")
JPEG = cv2.imencode(".jpg", np.full((360, 640, 3), 90, np.uint8))[1].tobytes()

#: A task none of the shipped ones resembles: boxes that look alike, the heaviest to a bin.
OTHER_TASK = ("Three boxes that look alike stand on the table. Put the heaviest box in the "
              "grey bin. Leave the other boxes where they are.")
OTHER_OBJECTS = (("red box", "box", "red"), ("white box", "box", "white"),
                 ("yellow box", "box", "yellow"), ("grey bin", "bin", "grey"))


def _observation(objects: list[tuple[str, str, str, bool, str]]) -> Observation:
    return Observation(tuple(
        ObjectInView(name, category, color, straw, size, 0.08, 60.0 + 120 * i, 180.0,
                     state="upright", length_m=0.06, width_m=0.05)
        for i, (name, category, color, straw, size) in enumerate(objects)), JPEG, 37.4)


def _requests(task: str, observation: Observation) -> list:
    """Every request any variant makes, with and without images: planner modes, prioritizer,
    the coder's modes and its retry, after one measurement and one failed block."""
    names = observation.names()
    knowledge = (KnowledgeEntry(names[0], "mass", 0.37, "kg", True),)
    failed = StepRecord(1, "explore", names[0], "get_mass", "t", "goto_pose([0.3, 0.0])",
                        False, "ValueError: position must have 3 numbers",
                        f"MEASURED: {names[0]} mass = 0.370 kg\n", (), (), 10.0)
    ctx = AgentContext(task, observation, knowledge, (failed,), 900.0)
    candidates = [Candidate(name=n, action=a, description=f"Measure the {n}.",
                            expected_info=f"the {n}'s {a[4:]}", estimated_robot_s=10.0)
                  for n in names[1:3] for a in ("get_mass", "get_stiffness")]
    requests = []
    for images in (True, False):
        book = PromptBook(images=images, world=WORLD)
        for physx in (False, True):
            api = CodeAPI(physx=physx)
            requests += [book.planner(ctx, m) for m in ("planner", "joint_planner",
                                                        "enumerator")]
            requests.append(book.prioritizer(ctx, candidates))
            requests.append(book.coder(ctx, api.describe(), api.names(), "explore",
                                       candidates[0]))
            requests.append(book.coder(ctx, api.describe(), api.names(), "final", reason="r"))
            requests.append(book.coder(ctx, api.describe(), api.names(), "task",
                                       failed=failed))
    return requests


def _text(request) -> str:
    return request.system + "\n" + request.prompt


def _shipped(task: str) -> tuple[str, Observation]:
    instance = TASKS[task].instance(0)
    return instance.prompt, _observation([
        (o.visible.name, o.visible.category, o.visible.color, o.visible.straw, o.visible.size)
        for o in instance.objects])


def test_the_word_list_is_the_shipped_tasks():
    """Each word comes from a shipped task's name, prompt or objects, so the scan below
    looks for what those tasks are made of."""
    shipped = " ".join(
        [name for name in TASKS]
        + [TASKS[name].instance(0).prompt for name in TASKS]
        + [f"{o.visible.name} {o.visible.category}" for name in TASKS
           for o in TASKS[name].instance(0).objects]).lower()
    for word, pattern in TASK_WORDS.items():
        assert re.search(pattern, shipped), word
    assert set(TASKS) == {"identify_empty_can", "pick_ripe_avocado", "empty_cup",
                          "find_blue_cube"}


@pytest.fixture(scope="module")
def other_requests() -> list:
    return _requests(OTHER_TASK, _observation([(*o, False, "") for o in OTHER_OBJECTS]))


def test_no_prompt_of_another_task_names_the_shipped_tasks_or_their_cues(other_requests):
    assert len(other_requests) == 28
    for request in other_requests:
        text = _text(request).lower()
        found = {word for word, pattern in (TASK_WORDS | TASK_CUES).items()
                 if re.search(pattern, text)}
        assert not found, (request.role, request.context["mode"], found)


def test_the_scan_finds_a_task_word_where_one_is_planted():
    """The scan above is no empty check: one avocado in the objects is found."""
    request = _requests(OTHER_TASK, _observation([("dark avocado", "avocado", "dark", False,
                                                   "")] + [(*o, False, "") for o in
                                                           OTHER_OBJECTS]))[0]
    assert re.search(TASK_WORDS["avocado"], _text(request))


def _canonical(text: str, task: str, observation: Observation) -> str:
    """`text` with the task's prompt, each object's line and then each object's name
    replaced by a placeholder numbered by the object's place in the view."""
    text = text.replace(task, "<task>")
    objects = observation.objects
    for i, obj in enumerate(objects):
        text = text.replace(object_line(obj), f"<object line {i}>")
    for i in sorted(range(len(objects)), key=lambda i: -len(objects[i].name)):
        text = text.replace(objects[i].name, f"<object {i}>")
    return text


@pytest.mark.parametrize("pair", [("identify_empty_can", "pick_ripe_avocado"),
                                  ("empty_cup", "identify_empty_can")])
def test_two_tasks_prompts_differ_only_in_the_tasks_text_and_objects(pair):
    rendered = []
    for task in pair:
        text, observation = _shipped(task)
        assert len(observation.objects) == 4
        requests = _requests(text, observation)
        rendered.append([(r.role, r.context["mode"], _canonical(_text(r), text, observation))
                         for r in requests])
        assert all("<task>" in c and "<object line 3>" in c for _, _, c in rendered[-1])
    assert [r[:2] for r in rendered[0]] == [r[:2] for r in rendered[1]]
    for a, b in zip(*rendered, strict=True):
        assert a == b, (a[:2], _first_difference(a[2], b[2]))


def _first_difference(a: str, b: str) -> str:
    at = next((i for i, (x, y) in enumerate(zip(a, b, strict=False)) if x != y),
              min(len(a), len(b)))
    return f"{a[max(0, at - 80):at + 80]!r} != {b[max(0, at - 80):at + 80]!r}"
