"""The sandbox that runs LLM-generated code: a static check, then a locked-down child process.

`run_sandboxed(code, api, limits)` is the blocking entry point (`runner`); `SandboxSession`
(`session`) is the same run in explicit steps, and `CallServer` (`runner`) serves its calls
for an owner that drives it event by event (both runners share it).
The parent trusts nothing the child sends: `messages` checks every message, `signatures`
every call's arguments, `budget` the block's budgets per call. `child` is the child's side,
`spare` a child started ahead of its block, `ast_check` and `policy` the filters, `rewrite`
and `views` the guard every attribute read passes in the child, `lockdown` and `seccomp` the
process wall, `isolation` the layers a child must report before any code runs, `clean_text`
what the parent does to the text a block produces, `protocol` the frames between the two.
See docs/sandbox.md.
"""

from .ast_check import CodeRejected, check_code
from .budget import BlockBudget, Meters, Stop
from .limits import SandboxLimits
from .outcome import CodeOutcome, OutcomeKind
from .runner import CallServer, Waiting, run_sandboxed, then
from .session import SandboxSession
from .signatures import (
    ApiFunction,
    Call,
    FunctionSpec,
    Name,
    Number,
    OrNone,
    ParameterKind,
    PlainValue,
    Refused,
    Text,
    Vector,
)
from .spare import SpareChild

__all__ = ["ApiFunction", "BlockBudget", "Call", "CallServer", "CodeOutcome", "CodeRejected",
           "FunctionSpec", "Meters", "Name", "Number", "OrNone", "OutcomeKind", "ParameterKind",
           "PlainValue", "Refused", "SandboxLimits", "SandboxSession", "SpareChild", "Stop",
           "Text", "Vector", "Waiting", "check_code", "run_sandboxed", "then"]
