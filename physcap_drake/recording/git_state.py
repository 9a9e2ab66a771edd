"""Which code made a run: the git commit of the checkout and whether it had local changes."""

from __future__ import annotations

import subprocess
from functools import cache
from pathlib import Path

_SOURCE_DIR = Path(__file__).resolve().parents[2]


@cache
def git_state() -> dict[str, str | bool | None]:
    """{"git_commit": hash or None, "git_dirty": bool or None}; None when the package is not
    in a git checkout (an installed wheel) or git is missing."""
    def git(*args: str) -> str | None:
        try:
            result = subprocess.run(["git", "-C", str(_SOURCE_DIR), *args], text=True,
                                    capture_output=True, timeout=10, check=False)
        except (OSError, subprocess.TimeoutExpired):
            return None
        return result.stdout.strip() if result.returncode == 0 else None

    commit = git("rev-parse", "HEAD")
    if commit is None:
        return {"git_commit": None, "git_dirty": None}
    status = git("status", "--porcelain", "--untracked-files=no")
    return {"git_commit": commit, "git_dirty": None if status is None else bool(status)}
