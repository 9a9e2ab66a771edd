"""The gate before a real arm's motors are enabled: asked on the terminal unless allowed.

A command given `--yes` calls `allow_enabling()`; otherwise `confirm_enabling(config)` asks
on the terminal, naming the speed and the collision level, and refuses (EnableRefused, a
StartupError) when there is no terminal or the answer is not yes. Emulated twins
(`emulate: true`) pass without asking.
"""

from __future__ import annotations

import sys

from physcap_drake.can.link_control import StartupError

_allowed = {"yes": False}


class EnableRefused(StartupError):
    """The motors were not enabled: nobody said yes."""


def allow_enabling(yes: bool = True) -> None:
    """From now on in this process, enable without asking (`yes`), or ask again."""
    _allowed["yes"] = yes


def enabling_question(config) -> str:
    level = config.arm_collision_level
    return (f"enable the motors of the PiPER on {config.interface}:{config.channel} (speed "
            f"{config.arm_speed_percent} %, joints at most {config.joint_speed:g} rad/s, "
            f"collision level {'as set on the arm' if level is None else level})?")


def confirm_enabling(config, ask=input, is_terminal=None) -> None:
    """Returns if the motors of `config`'s arm may be enabled (see module docstring)."""
    if not config.real_arm or _allowed["yes"]:
        return
    terminal = sys.stdin.isatty() if is_terminal is None else is_terminal
    if not terminal:
        raise EnableRefused("the arm's motors are enabled only when someone says so: run "
                            "in a terminal to be asked, or pass --yes")
    question = enabling_question(config)
    answer = ask(question[0].upper() + question[1:] + " [y/N] ")
    if answer.strip().lower() not in ("y", "yes"):
        raise EnableRefused("not enabled: the motors stay off (answer y, or pass --yes)")
