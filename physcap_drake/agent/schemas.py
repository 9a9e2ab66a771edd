"""The answers the agents must give, as pydantic models (their JSON Schemas go to the models).

Planner: is the information sufficient, and if not, which explorations could reveal it.
Prioritizer: a score and a reason per candidate, and the candidates reordered (only
reordered: `check_reordering` rejects added, dropped, renamed or edited candidates).
Joint planner (physcap_joint): the planner's answer with its candidates already in order.
Coder: a thought and the Python code of one code block.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class CentralObject(_Strict):
    """An object the task depends on, and what must be known about it."""

    name: str = Field(description="How the perception module names the object.")
    description: str = Field(description="What it looks like, where it is.")
    required_properties: list[str] = Field(
        description="What must be known about it, e.g. mass, stiffness, what is under it.")


class Candidate(_Strict):
    """One exploration: one action on one object that may reveal missing information."""

    name: str = Field(description="The object to explore, as the perception module names it.")
    action: str = Field(description="The robot function or manoeuvre, e.g. get_mass, "
                                    "get_stiffness, lift_and_look.")
    description: str = Field(description="What the robot does, in one sentence.")
    parameters: dict[str, str] = Field(default_factory=dict,
                                       description="Parameter names and their types.")
    expected_info: str = Field(description="What the exploration reveals.")
    estimated_cost: Literal["low", "medium", "high"]


class PlannerAnswer(_Strict):
    """The planner's verdict and, when information is missing, the exploration candidates."""

    sufficient: bool = Field(description="True if the task can be finished with what is "
                                         "known now.")
    reason: str
    central_objects: list[CentralObject] = Field(default_factory=list)
    exploration_candidates: list[Candidate] = Field(default_factory=list)

    @model_validator(mode="after")
    def _candidates_when_needed(self) -> PlannerAnswer:
        if not self.sufficient and not self.exploration_candidates:
            raise ValueError("'sufficient' is false but 'exploration_candidates' is empty: "
                             "propose at least one exploration")
        _require_unique([c.name for c in self.exploration_candidates])
        return self


class CandidateScore(_Strict):
    name: str = Field(description="The candidate's name, unchanged.")
    priority_score: float = Field(ge=0, le=10, description="0 (implausible) to 10 (explore "
                                                           "first).")
    reason: str


class PrioritizerAnswer(_Strict):
    """Scores for every candidate, and all candidates in the order to explore them."""

    scored_candidates: list[CandidateScore]
    prioritized_candidates: list[Candidate]


class JointPlannerAnswer(PlannerAnswer):
    """The merged planner-prioritizer's answer: candidates already in exploration order,
    with a reason for the order."""

    ordering_reason: str = ""


class CoderAnswer(_Strict):
    """One code block: the reasoning behind it and the Python to run."""

    thought: str = Field(description="Why this code, in one or two sentences.")
    code: str = Field(description="Python that calls the robot functions; no markdown.")
    task_complete: bool = Field(default=False, description="True if the task is done once "
                                                           "this block has run.")


def _require_unique(names: list[str]) -> None:
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ValueError(f"candidate names must be unique; repeated: {repeated}")


def check_reordering(original: list[Candidate], answer: PrioritizerAnswer) -> list[Candidate]:
    """The prioritizer's order, after checking it only reorders `original`: the same
    candidates, each once, none edited, and a score for each. Raises ValueError otherwise,
    naming what differs (the message goes back to the model in a repair attempt)."""
    by_name = {c.name: c for c in original}
    ordered = answer.prioritized_candidates
    names = [c.name for c in ordered]
    problems = []
    added = [n for n in names if n not in by_name]
    dropped = [n for n in by_name if n not in names]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if added:
        problems.append(f"added candidates {added}")
    if dropped:
        problems.append(f"dropped candidates {dropped}")
    if repeated:
        problems.append(f"repeated candidates {repeated}")
    edited = [c.name for c in ordered if c.name in by_name and c != by_name[c.name]]
    if edited:
        problems.append(f"edited the fields of {edited} (only the order may change)")
    scored = {s.name for s in answer.scored_candidates}
    if scored != set(by_name):
        problems.append(f"scores must cover exactly the candidates {sorted(by_name)}; got "
                        f"{sorted(scored)}")
    if problems:
        raise ValueError("the prioritizer may only reorder the candidates: "
                         + "; ".join(problems))
    return list(ordered)
