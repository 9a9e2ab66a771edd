"""The limits of one sandboxed code block, enforced by the parent whatever the child does."""

from __future__ import annotations

import dataclasses as dc

#: The most output a block may be allowed to keep (characters).
MAX_OUTPUT_CHARS_LIMIT = 100_000


@dc.dataclass(frozen=True)
class SandboxLimits:
    """Limits of one code block (seconds, megabytes, characters, calls).

    cpu_s: CPU time of the code (an rlimit the child sets on itself).
    compute_wall_s: wall time the code may spend between and around API calls (time spent
        serving a call is not counted).
    total_wall_s: the block's own wall time: wall time from the moment the code starts
        (after the child's start-up, which has `startup_s` of its own), less the time the
        parent spends answering its API calls (the robot moving, however slowly the host
        simulates it); the code computing or waiting for anything else counts. A block that
        loops forever is stopped whatever else it does; checked while the code runs, before
        each call and after each call returns.
    memory_mb: address space of the child (an rlimit).
    max_output_chars: printed text kept; beyond it the output is cut (not an error).
    max_api_calls: calls the code may make; one more ends the block.
    robot_time_s: robot execution time one block may spend (s), checked before each motion:
        a motion that would start past it ends the block. The caller may lower it further
        (e.g. to what is left of the episode's budget).
    knowledge_chars: how much the block may add to the scene knowledge (characters of the
        entries' text), checked after each call.
    max_gripper_cycles: times the code may close the gripper (each close, and the opening
        that follows, wears the fingers and whatever they hold).
    max_probe_calls: physical probes (get_mass, get_stiffness) the code may run.
    max_pose_calls: get_object_pose calls the code may make (with a model as the pointer,
        each new look is a paid model call).
    startup_s: wall time the child may take to start and lock itself down, counted from the
        moment the session starts it, or takes over a child started ahead (a spare's idle
        wait before that is not counted).
    """

    cpu_s: float = 20.0
    compute_wall_s: float = 30.0
    total_wall_s: float = 600.0
    memory_mb: int = 1024
    max_output_chars: int = 20_000
    max_api_calls: int = 200
    robot_time_s: float = 300.0
    knowledge_chars: int = 4000
    max_gripper_cycles: int = 20
    max_probe_calls: int = 16
    max_pose_calls: int = 60
    startup_s: float = 30.0

    def __post_init__(self) -> None:
        for field in dc.fields(self):
            if not getattr(self, field.name) > 0:
                raise ValueError(f"SandboxLimits.{field.name} must be positive, got "
                                 f"{getattr(self, field.name)!r}")
        if self.max_output_chars > MAX_OUTPUT_CHARS_LIMIT:
            raise ValueError(f"SandboxLimits.max_output_chars may be at most "
                             f"{MAX_OUTPUT_CHARS_LIMIT}, got {self.max_output_chars}")
