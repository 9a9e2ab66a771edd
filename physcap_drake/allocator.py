"""The memory allocator a `physcap` process runs with: TCMalloc when the machine has it.

Design notes: docs/design/physcap_drake.md.
"""

from __future__ import annotations

import ctypes.util
import os
import sys
from collections.abc import Mapping

#: The environment variable that chooses: "tcmalloc" (the default) or "system".
CHOICE_VARIABLE = "PHYSCAP_ALLOCATOR"
CHOICES = ("tcmalloc", "system")
#: The shared library, as the dynamic linker finds it, and its Debian package.
LIBRARY = "libtcmalloc_minimal.so.4"
PACKAGE = "libtcmalloc-minimal4"
#: In the environment: "restarted" in the process started again (so it never starts itself
#: a third time, e.g. when the library is found but cannot be preloaded), "said" once a
#: process has said why it runs with glibc's allocator (its child processes stay quiet).
STATE_VARIABLE = "PHYSCAP_ALLOCATOR_STATE"


def choice(environ: Mapping[str, str] = os.environ) -> str:
    """The allocator asked for by PHYSCAP_ALLOCATOR (default "tcmalloc"). Raises ValueError
    naming the variable and the choices for any other value."""
    value = environ.get(CHOICE_VARIABLE, "tcmalloc").strip().lower() or "tcmalloc"
    if value not in CHOICES:
        raise ValueError(f"{CHOICE_VARIABLE} must be one of {', '.join(CHOICES)}; "
                         f"got {environ[CHOICE_VARIABLE]!r}")
    return value


def in_use(maps_path: str = "/proc/self/maps") -> str:
    """The allocator this process runs with: "tcmalloc" if the library is mapped into it,
    else "system" (also where /proc is missing)."""
    try:
        with open(maps_path) as maps:
            return "tcmalloc" if any("libtcmalloc" in line for line in maps) else "system"
    except OSError:
        return "system"


def find_library() -> str | None:
    """The TCMalloc library's name as the dynamic linker resolves it, or None."""
    return ctypes.util.find_library("tcmalloc_minimal")


def restart_environment(environ: Mapping[str, str], library: str) -> dict[str, str]:
    """`environ` with `library` first in LD_PRELOAD and the restart marked."""
    preload = [library, *(p for p in environ.get("LD_PRELOAD", "").replace(":", " ").split()
                          if p != library)]
    return {**environ, "LD_PRELOAD": " ".join(preload), STATE_VARIABLE: "restarted"}


def use_tcmalloc() -> None:
    """Starts this process again (same interpreter, same arguments) with TCMalloc preloaded,
    unless PHYSCAP_ALLOCATOR=system, it is loaded already, or this is the restarted process.
    Says on stderr (once) why it runs with glibc's allocator when TCMalloc was wanted but is
    missing. Call it first thing in a command's entry point: it does not return when it
    restarts."""
    try:
        wanted = choice()
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        sys.exit(2)
    state = os.environ.get(STATE_VARIABLE)
    if wanted == "system" or in_use() == "tcmalloc" or state == "said":
        return
    library = find_library()
    if state == "restarted" or library is None:
        why = ("could not be preloaded" if library is not None else
               f"not found (install {PACKAGE})")
        print(f"physcap: {LIBRARY} {why}; running with glibc's allocator, about a sixth "
              f"slower (set {CHOICE_VARIABLE}=system to say that is meant)", file=sys.stderr)
        os.environ[STATE_VARIABLE] = "said"
        return
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(sys.executable, sys.orig_argv, restart_environment(os.environ, library))
