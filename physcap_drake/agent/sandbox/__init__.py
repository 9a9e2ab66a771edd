"""The sandbox that runs LLM-generated code: a static check, then a locked-down child process.

Design notes: docs/design/agent.md.
"""

from .ast_check import CodeRejected, check_code
from .budget import BlockBudget, Meters, Stop
from .limits import SandboxLimits
from .outcome import CodeOutcome, OutcomeKind
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
from .stepping import Waiting, then

__all__ = ["ApiFunction", "BlockBudget", "Call", "CodeOutcome", "CodeRejected",
           "FunctionSpec", "Meters", "Name", "Number", "OrNone", "OutcomeKind", "ParameterKind",
           "PlainValue", "Refused", "SandboxLimits", "SandboxSession", "SpareChild", "Stop",
           "Text", "Vector", "Waiting", "check_code", "then"]
