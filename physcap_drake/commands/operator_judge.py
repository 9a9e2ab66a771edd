"""`physcap run --judge operator`: the person at the rig says whether the episode succeeded.

Without a simulator nothing knows the truth of a real rig but the people watching it. When
the episode is over (the arm holding), the operator is asked on the terminal: success y/n,
then a reason in a line. Both go into the outcome (`summary.json`: success, reason).
"""

from __future__ import annotations

import sys
from collections.abc import Callable

from rich.console import Console

from physcap_drake.perception.judge import Verdict


def can_ask() -> bool:
    """Whether there is a terminal to ask on (stdin and stdout)."""
    return sys.stdin.isatty()


def ask_operator(console: Console, read: Callable[[str], str] = input,
                 before: Callable[[], None] | None = None) -> Verdict:
    """Asks until it gets y or n, then a non-empty reason. `read(prompt)` reads one line
    (EOFError, e.g. Ctrl-D, goes through: the episode then has no verdict). `before()` runs
    first (e.g. stopping a progress line)."""
    if before is not None:
        before()
    console.print("[bold]The episode is over; the arm holds. Did it do the task?[/]")
    success = None
    while success is None:
        answer = read("success? [y/n] ").strip().lower()
        success = {"y": True, "yes": True, "n": False, "no": False}.get(answer)
        if success is None:
            console.print(f"please answer y or n (got {answer!r})")
    reason = ""
    while not reason:
        reason = read("why, in a line: ").strip()
    return Verdict(success, reason)
