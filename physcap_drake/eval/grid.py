"""The evaluation grid: which episodes to run and where each one's folder is.

    <out>/<task>/<agent>/seed_<NNN>/   one episode folder (see recording.episode_folder)

Trial k of a cell uses layout seed k, so every variant meets the same scenes. The number of
trials follows the paper's protocol unless given: ten per cell of its real-arm tasks (its
Table 1) and fifty for its simulated task; `paper_grid()` is exactly the paper's grid (its
simulated table has three variants only).
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

from physcap_drake.agent.variant import variant_names
from physcap_drake.eval.paper_figures import PAPER_TABLE_1
from physcap_drake.tasks.registry import TASKS, folder_name

#: The paper's order of the variants (weakest first), used for rows of the tables.
PAPER_VARIANT_ORDER = ("cap", "cap_physx", "cap_physx_planner", "physcap_joint", "physcap")
#: The paper's real-arm tasks (its Table 1) and its simulated task.
TABLE_1_TASKS = ("find_blue_cube", "identify_empty_can", "pick_ripe_avocado")
SIMULATION_TASKS = ("empty_cup",)
#: Trials per cell in the paper's protocol.
PAPER_TRIALS = {**dict.fromkeys(TABLE_1_TASKS, 10), "empty_cup": 50}
#: The variants of the paper's simulated table (CaP and PhysCaP-joint were not run there).
PAPER_SIMULATION_AGENTS = ("cap_physx", "cap_physx_planner", "physcap")


@dc.dataclass(frozen=True, order=True)
class EpisodeSpec:
    """One episode of the grid: a task, an agent variant and a layout seed."""

    task: str
    agent: str
    seed: int

    def folder(self, out: Path) -> Path:
        return Path(out) / folder_name(self.task) / self.agent / f"seed_{self.seed:03d}"

    def label(self) -> str:
        return f"{self.task}/{self.agent}/seed {self.seed}"


def parse_names(text: str, known: list[str] | tuple[str, ...], what: str) -> list[str]:
    """"all" or a comma-separated list of names, each of which must be known."""
    if text.strip() == "all":
        return list(known)
    names = [name.strip() for name in text.split(",") if name.strip()]
    unknown = [name for name in names if name not in known]
    if unknown or not names:
        raise ValueError(f"unknown {what} {', '.join(map(repr, unknown)) or '(none given)'}; "
                         f"use 'all' or a comma-separated list of: {', '.join(known)}")
    return names


def all_agents() -> list[str]:
    """Every variant in agents/, the paper's in its order first."""
    names = variant_names()
    return [n for n in PAPER_VARIANT_ORDER if n in names] + sorted(
        n for n in names if n not in PAPER_VARIANT_ORDER)


def all_tasks() -> list[str]:
    return list(TASKS)


def default_trials(task: str) -> int:
    """Trials per cell of `task` in the paper's protocol (ten for a task it did not run)."""
    return PAPER_TRIALS.get(task, 10)


def paper_successes(task: str, agent: str) -> tuple[int, int] | None:
    """The paper's (successes, trials) of a cell, from its success rate and protocol."""
    paper = PAPER_TABLE_1.get((task, agent))
    if paper is None:
        return None
    trials = default_trials(task)
    return round(paper[0] * trials), trials


def make_grid(tasks: list[str], agents: list[str], trials: int | None = None,
              first_seed: int = 0) -> list[EpisodeSpec]:
    """Every task × agent × trial; `trials` None takes each task's `default_trials`."""
    if trials is not None and trials < 1:
        raise ValueError(f"trials must be at least 1, got {trials}")
    return [EpisodeSpec(task, agent, seed) for task in tasks for agent in agents
            for seed in range(first_seed, first_seed + (trials or default_trials(task)))]


def paper_grid() -> list[EpisodeSpec]:
    """The paper's grid: its Table 1 (five variants × three real-arm tasks × 10 trials) and
    its simulated table (three variants × empty_cup × 50 trials)."""
    return (make_grid(list(TABLE_1_TASKS), list(PAPER_VARIANT_ORDER))
            + make_grid(list(SIMULATION_TASKS), list(PAPER_SIMULATION_AGENTS)))
