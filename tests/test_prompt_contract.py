"""Every prompt of every role for every task, rendered and read as a model would: the coder's
contract equals the sandbox's policy and the robot's facts, the planner names only actions
the coder can carry out, no container the scene lacks, metres throughout, and a retry asks
for the same JSON as the schema."""

from __future__ import annotations

import dataclasses as dc
import math
import re

import cv2
import numpy as np
import pytest
from sandbox_runs import run_sandboxed

from physcap_drake.agent.code_api import EXPLORATIONS_ROBOT_S, MANOEUVRES, CodeAPI
from physcap_drake.agent.history import StepRecord
from physcap_drake.agent.llm.base import LLMRequest
from physcap_drake.agent.observation import ObjectInView, Observation
from physcap_drake.agent.prompts import AgentContext, PromptBook
from physcap_drake.agent.reference.reasoner import ReferenceReasoner
from physcap_drake.agent.sandbox import policy
from physcap_drake.agent.schemas import Candidate, JointPlannerAnswer, PlannerAnswer
from physcap_drake.agent.structured_call import ask_structured
from physcap_drake.agent.variant import load_variant, variant_names
from physcap_drake.agent.world_facts import WorldFacts, finger_length
from physcap_drake.knowledge import KnowledgeEntry
from physcap_drake.resources import stations_dir
from physcap_drake.robot_calls import RobotCalls
from physcap_drake.scenario import load_scenario
from physcap_drake.station.robot_model import robot_model
from physcap_drake.tasks.registry import TASKS

#: Words that name a container a prompt could send the robot to ("box" is left out: the
#: workspace and a box-shaped object's faces are no container).
CONTAINER_WORDS = ("tray", "basket", "bowl", "bin", "plate", "crate")

#: The episode's robot-time limit, s (docs/agent.md: 900 s unless the task states one).
EPISODE_LIMIT_S = 900.0


@pytest.fixture(scope="module")
def world() -> WorldFacts:
    return WorldFacts.from_scenario(load_scenario(stations_dir() / "find_blue_cube.yaml"))


#: Robot time used at the rendered decision, s.
USED_S = 37.4


def _budget(task: str) -> float:
    """The budget the prompts must show: the one the task's prompt states ("within N s of
    robot time"), else the episode's robot-time limit."""
    stated = re.search(r"within (\d+) s of robot time", TASKS[task].prompt)
    return float(stated.group(1)) if stated else EPISODE_LIMIT_S


def _observation(task: str) -> Observation:
    objects = TASKS[task].instance(0).objects
    image = np.full((360, 640, 3), 90, np.uint8)
    jpeg = cv2.imencode(".jpg", image)[1].tobytes()
    return Observation(tuple(
        ObjectInView(o.visible.name, o.visible.category, o.visible.color, o.visible.straw,
                     o.visible.size, 0.1, 40.0 + 60 * i, 180.0)
        for i, o in enumerate(objects)), jpeg, USED_S)


def _coder_api(physx: bool) -> CodeAPI:
    return CodeAPI(physx=physx)


def _requests(task: str, world: WorldFacts) -> list[LLMRequest]:
    """Every request of every variant for `task`: planner modes, prioritizer, coder modes
    and the coder's retry, with one measurement and one failed block in the context. Each
    request's context["functions"] holds its variant's coder functions."""
    instance = TASKS[task].instance(0)
    observation = _observation(task)
    first = observation.objects[-1].name
    knowledge = (KnowledgeEntry(first, "mass", 0.37, "kg", True),)
    failed = StepRecord(1, "explore", "", "", "t", "goto_pose([0.3, 0.0])", False,
                        "ValueError: position must have 3 numbers", "", (), (), 10.0)
    budget = min(EPISODE_LIMIT_S, getattr(TASKS[task], "time_limit_s", None) or math.inf)
    ctx = AgentContext(instance.prompt, observation, knowledge, (failed,), budget)
    requests = []
    for name in variant_names():
        variant = load_variant(name)
        book = PromptBook(world=world)
        api = _coder_api(variant.physx_api)
        candidates: list[Candidate] = []
        first_of_variant = len(requests)
        if variant.decider != "coder":
            mode = {"planner": "planner", "joint_planner": "joint_planner",
                    "enumerator": "enumerator"}[variant.decider]
            request = book.planner(ctx, mode)
            requests.append(request)
            answer = JointPlannerAnswer if mode == "joint_planner" else PlannerAnswer
            plan, _ = ask_structured(ReferenceReasoner(), request, answer)
            candidates = plan.exploration_candidates
        if candidates:
            requests.append(book.prioritizer(ctx, candidates))
            requests.append(book.coder(ctx, api.describe(), api.names(), "explore",
                                       candidates[0]))
        requests.append(book.coder(ctx, api.describe(), api.names(), "final", reason="r"))
        requests.append(book.coder(ctx, api.describe(), api.names(), "task", failed=failed))
        for i in range(first_of_variant, len(requests)):
            requests[i] = dc.replace(requests[i], context=requests[i].context | {
                "functions": api.names()})
    return requests


