"""The syscall filter of the code's process: an allow-list built with libseccomp.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import errno
import os

HIDE_ENV = "PHYSCAP_SANDBOX_HIDE_LIBSECCOMP"
_load_error = ""
try:
    if os.environ.get(HIDE_ENV) == "1":
        raise ImportError(f"hidden by {HIDE_ENV}=1")
    import pyseccomp
except (ImportError, OSError, RuntimeError) as error:  # not installed, or no libseccomp.so.2
    pyseccomp = None
    _load_error = f"{type(error).__name__}: {error}"

# What the code's process needs once it runs generated code, grouped by purpose. Found by
# tracing the child through numpy's common paths (linear algebra, FFT, random, printing,
# MemoryError), printing, sleeping and exiting.
ALLOWED_GROUPS: dict[str, tuple[str, ...]] = {
    # memory: every mapping here counts against RLIMIT_AS
    "memory": ("brk", "mmap", "munmap", "mremap", "mprotect", "madvise"),
    # the file descriptors already open (protocol pipes, /dev/null, the stderr pipe)
    "open descriptors": ("read", "write", "readv", "writev"),
    # clocks and sleeping
    "time": ("clock_gettime", "clock_getres", "gettimeofday", "time", "nanosleep",
             "clock_nanosleep"),
    # the process's own signal handlers and masks (sending signals is not allowed)
    "own signals": ("rt_sigaction", "rt_sigprocmask", "rt_sigreturn", "sigaltstack",
                    "restart_syscall"),
    # the process itself: who it is, its randomness, locks, usage, its end
    "own process": ("getpid", "gettid", "getppid", "getuid", "geteuid", "getgid", "getegid",
                    "getrandom", "futex", "sched_yield", "sched_getaffinity",
                    "set_robust_list", "rseq", "getrusage", "times", "exit", "exit_group"),
}
ALLOWED: tuple[str, ...] = tuple(name for names in ALLOWED_GROUPS.values() for name in names)
#: Reading resource limits is allowed (prlimit64 with no new limit, i.e. argument 2 NULL).
READ_ONLY_PRLIMIT = "prlimit64"


def available() -> bool:
    """Whether libseccomp could be loaded."""
    return pyseccomp is not None


def problem() -> str:
    """Why libseccomp could not be loaded ("" if it was)."""
    return "" if pyseccomp is not None else (_load_error or "pyseccomp is missing")


def build_filter() -> pyseccomp.SyscallFilter:
    """The filter for this machine's architecture (not yet loaded). RuntimeError without
    libseccomp."""
    if pyseccomp is None:
        raise RuntimeError("libseccomp is not available (install libseccomp2 and pyseccomp)")
    syscall_filter = pyseccomp.SyscallFilter(pyseccomp.ERRNO(errno.EPERM))
    syscall_filter.set_attr(pyseccomp.Attr.ACT_BADARCH, pyseccomp.KILL_PROCESS)
    syscall_filter.set_attr(pyseccomp.Attr.CTL_TSYNC, 1)
    for name in ALLOWED:
        if resolve(name) >= 0:
            syscall_filter.add_rule(pyseccomp.ALLOW, name)
    if resolve(READ_ONLY_PRLIMIT) >= 0:
        syscall_filter.add_rule(pyseccomp.ALLOW, READ_ONLY_PRLIMIT,
                                pyseccomp.Arg(2, pyseccomp.EQ, 0))
    return syscall_filter


def resolve(name: str) -> int:
    """The number of the system call `name` on this machine; negative if it has none."""
    return pyseccomp.resolve_syscall(pyseccomp.Arch.NATIVE, name)


def install() -> bool:
    """Set no_new_privs and load the filter on every thread of this process. True if the
    filter is in place; False without libseccomp or if the kernel refused."""
    if pyseccomp is None:
        return False
    try:
        build_filter().load()
    except OSError:
        return False
    return True
