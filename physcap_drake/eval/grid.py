"""The evaluation grid: which episodes to run and where each one's folder is.

    <out>/<task>/<agent>/seed_<NNN>/   one episode folder (see recording.episode_folder)

Trial k of a cell uses layout seed k, so every variant meets the same ten scenes.
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

from physcap_drake.agent.variant import variant_names
from physcap_drake.tasks.registry import TASKS

#: The paper's order of the variants (weakest first), used for rows of the tables.
PAPER_VARIANT_ORDER = ("cap", "cap_physx", "cap_physx_planner", "physcap_joint", "physcap")
#: The paper's real-arm tasks (its Table 1) and its simulated task.
TABLE_1_TASKS = ("find_blue_cube", "identify_empty_can", "pick_ripe_avocado")
SIMULATION_TASKS = ("empty_cup",)


@dc.dataclass(frozen=True, order=True)
class EpisodeSpec:
    """One episode of the grid: a task, an agent variant and a layout seed."""

    task: str
    agent: str
    seed: int

    def folder(self, out: Path) -> Path:
        return Path(out) / self.task / self.agent / f"seed_{self.seed:03d}"

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


def make_grid(tasks: list[str], agents: list[str], trials: int,
              first_seed: int = 0) -> list[EpisodeSpec]:
    if trials < 1:
        raise ValueError(f"trials must be at least 1, got {trials}")
    return [EpisodeSpec(task, agent, seed) for task in tasks for agent in agents
            for seed in range(first_seed, first_seed + trials)]