@pytest.fixture(scope="module", params=sorted(TASKS))
def rendered(request, world) -> tuple[str, list[LLMRequest]]:
    return request.param, _requests(request.param, world)


def _text(request: LLMRequest) -> str:
    return request.system + "\n" + request.prompt


def test_no_prompt_names_a_robot_function_the_coder_lacks(rendered):
    _, requests = rendered
    robot_calls = {n for n in dir(RobotCalls) if not n.startswith("_") and "_" in n}
    for request in requests:
        coder_names = set(request.context["functions"])
        text = _text(request)
        lacking = sorted(n for n in robot_calls - coder_names if re.search(rf"\b{n}\b", text))
        assert not lacking, f"the {request.role} prompt names {lacking}"
        actions = set(re.findall(r'action "(\w+)"', text))
        assert actions <= coder_names | set(MANOEUVRES), actions
    coders = [r for r in requests if r.role == "coder"]
    for manoeuvre in MANOEUVRES:  # the coder is told how to compose each manoeuvre
        assert all(f"- {manoeuvre}(" in r.system for r in coders)
    assert set(EXPLORATIONS_ROBOT_S) <= set(_coder_api(True).names()) | set(MANOEUVRES)
    planners = [r for r in requests if r.role == "planner"]
    for action, seconds in EXPLORATIONS_ROBOT_S.items():
        assert all(f'action "{action}"' in r.system and f"about {seconds:g} s" in r.system
                   for r in planners)


def test_no_prompt_names_a_container_the_scene_lacks(rendered):
    task, requests = rendered
    scenario = load_scenario(stations_dir() / f"{task}.yaml")
    in_scene = {o.category for o in _observation(task).objects} | {
        d.add_model.name for d in scenario.directives if d.add_model is not None}
    for request in requests:
        named = {w for w in CONTAINER_WORDS if re.search(rf"\b{w}s?\b", _text(request))}
        assert named <= in_scene, f"{task}: the {request.role} prompt names {named - in_scene}"


def test_a_request_with_a_schema_never_asks_for_plain_python(rendered):
    _, requests = rendered
    for request in requests:
        assert request.json_schema is not None
        text = _text(request).lower()
        assert "plain python" not in text and "no explanations around it" not in text
        assert "json" in request.system.lower()
    retry = [r for r in requests if "# The last code block failed" in r.prompt]
    assert retry and all("the same JSON object the schema asks for" in r.prompt for r in retry)


def test_lengths_are_in_metres(rendered):
    _, requests = rendered
    for request in requests:
        assert not re.search(r"\d\s*(cm|mm|centimet|millimet)", _text(request)), request.role
    context = requests[-1].prompt
    assert "0.100 m high (top at z 0.100 m, bottom at z 0.000 m)" in context


