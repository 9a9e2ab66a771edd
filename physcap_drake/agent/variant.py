"""Agent variants: which agents take part and how the next exploration is chosen, one YAML
file per variant in `agents/` (cap, cap_physx, cap_physx_planner, physcap_joint, physcap)."""

# No `from __future__ import annotations`: yaml_load_typed reads the field types at run time.
import dataclasses as dc
from pathlib import Path

from pydrake.common.yaml import yaml_load_typed

from physcap_drake.agent.sandbox import SandboxLimits
from physcap_drake.config_checks import ConfigChecker
from physcap_drake.resources import agents_dir
from physcap_drake.scenario_errors import ScenarioError, file_label, locate_yaml_error

#: Who decides what happens next:
#: coder: no planner; the coder writes each block and says when the task is complete.
#: enumerator: one call lists every candidate; all are explored, then the task is finished.
#: planner: the planner decides each step whether to explore more or finish.
#: joint_planner: like planner, with the prioritizer's ordering merged into the same call.
DECIDERS = ("coder", "enumerator", "planner", "joint_planner")
#: How the candidates are ordered: as the decider gave them, by their left-to-right position
#: in the image, at random (seeded), or by the prioritizer agent.
ORDERS = ("as_given", "spatial", "random", "prioritizer")


@dc.dataclass
class AgentVariant:
    """One agent variant (see the module docstring and agents/*.yaml)."""

    # The variant's name, as `physcap run --agent NAME` takes it.
    name: str = ""
    # One line for listings.
    description: str = ""
    # Whether generated code may call get_mass / get_stiffness.
    physx_api: bool = True
    # See DECIDERS.
    decider: str = "planner"
    # See ORDERS.
    order: str = "prioritizer"
    # The most code blocks one episode may run.
    max_steps: int = 10
    # How often a malformed answer is sent back for repair before the episode fails.
    repair_attempts: int = 2
    # Per code block: how often it may close the gripper, run a physical probe, and call
    # get_object_pose (one more ends the block, naming the limit).
    max_gripper_cycles: int = SandboxLimits.max_gripper_cycles
    max_probe_calls: int = SandboxLimits.max_probe_calls
    max_pose_calls: int = SandboxLimits.max_pose_calls

    def block_limits(self, limits: SandboxLimits) -> SandboxLimits:
        """`limits` with this variant's per-block call budgets."""
        return dc.replace(limits, max_gripper_cycles=self.max_gripper_cycles,
                          max_probe_calls=self.max_probe_calls,
                          max_pose_calls=self.max_pose_calls)

    def check(self, at: ConfigChecker) -> None:
        if not self.name:
            at.fail("name", "a non-empty variant name", "got an empty name")
        at.choice("decider", self.decider, DECIDERS)
        at.choice("order", self.order, ORDERS)
        at.number("max_steps", self.max_steps, minimum=1, maximum=100)
        at.number("repair_attempts", self.repair_attempts, minimum=0, maximum=10)
        for key in ("max_gripper_cycles", "max_probe_calls", "max_pose_calls"):
            at.number(key, getattr(self, key), minimum=1, maximum=1000)
        if self.decider == "coder" and self.order != "as_given":
            at.fail("order", "'as_given' (the coder explores without a candidate list)",
                    f"got {self.order!r}")
        if self.order == "prioritizer" and self.decider != "planner":
            at.fail("order", "'prioritizer' only with decider 'planner'",
                    f"got decider {self.decider!r}")
        if self.decider != "coder" and not self.physx_api:
            at.fail("physx_api", "true (exploring variants measure with the PhysX modules)",
                    "got false")


def variant_names() -> list[str]:
    return sorted(path.stem for path in agents_dir().glob("*.yaml"))


def load_variant(name_or_path: str | Path) -> AgentVariant:
    """Loads agents/<name>.yaml (or a given YAML file) and checks it. Raises ScenarioError
    naming the file and key on a bad value, and ValueError listing the variants on an
    unknown name."""
    path = Path(name_or_path)
    if not path.suffix:
        path = agents_dir() / f"{name_or_path}.yaml"
        if not path.is_file():
            raise ValueError(f"unknown agent variant {str(name_or_path)!r}; choose one of "
                             f"{', '.join(variant_names())}")
    label = file_label(path)
    try:
        variant = yaml_load_typed(schema=AgentVariant, filename=str(path))
    except (RuntimeError, ValueError, TypeError, KeyError, AssertionError) as error:
        raise locate_yaml_error(error, label) from error
    except Exception as error:  # noqa: BLE001  yaml syntax errors carry line and column
        raise ScenarioError(filename=label, key_path="", expected="valid YAML",
                            problem=str(error)) from error
    variant.check(ConfigChecker(label))
    return variant
