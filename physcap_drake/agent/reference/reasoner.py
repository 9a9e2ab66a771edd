"""ReferenceReasoner: the offline default "model", a rule-based stand-in for an LLM.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import json
import re
import zlib
from string import Template

import numpy as np

from physcap_drake.agent.code_api import EXPLORATIONS_ROBOT_S
from physcap_drake.agent.llm.base import LLMRequest, LLMResponse
from physcap_drake.agent.reference.naming import ObjectNotInView, current_name
from physcap_drake.agent.reference.priors import IMPLAUSIBLE, plausibility
from physcap_drake.agent.reference.task_reading import Goal, read_task
from physcap_drake.resources import agents_dir

MODEL = "reference-reasoner-1"
#: How a lifting block announces itself in its printed output.
LIFT_PRINTED = re.compile(r"ACTION: lift the (.+?) and look under it")


class ReferenceReasoner:
    """Answers agent requests by rule (see the design notes)."""

    name = "reference"

    def __init__(self, seed: int = 0):
        self.model = MODEL
        self._seed = seed

    def complete(self, request: LLMRequest) -> LLMResponse:
        context = request.context
        goal = read_task(context["task"],
                         tuple(o["category"] for o in context["objects_in_view"]))
        handler = {"planner": self._plan, "joint_planner": self._plan,
                   "enumerator": self._plan, "prioritizer": self._prioritize,
                   "explore": self._explore_code, "final": self._final_code,
                   "task": self._task_code}.get(context.get("mode", ""))
        if handler is None:
            raise ValueError(f"the reference reasoner cannot answer a {request.role!r} "
                             f"request in mode {context.get('mode')!r}")
        answer = handler(context, goal)
        text = json.dumps(answer, indent=1)
        return LLMResponse(text, MODEL, input_tokens=len(request.prompt.split()),
                           output_tokens=len(text.split()))

    # --- what is known -------------------------------------------------------------------

    @staticmethod
    def _subjects(context: dict, goal: Goal) -> list[dict]:
        return [o for o in context["objects_in_view"] if o["category"] == goal.subject]

    @staticmethod
    def _measured(context: dict, goal: Goal) -> dict[str, float]:
        """Latest successful measurement of the goal's property per object, under the
        object's name in the latest view (under the name it was measured by when it cannot
        be found there: the coder then says why it cannot reach it)."""
        values = {}
        for entry in context["knowledge"]:
            if entry["prop"] == goal.kind and entry["ok"]:
                try:
                    name = current_name(entry["subject"], context, goal.subject)
                except ObjectNotInView:
                    name = entry["subject"]
                values[name] = float(entry["value"])
        return values

    @staticmethod
    def _explored(context: dict, goal: Goal) -> list[str]:
        """Objects already lifted (hidden-object tasks), oldest first."""
        return [step["target"] for step in context["history"]
                if step["action"] == goal.action and step["target"]]

    def _plausible(self, context: dict, goal: Goal) -> list[str]:
        """The subjects whose look leaves them plausible (all of them if none is)."""
        in_view, subjects = context["objects_in_view"], self._subjects(context, goal)
        likely = [o["name"] for o in subjects
                  if plausibility(o, goal, in_view)[0] >= IMPLAUSIBLE]
        return likely or [o["name"] for o in subjects]

    def _answer(self, context: dict, goal: Goal) -> tuple[str | None, str]:
        """The object the evidence singles out (None if it does not yet) and why."""
        if goal.extreme:
            return self._compared(context, goal)
        measured = self._measured(context, goal)
        for name, value in measured.items():
            if goal.satisfied_by(value):
                return name, (f"the {name}'s {goal.kind} is {_quantity(value, goal)}, which "
                              "meets the task")
        subjects = [o["name"] for o in self._subjects(context, goal)]
        unmeasured = [name for name in subjects if name not in measured]
        if goal.exactly_one and len(unmeasured) == 1 and measured:
            return unmeasured[0], (f"every other {goal.subject} was measured and none has "
                                   f"the property, so it must be the {unmeasured[0]}")
        if subjects and not unmeasured:
            pick = (max if goal.seeks_high else min)(measured, key=measured.get)
            return pick, f"all were measured; the {pick} comes closest to the property"
        if not subjects:
            return None, f"no {goal.subject} is in view"
        if not measured:
            return None, (f"the camera cannot show a {goal.subject}'s {goal.kind}, and none has "
                          "been measured yet")
        found = ", ".join(f"the {name}'s is {_quantity(value, goal)}"
                          for name, value in measured.items())
        return None, (f"{goal.kind} measured so far: {found}, none meeting the task; still "
                      f"to measure: the {', the '.join(unmeasured)}")

    def _compared(self, context: dict, goal: Goal) -> tuple[str | None, str]:
        """A comparison is decided once every plausible subject is measured: the one with
        the highest (lowest) value of all measured."""
        if not self._subjects(context, goal):
            return None, f"no {goal.subject} is in view"
        measured = self._measured(context, goal)
        if not measured:
            return None, (f"the camera cannot show a {goal.subject}'s {goal.kind}, and none has "
                          "been measured yet")
        found = ", ".join(f"the {name}'s is {_quantity(value, goal)}"
                          for name, value in measured.items())
        todo = [name for name in self._plausible(context, goal) if name not in measured]
        if todo:
            return None, (f"{goal.kind} measured so far: {found}; the {goal.wording} cannot be "
                          f"told before the {', the '.join(todo)} are measured too")
        pick = (max if goal.extreme == "max" else min)(measured, key=measured.get)
        highest = "highest" if goal.extreme == "max" else "lowest"
        return pick, (f"every {goal.subject} that could be the {goal.wording} was measured "
                      f"({found}): the {pick}'s {goal.kind} is the {highest}")

    # --- planner -------------------------------------------------------------------------

    def _plan(self, context: dict, goal: Goal) -> dict:
        mode = context["mode"]
        in_view = context["objects_in_view"]
        subjects = self._subjects(context, goal)
        if goal.kind == "hidden":
            seen = sum(o["category"] == goal.sought for o in in_view)
            done_by = self._explored(context, goal)
            sufficient = seen >= goal.count
            reason = (f"{seen} of the {goal.count} {goal.sought}s are in sight" + (
                ": the task is done" if sufficient else f"; one may be under a {goal.subject}"))
            open_subjects = [o for o in subjects if o["name"] not in done_by]
            if not sufficient and not open_subjects:
                sufficient, reason = True, reason + "; nothing is left to lift"
        else:
            answer, reason = self._answer(context, goal)
            sufficient = (not self._unmeasured(context, goal) if mode == "enumerator"
                          else answer is not None)
            worth = (self._plausible(context, goal) if goal.extreme and mode != "enumerator"
                     else [o["name"] for o in subjects])
            open_subjects = [o for o in subjects if o["name"] in worth
                             and o["name"] not in self._measured(context, goal)]
        candidates = [] if sufficient else [self._candidate(o, goal) for o in open_subjects]
        if mode == "joint_planner":
            candidates.sort(key=lambda c: (-plausibility(_find(in_view, c["name"]), goal,
                                                         in_view)[0], self._tie_rank(c["name"])))
        answer = {"sufficient": sufficient, "reason": reason,
                  "central_objects": [
                      {"name": o["name"], "description": _look(o),
                       "required_properties": [_property_name(goal)]} for o in subjects],
                  "exploration_candidates": candidates}
        if mode == "joint_planner":
            answer["ordering_reason"] = "candidates that look likely come first"
        return answer

    def _unmeasured(self, context: dict, goal: Goal) -> list[str]:
        measured = self._measured(context, goal)
        return [o["name"] for o in self._subjects(context, goal) if o["name"] not in measured]

    @staticmethod
    def _candidate(obj: dict, goal: Goal) -> dict:
        verbs = {"get_mass": f"Weigh the {obj['name']}.",
                 "get_stiffness": f"Squeeze the {obj['name']} to measure its stiffness.",
                 "lift_and_look": f"Lift the {obj['name']} and set it down on the "
                                  f"{goal.destination} to see what it covers."}
        return {"name": obj["name"], "action": goal.action, "description": verbs[goal.action],
                "expected_info": f"the {obj['name']}'s {_property_name(goal)}",
                "estimated_robot_s": EXPLORATIONS_ROBOT_S[goal.action]}

    # --- prioritizer ---------------------------------------------------------------------

    def _prioritize(self, context: dict, goal: Goal) -> dict:
        in_view, measured = context["objects_in_view"], self._measured(context, goal)
        scored = []
        for candidate in context["candidates"]:
            obj = _find(in_view, candidate["name"])
            if candidate["name"] in measured:
                score, reason = 0.0, "already measured"
            elif obj is None:
                score, reason = 5.0, "not recognized in the image"
            else:
                value, reason = plausibility(obj, goal, in_view)
                score = round(10.0 * value, 1)
            scored.append({"name": candidate["name"], "action": candidate["action"],
                           "priority_score": score, "reason": reason})
        order = sorted(range(len(scored)), key=lambda i: (-scored[i]["priority_score"],
                                                          self._tie_rank(scored[i]["name"])))
        return {"scored_candidates": scored, "order": order}

    def _tie_rank(self, name: str) -> float:
        """A random rank in [0, 1) drawn per (seed, object name): orders equally likely
        candidates the same way all episode, independently of their place in the image."""
        return float(np.random.default_rng((self._seed, 31, zlib.crc32(name.encode()))).random())

    # --- coder ---------------------------------------------------------------------------

    def _explore_code(self, context: dict, goal: Goal) -> dict:
        candidate = context["candidate"]
        action = candidate["action"]
        name = current_name(candidate["name"], context, goal.subject)
        thought = f"{candidate['description']} This reveals {candidate['expected_info']}."
        if name != candidate["name"]:
            thought += f" The {candidate['name']} is now seen as the {name}."
        if action == "lift_and_look":
            code = _code("lift_and_look", name=name, thought=thought,
                         destination=goal.destination,
                         action_text=f"lift the {name} and look under it")
        elif action in ("get_mass", "get_weight", "get_stiffness"):
            code = _code("get_stiffness" if action == "get_stiffness" else "get_mass",
                         name=name, thought=thought)
        else:
            raise ValueError(f"the reference coder knows no action {action!r}")
        return {"thought": thought, "code": code, "task_complete": False}

    def _final_code(self, context: dict, goal: Goal) -> dict:
        if goal.kind == "hidden":
            thought = context.get("reason") or "the task is done"
            return {"thought": thought, "code": _code("report", thought=thought),
                    "task_complete": True}
        answer, reason = self._answer(context, goal)
        if answer is None:
            raise ValueError("asked for the final code, but the evidence singles out no object")
        return self._move_answer(answer, reason, goal, context)

    def _move_answer(self, name: str, reason: str, goal: Goal, context: dict) -> dict:
        """The block putting `name` on the destination; `name` must be in the latest view
        (`current_name` says why it cannot be found otherwise)."""
        name = current_name(name, context, goal.subject)
        thought = f"{reason}; put it on the {goal.destination}"
        return {"thought": thought, "code": _code(
            "place_in", name=name, thought=thought, destination=goal.destination,
            action_text=f"put the {name} on the {goal.destination}"),
            "task_complete": True}

    def _task_code(self, context: dict, goal: Goal) -> dict:
        """The vision-only coder: no measurements, so it guesses among the objects that look
        plausible, or lifts objects left to right until the sought ones are in sight."""
        in_view = context["objects_in_view"]
        if goal.kind == "hidden":
            if sum(o["category"] == goal.sought for o in in_view) >= goal.count:
                return self._final_code(context | {"reason": f"all {goal.count} "
                                                   f"{goal.sought}s are in sight"}, goal)
            lifted = self._explored_by_code(context)
            remaining = [o for o in self._subjects(context, goal) if o["name"] not in lifted]
            if not remaining:
                return {"thought": "nothing is left to lift", "code": _code(
                    "report", thought="nothing is left to lift"), "task_complete": True}
            target = remaining[0]["name"]
            thought = f"a {goal.sought} may be under the {target}; lift it"
            return {"thought": thought, "task_complete": False, "code": _code(
                "lift_and_look", name=target, thought=thought,
                destination=goal.destination,
                action_text=f"lift the {target} and look under it")}
        pool = self._plausible(context, goal)
        if not pool:
            raise ValueError(f"no {goal.subject} is in view")
        rng = np.random.default_rng((self._seed, zlib.crc32(context["task"].encode())))
        guess = pool[int(rng.integers(len(pool)))]
        reason = (f"the camera cannot tell which {goal.subject} it is; the {guess} looks as "
                  "likely as any")
        return self._move_answer(guess, reason, goal, context)

    @staticmethod
    def _explored_by_code(context: dict) -> list[str]:
        """What earlier vision-only blocks lifted, read from what they printed."""
        return [m.group(1) for step in context["history"]
                for m in [LIFT_PRINTED.search(step["stdout"])] if m]


def _find(in_view: list[dict], name: str) -> dict | None:
    return next((o for o in in_view if o["name"] == name), None)


def _look(obj: dict) -> str:
    parts = [obj["size"], obj["color"], obj["category"]]
    text = " ".join(p for p in parts if p)
    return text + (" with a straw" if obj["straw"] else "")


def _quantity(value: float, goal: Goal) -> str:
    return f"{value:.3f} kg" if goal.kind == "mass" else f"level {value:g}"


def _property_name(goal: Goal) -> str:
    return {"mass": "mass", "stiffness": "stiffness",
            "hidden": f"whether a {goal.sought} is under it"}[goal.kind]


def _code(template: str, **values) -> str:
    path = agents_dir() / "code" / f"{template}.py"
    return Template(path.read_text()).substitute({k: str(v) for k, v in values.items()})
