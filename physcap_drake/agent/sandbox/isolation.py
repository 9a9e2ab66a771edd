"""The layers of the wall this platform must give before any code block runs (fail closed).

`expected_layers()`: the closed fds, the rlimits and the seccomp filter always; the user,
PID and network namespaces where the kernel lets a fresh process make them (probed once per
process by running `lockdown.enter_namespaces` in a throwaway interpreter). A child that
reports less is refused (`IsolationMissing`), and the child itself runs no code without
the layers its start message requires.
`platform_problem()`: one line naming what is missing and how to install it, or None.
"""

from __future__ import annotations

import functools
import subprocess
import sys
from pathlib import Path

from . import seccomp

ALWAYS = ("fds_closed", "rlimits", "seccomp")
#: Namespaces required wherever the kernel allows them (mount and IPC are extras).
WHERE_ALLOWED = ("user_ns", "pid_ns", "net_ns")
INSTALL_HINT = ("install libseccomp2 (apt-get install libseccomp2) and pyseccomp "
                "(pip install pyseccomp), or run ./run setup")
_PROBE = (
    "import importlib.util, sys\n"
    "spec = importlib.util.spec_from_file_location('lockdown', sys.argv[1])\n"
    "module = importlib.util.module_from_spec(spec)\n"
    "spec.loader.exec_module(module)\n"
    "print(','.join(module.enter_namespaces()))\n"
)
_PROBE_TIMEOUT_S = 30.0


class IsolationMissing(RuntimeError):
    """The platform cannot give a layer of the sandbox's wall: no code block may run."""


def platform_problem() -> str | None:
    """Why code blocks cannot run here (one line), or None."""
    if not seccomp.available():
        return f"the sandbox's system-call filter cannot be loaded ({seccomp.problem()}): " \
               f"{INSTALL_HINT}"
    return None


@functools.cache
def kernel_namespaces() -> frozenset[str]:
    """The namespaces a fresh unprivileged-or-root process can make here."""
    lockdown = Path(__file__).with_name("lockdown.py")
    try:
        done = subprocess.run([sys.executable, "-I", "-B", "-c", _PROBE, str(lockdown)],
                              capture_output=True, text=True, timeout=_PROBE_TIMEOUT_S,
                              check=False)
    except (OSError, subprocess.TimeoutExpired):
        return frozenset()
    if done.returncode != 0:
        return frozenset()
    return frozenset(name for name in done.stdout.strip().split(",") if name)


def expected_layers() -> frozenset[str]:
    """Every layer a child must report on this platform."""
    return frozenset(ALWAYS) | (kernel_namespaces() & frozenset(WHERE_ALLOWED))


def check_reported(reported: tuple[str, ...] | list[str]) -> None:
    """IsolationMissing unless `reported` has every expected layer."""
    missing = sorted(expected_layers() - set(reported))
    if not missing:
        return
    hint = f"; {INSTALL_HINT}" if "seccomp" in missing else ""
    raise IsolationMissing(f"the sandboxed process lacks {', '.join(missing)} (it has "
                           f"{', '.join(reported) or 'nothing'}), so no code block runs{hint}")
