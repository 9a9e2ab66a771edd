"""Run by test_sandbox.py in a fresh interpreter: become an ordinary user, build one layer of
the sandbox's wall only, then try to fork and to signal the process that started this one.

    python lockdown_probe.py LAYER PARENT_PID

LAYER is "namespaces+rlimits" or "seccomp". Prints what happened on one line (the layer's
report, then "fork:<result> signal:<result>") and exits 0; exits 1 if the probe itself broke.
Its stdout must be a pipe: the rlimits forbid writing to files.

A fresh interpreter has one thread, so its forks are safe; forking pytest itself (which may
have started threads) is not. The two layers are loaded from their files alone (the
sandbox package's __init__ is not run), as the sandboxed child loads them.
"""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

ORDINARY_UID = 54321
SANDBOX = Path(__file__).resolve().parents[1] / "physcap_drake" / "agent" / "sandbox"


def _load(name: str):
    spec = importlib.util.spec_from_file_location(f"_probe_{name}", SANDBOX / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _attempts(parent: int) -> list[str]:
    report = []
    for name, attempt in (("fork", os.fork), ("signal", lambda: os.kill(parent, 0))):
        try:
            if attempt() == 0:
                os._exit(0)  # a fork that worked: the copy leaves at once
            report.append(f"{name}:allowed")
        except OSError as error:
            report.append(f"{name}:{error.strerror}")
    return report


def main(layer: str, parent: int) -> None:
    if layer not in ("namespaces+rlimits", "seccomp"):
        raise ValueError(f"unknown layer {layer!r}: use 'namespaces+rlimits' or 'seccomp'")
    # Loaded (with ctypes and pyseccomp) while still root: an ordinary user may not be able
    # to read the interpreter's library folders.
    lockdown, seccomp = _load("lockdown"), _load("seccomp")
    os.setgroups([])
    os.setresgid(ORDINARY_UID, ORDINARY_UID, ORDINARY_UID)
    os.setresuid(ORDINARY_UID, ORDINARY_UID, ORDINARY_UID)
    if layer == "namespaces+rlimits":
        entered = lockdown.enter_namespaces()
        report = [",".join(entered)]
        if "pid_ns" in entered and os.fork():  # the new pid namespace begins with a child
            _, status = os.wait()
            os._exit(os.waitstatus_to_exitcode(status))
        lockdown.set_rlimits(2, 512, sys.stdout.fileno(), kill_at_soft=True)
    else:
        report = [f"seccomp={seccomp.install()}"]
    print(" ".join(report + _attempts(parent)), flush=True)


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
