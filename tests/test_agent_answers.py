"""The agents' answer schemas, the prioritizer's order of candidate indices and the repair path."""

from __future__ import annotations

import json

import pytest

from physcap_drake.agent.llm.base import LLMRequest, LLMResponse
from physcap_drake.agent.schemas import (
    Candidate,
    CoderAnswer,
    PlannerAnswer,
    PrioritizerAnswer,
    check_reordering,
)
from physcap_drake.agent.structured_call import AgentAnswerError, ask_structured, parse_answer


def _candidate(name: str, action: str = "get_mass") -> Candidate:
    return Candidate(name=name, action=action, description=f"Weigh the {name}.",
                     expected_info="its mass", estimated_robot_s=10.0)


CANDIDATES = [_candidate("red can"), _candidate("blue can"), _candidate("green can")]
KEYS = [(c.name, c.action) for c in CANDIDATES]


def _answer(order: list[int], scored: list[tuple[str, str]] | None = None) -> PrioritizerAnswer:
    keys = scored if scored is not None else KEYS
    return PrioritizerAnswer(
        scored_candidates=[{"name": n, "action": a, "priority_score": 5, "reason": "r"}
                           for n, a in keys],
        order=order)


def test_an_order_of_indices_orders_the_candidates():
    assert check_reordering(CANDIDATES, _answer([2, 0, 1])) == [CANDIDATES[2], CANDIDATES[0],
                                                                 CANDIDATES[1]]


@pytest.mark.parametrize(("order", "message"), [
    ([0, 1], "order leaves out candidates [2]"),
    ([0, 1, 2, 3], "indices [3] that no candidate has"),
    ([0, 0, 1, 2], "order repeats candidates [0]"),
    ([-1, 0, 1, 2], "indices [-1]"),
])
def test_the_order_must_name_each_candidate_once(order, message):
    with pytest.raises(ValueError, match="does not fit the candidates") as error:
        check_reordering(CANDIDATES, _answer(order))
    assert message in str(error.value)


def test_scores_are_keyed_by_object_and_action():
    with pytest.raises(ValueError, match="score each \\(name, action\\) once"):
        check_reordering(CANDIDATES, _answer([0, 1, 2], KEYS[:2]))
    wrong_action = [*KEYS[:2], ("green can", "get_stiffness")]
    with pytest.raises(ValueError, match="score each"):
        check_reordering(CANDIDATES, _answer([0, 1, 2], wrong_action))
    # two actions on one object are two candidates, told apart by the action
    two = [_candidate("red can"), _candidate("red can", "get_stiffness")]
    answer = PrioritizerAnswer(scored_candidates=[
        {"name": "red can", "action": "get_stiffness", "priority_score": 9, "reason": "r"},
        {"name": "red can", "action": "get_mass", "priority_score": 1, "reason": "r"}],
        order=[1, 0])
    assert check_reordering(two, answer) == [two[1], two[0]]


def test_an_insufficient_plan_must_propose_explorations():
    with pytest.raises(ValueError, match="propose at least one exploration"):
        PlannerAnswer(sufficient=False, reason="unknown masses")
    with pytest.raises(ValueError, match="proposed once"):
        PlannerAnswer(sufficient=False, reason="r",
                      exploration_candidates=[CANDIDATES[0], CANDIDATES[0]])
    PlannerAnswer(sufficient=False, reason="r", exploration_candidates=[
        CANDIDATES[0], _candidate("red can", "get_stiffness")])


CODE = {"thought": "weigh it", "code": "home_pose()"}


@pytest.mark.parametrize("text", [
    "Sure!\n```json\n" + json.dumps(CODE) + "\n```",
    # prose with brackets (and a JSON list, and a smaller object) before the answer
    "Here is my answer [as asked] with [1, 2] and {\"note\": 1}:\n" + json.dumps(CODE)
    + "\nHope this helps {really}.",
    "[" + json.dumps(CODE) + "]",
])
def test_the_answer_is_found_where_it_is(text):
    assert parse_answer(text, CoderAnswer) == CoderAnswer(**CODE)


def test_parse_problems_say_what_is_wrong():
    with pytest.raises(ValueError, match="no JSON object"):
        parse_answer("I cannot help with that [sorry].", CoderAnswer)
    with pytest.raises(ValueError, match="character 4 is not valid JSON .*cut off"):
        parse_answer('OK: {"thought": "t", "code": "home_po', CoderAnswer)
    # of several objects none of which fits, the largest one's problem is reported
    with pytest.raises(ValueError, match="code") as error:
        parse_answer('{"a": 1} then {"thought": "a longer object"}', CoderAnswer)
    assert "Field required" in str(error.value)


class ScriptedModel:
    """Answers with the given texts in turn and keeps the requests it received."""

    name, model = "scripted", "scripted-1"

    def __init__(self, *texts: str):
        self.texts, self.requests = list(texts), []

    def complete(self, request: LLMRequest) -> LLMResponse:
        self.requests.append(request)
        return LLMResponse(self.texts.pop(0), self.model)


REQUEST = LLMRequest(role="coder", system="write code", prompt="the task",
                     json_schema=CoderAnswer.model_json_schema())
VALID = json.dumps({"thought": "t", "code": "home_pose()"})


def test_a_malformed_answer_is_repaired_with_the_problem_stated():
    model = ScriptedModel("not json at all", '{"thought": "t"}', VALID)
    answer, _ = ask_structured(model, REQUEST, CoderAnswer, repairs=2)
    assert answer.code == "home_pose()"
    assert len(model.requests) == 3
    assert "no JSON object" in model.requests[1].prompt
    assert "code: Field required" in model.requests[2].prompt
    assert model.requests[2].context["repair"] == "code: Field required"


def test_after_two_repairs_the_agent_fails_with_the_reason():
    model = ScriptedModel("nope", "still nope", "{broken", VALID)
    with pytest.raises(AgentAnswerError, match=r"the coder \(scripted model scripted-1\) gave "
                                               "no valid answer in 3 attempt") as error:
        ask_structured(model, REQUEST, CoderAnswer, repairs=2)
    assert "not valid JSON" in error.value.problem
    assert len(model.texts) == 1  # the fourth answer was never asked for


def test_a_failed_check_counts_as_malformed():
    bad = _answer([0]).model_dump_json()
    good = _answer([0, 1, 2]).model_dump_json()
    model = ScriptedModel(bad, good)
    _, ordered = ask_structured(model, REQUEST, PrioritizerAnswer, repairs=2,
                                check=lambda a: check_reordering(CANDIDATES, a))
    assert [c.name for c in ordered] == ["red can", "blue can", "green can"]
    assert "leaves out candidates [1, 2]" in model.requests[1].prompt