def test_the_sandbox_rules_in_the_coder_prompt_are_the_policy(rendered):
    _, requests = rendered
    for request in (r for r in requests if r.role == "coder"):
        system = request.system
        builtins = re.search(r"Built-in functions: (.+)\.\n", system).group(1).split(", ")
        assert builtins == ["print", *policy.SAFE_BUILTIN_NAMES]
        caught = re.search(r"catch by name: (.+?)\. ", system).group(1).split(", ")
        assert caught == [*policy.EXCEPTION_NAMES, *policy.SKILL_ERROR_NAMES]
        modules = re.search(r"`import` works only for these modules: (.+)\.\n", system)
        assert modules.group(1).split(", ") == sorted(policy.ALLOWED_MODULES)
        for name, reason in policy.FORBIDDEN_NAMES.items():
            assert re.search(rf"  [^\n]*\b{name}\b[^\n]*: {re.escape(reason)}\n", system), name
        for name, reason in policy.FORBIDDEN_ATTRIBUTES.items():
            assert re.search(rf"  [^\n]*\b{name}\b[^\n]*: {re.escape(reason)}\n", system), name
        assert policy.PRIVATE_REASON in system
        assert "each finger reaches 0.0765 m" in system and "opens to 0.100 m" in system
        assert "Statements refused: global, nonlocal, yield (generator functions), async " \
               "def / await, match." in system


def test_what_the_prompt_calls_pre_imported_and_refused_is_what_the_sandbox_does():
    ran = run_sandboxed("print(np.pi == math.pi, numpy.sqrt(4.0))", {})
    assert ran.ok and ran.stdout == "True 2.0\n"
    refused = run_sandboxed("print(type(1))", {})
    assert refused.kind == "rejected" and "type" in refused.error
    caught = run_sandboxed("try:\n    raise SkillRefused('far')\nexcept SkillError as e:\n"
                           "    print(repr(e))\n", {})
    assert caught.ok and caught.stdout == "SkillRefused('far')\n"


def test_the_robot_facts_come_from_the_fitted_gripper_and_the_camera(world):
    assert world.gripper_stroke_m == pytest.approx(0.100)
    assert world.finger_length_m == pytest.approx(0.0765)  # the finger SDF: z -0.0765 .. 0
    assert "opens to 0.100 m" in world.coder_text()
    assert "each finger reaches 0.0765 m back from the fingertip" in world.coder_text()
    assert "x 0.08 to 0.70, y -0.50 to 0.50, z 0.005 to 0.60" in world.coder_text()
    # The default camera stands behind the arm looking forward: the image's up is +x.
    assert world.image_right.startswith("-y") and world.image_up.startswith("+x")
    scenario = load_scenario(stations_dir() / "find_blue_cube.yaml")
    for directive in scenario.directives:
        if directive.add_directives is not None:
            directive.add_directives.file = directive.add_directives.file.replace(
                "piper_100mm", "piper_70mm")
    small = robot_model(scenario.directives, scenario.station.arm_model,
                        scenario.station.gripper_model)
    assert small.gripper_stroke == pytest.approx(0.070)
    assert math.isclose(finger_length(small), 0.0765, abs_tol=0.01)


def test_the_image_axes_are_told_to_every_role(rendered):
    _, requests = rendered
    for request in requests:
        assert "rightwards is world -y (to the arm's right) and upwards is world +x" \
               in request.prompt


def test_the_rule_on_what_to_explore_is_stated_once_in_the_same_words(rendered):
    _, requests = rendered
    rule = PromptBook().render("pruning")
    judges = [r for r in requests if r.role == "prioritizer"
              or r.context.get("mode") in ("planner", "joint_planner")]
    assert judges
    for request in judges:
        assert request.system.count(rule) == 1, request.context.get("mode")
        assert "list every exploration" not in request.system
        assert "rank it last" not in request.system


def test_every_prompt_shows_the_robot_time_used_and_the_tasks_budget(rendered):
    task, requests = rendered
    budget = _budget(task)
    line = (f"Robot time used: 37 s of the task's {budget:.0f} s budget "
            f"({budget - 37.4:.0f} s left).")
    assert {"planner", "coder"} <= {r.role for r in requests}
    for request in requests:
        assert line in request.prompt, (request.role, request.context.get("mode"))
        assert request.context["robot_time_s"] == USED_S
        assert request.context["budget_s"] == budget
    if task == "empty_cup":  # the only task whose prompt states its own limit
        assert "of the task's 200 s budget (163 s left)" in requests[0].prompt
