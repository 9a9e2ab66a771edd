"""How a sandboxed code block ended."""

from __future__ import annotations

import dataclasses as dc
from typing import Literal

#: ok: the code ran to its end. rejected: the static check (or the parent's size limit on
#: what it sends) refused the code; no process ran. exception: the code raised.
#: cpu_limit, wall_limit, memory_limit (a MemoryError under the address-space limit),
#: api_call_limit, robot_time_limit, knowledge_limit: a budget ran out and the code was
#: stopped. fault: an API call raised one of the caller's fatal errors (an arm fault): the
#: code was stopped at once and never heard of it. protocol_error: the child sent something
#: that is not a message of the protocol. crashed: the child ended without reporting.
OutcomeKind = Literal["ok", "rejected", "exception", "cpu_limit", "wall_limit", "memory_limit",
                      "api_call_limit", "robot_time_limit", "knowledge_limit", "fault",
                      "protocol_error", "crashed"]


@dc.dataclass
class CodeOutcome:
    """How a sandboxed run ended.

    ok: the code ran to its end. kind: see OutcomeKind. stdout: what it printed (cut at the
    limit, see output_truncated). error: a message for the code's author (a language model):
    what went wrong and, where known, at which line. api_calls: (name, argument summary) of
    every call the code made, in order (refused ones included). isolation: what the child's
    lockdown achieved on this machine (e.g. fds_closed, user_ns, net_ns, mount_ns, ipc_ns,
    pid_ns, uid_nobody, rlimits, seccomp). duration_s: wall time of the whole run.
    """

    ok: bool
    kind: OutcomeKind
    stdout: str
    error: str | None
    api_calls: list[tuple[str, str]]
    isolation: list[str]
    duration_s: float
    output_truncated: bool = False
