"""The rules of the sandbox, in the coder's words, generated from the sandbox's own policy.

Design notes: docs/agent_prompts.md.
"""

from __future__ import annotations

import functools
from collections import defaultdict

from physcap_drake.agent.sandbox import CodeRejected, check_code, policy

#: Names the sandbox defines before the code runs (the child's namespace).
PRE_IMPORTED = ("math", "np", "numpy")
#: Constructs a model may try, each with a small example the static check is asked about:
#: the prompt lists those it refuses.
CONSTRUCT_PROBES: dict[str, str] = {
    "global": "x = 1\ndef f():\n    global x\n",
    "nonlocal": "def f():\n    x = 1\n    def g():\n        nonlocal x\n",
    "yield (generator functions)": "def f():\n    yield 1\n",
    "async def / await": "async def f():\n    pass\n",
    "match": "match 1:\n    case 1:\n        pass\n",
    "lambda": "f = lambda v: v\n",
    "try / except": "try:\n    pass\nexcept ValueError as error:\n    print(error)\n",
    "with": "with x:\n    pass\n",
    "class definitions": "class A:\n    pass\n",
}


def refused_constructs() -> list[str]:
    """The CONSTRUCT_PROBES the static check rejects."""
    refused = []
    for construct, source in CONSTRUCT_PROBES.items():
        try:
            check_code(source)
        except CodeRejected:
            refused.append(construct)
    return refused


def _grouped(reasons: dict[str, str]) -> list[str]:
    groups: dict[str, list[str]] = defaultdict(list)
    for name, reason in reasons.items():
        groups[reason].append(name)
    return [f"  {', '.join(sorted(names))}: {reason}" for reason, names in groups.items()]


@functools.cache
def sandbox_rules_text() -> str:
    """What the coder's code may use and what the checker refuses, with the reasons."""
    modules = ", ".join(sorted(policy.ALLOWED_MODULES))
    lines = [
        f"- Already imported: {', '.join(PRE_IMPORTED)} (np is numpy). `import` works only "
        f"for these modules: {modules}.",
        f"- Built-in functions: print, {', '.join(policy.SAFE_BUILTIN_NAMES)}.",
        f"- Exceptions you may raise or catch by name: "
        f"{', '.join(policy.EXCEPTION_NAMES + policy.SKILL_ERROR_NAMES)}. SkillRefused and "
        "SkillFailed are kinds of SkillError, a kind of RuntimeError. type() is refused: "
        "print(repr(error)) shows an error's class and message.",
        f"- Names starting with '_' (a lone '_' excepted): {policy.PRIVATE_REASON}; so "
        "__name__, __class__, __dict__ and the like are refused too.",
        "- Built-in names refused, and why:",
        *_grouped(policy.FORBIDDEN_NAMES),
        "- Attributes refused on any object, and why:",
        *_grouped(policy.FORBIDDEN_ATTRIBUTES),
        f"  attributes starting with {', '.join(policy.FORBIDDEN_ATTRIBUTE_PREFIXES)}: "
        "they belong to frames, code objects, tracebacks and generators",
    ]
    refused = refused_constructs()
    if refused:
        lines.append(f"- Statements refused: {', '.join(refused)}.")
    lines.append("- A refused block does not run at all: the checker names the line and the "
                 "construct, and you write the block again.")
    return "\n".join(lines)
