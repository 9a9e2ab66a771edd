"""The sandbox that runs LLM-generated code: a static check, then a locked-down child process.

`run_sandboxed(code, api, limits)` is the one entry point: see `runner` for the parent's
side, `child` for the child's, `ast_check` and `policy` for the filters, `lockdown` and
`seccomp` for the process wall, and `protocol` for the messages between the two.
"""

from .ast_check import CodeRejected, check_code
from .runner import CodeOutcome, SandboxLimits, run_sandboxed

__all__ = ["CodeOutcome", "CodeRejected", "SandboxLimits", "check_code", "run_sandboxed"]
