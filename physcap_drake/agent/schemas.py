"""The answers the agents must give, as pydantic models (their JSON Schemas go to the models).

Planner: is the information sufficient, and if not, which explorations could reveal it.
Prioritizer: a score and a reason per candidate, keyed by (object, action), and the order
of the candidates' indices (`check_reordering` rejects an order or scores that miss some).
Joint planner (physcap_joint): the planner's answer with its candidates already in order.
Coder: a thought and the Python code of one code block.
"""

from __future__ import annotations

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
    action: str = Field(description="One of the robot's abilities listed above, by its name "
                                    "(e.g. get_mass).")
    description: str = Field(description="What the robot does, in one sentence.")
    expected_info: str = Field(description="What the exploration reveals.")
    estimated_robot_s: float = Field(ge=0, description="Robot time it takes, s (the "
                                                       "abilities list gives each one's).")

    def key(self) -> tuple[str, str]:
        """(object, action): what identifies a candidate."""
        return self.name, self.action


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
        _require_unique([c.key() for c in self.exploration_candidates])
        return self


class CandidateScore(_Strict):
    """The score of one candidate, keyed by its (object, action)."""

    name: str = Field(description="The candidate's object name, unchanged.")
    action: str = Field(description="The candidate's action, unchanged.")
    priority_score: float = Field(ge=0, le=10, description="0 (implausible) to 10 (explore "
                                                           "first).")
    reason: str


class PrioritizerAnswer(_Strict):
    """A score for every candidate, and the order to explore them in (candidate indices)."""

    scored_candidates: list[CandidateScore]
    order: list[int] = Field(description="The candidates' indices as numbered in the list "
                                         "received, in the order to explore them; each once.")


class PrioritizerRecord(PrioritizerAnswer):
    """What the transcript keeps of a prioritizer's turn: its answer and the candidates it
    ranked (the order's indices count in them)."""

    candidates: list[Candidate]


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


def _require_unique(keys: list[tuple[str, str]]) -> None:
    repeated = sorted({k for k in keys if keys.count(k) > 1})
    if repeated:
        raise ValueError(f"each (name, action) may be proposed once; repeated: {repeated}")


def check_reordering(original: list[Candidate], answer: PrioritizerAnswer) -> list[Candidate]:
    """The candidates in the prioritizer's order, after checking the order names each index
    of `original` once and the scores cover exactly its (name, action) pairs. Raises
    ValueError otherwise, naming what differs (the message goes back to the model)."""
    problems = []
    indices = range(len(original))
    unknown = [i for i in answer.order if i not in indices]
    missing = [i for i in indices if i not in answer.order]
    repeated = sorted({i for i in answer.order if answer.order.count(i) > 1})
    if unknown:
        problems.append(f"order names indices {unknown} that no candidate has (0 to "
                        f"{len(original) - 1})")
    if missing:
        problems.append(f"order leaves out candidates {missing}")
    if repeated:
        problems.append(f"order repeats candidates {repeated}")
    keys = [c.key() for c in original]
    scored = [(s.name, s.action) for s in answer.scored_candidates]
    if sorted(scored) != sorted(keys):
        problems.append(f"scored_candidates must score each (name, action) once: "
                        f"{sorted(keys)}; got {sorted(scored)}")
    if problems:
        raise ValueError("the prioritizer's answer does not fit the candidates: "
                         + "; ".join(problems))
    return [original[i] for i in answer.order]
