"""The process wall, built by the child around itself before it runs generated code.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import ctypes
import errno
import os
import resource
import signal

NOBODY = 65534
_PR_SET_PDEATHSIG = 1
_REFUSED = (errno.EPERM, errno.EINVAL, errno.ENOSYS, errno.EACCES, errno.ENOSPC,
            errno.EUSERS, errno.ENOMEM)

# Namespace flags to try one by one, with the names reported to the parent.
_NAMESPACES = (
    ("net_ns", "CLONE_NEWNET"),
    ("mount_ns", "CLONE_NEWNS"),
    ("ipc_ns", "CLONE_NEWIPC"),
    ("pid_ns", "CLONE_NEWPID"),
)


def close_other_fds(keep: set[int]) -> None:
    """Close every file descriptor above 2 that is not in `keep`."""
    low = 3
    for fd in sorted(fd for fd in keep if fd >= 3):
        os.closerange(low, fd)
        low = fd + 1
    os.closerange(low, _fd_ceiling())


def _fd_ceiling() -> int:
    soft, _hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY or soft > 1 << 20:
        return 1 << 20
    return soft


def enter_namespaces() -> list[str]:
    """Unshare what the kernel allows; return the names of the namespaces entered. A user
    namespace is only needed (and only tried) when not running as root."""
    if not hasattr(os, "unshare"):
        return []
    entered: list[str] = []
    if os.geteuid() != 0:
        if not _unshare(os.CLONE_NEWUSER):
            return entered
        entered.append("user_ns")
    for name, flag in _NAMESPACES:
        if _unshare(getattr(os, flag)):
            entered.append(name)
    return entered


def _unshare(flag: int) -> bool:
    try:
        os.unshare(flag)
    except OSError as error:
        if error.errno in _REFUSED:
            return False
        raise
    return True


def drop_root() -> bool:
    """If running as root, become nobody:nogroup with no supplementary groups. True if the
    process ended up without root (also when it never had it)."""
    if os.geteuid() != 0:
        return True
    try:
        os.setgroups([])
        os.setresgid(NOBODY, NOBODY, NOBODY)
        os.setresuid(NOBODY, NOBODY, NOBODY)
    except OSError:
        return False
    return os.geteuid() != 0 and os.getuid() != 0


def die_with_parent() -> bool:
    """Ask the kernel to SIGKILL this process when its parent dies (PR_SET_PDEATHSIG), so
    the code's process cannot outlive the one waiting for it. True if the kernel agreed."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
    except OSError:
        return False
    return libc.prctl(_PR_SET_PDEATHSIG, ctypes.c_ulong(signal.SIGKILL), ctypes.c_ulong(0),
                      ctypes.c_ulong(0), ctypes.c_ulong(0)) == 0


def set_rlimits(cpu_s: float, memory_mb: int, max_fd: int, *, kill_at_soft: bool) -> None:
    """Cap the calling process: `cpu_s` more CPU seconds, `memory_mb` of address space (the
    whole process, numpy included; never below what it already maps), no new processes or
    threads, no file data, no core dumps, file descriptors numbered below max_fd + 8.

    With `kill_at_soft` the CPU hard limit equals the soft one (the kernel sends SIGKILL
    there: a PID namespace's first process ignores SIGXCPU); otherwise SIGXCPU at the soft
    limit ends the process and SIGKILL follows a second later if it is caught."""
    used = resource.getrusage(resource.RUSAGE_SELF)
    # whole seconds only; rounded, so the code gets cpu_s give or take half a second
    cpu_limit = max(1, round(used.ru_utime + used.ru_stime + cpu_s))
    cpu_hard = cpu_limit if kill_at_soft else cpu_limit + 1
    resource.setrlimit(resource.RLIMIT_CPU, (cpu_limit, cpu_hard))
    address_space = max(memory_mb << 20, _mapped_bytes() + (64 << 20))
    resource.setrlimit(resource.RLIMIT_AS, (address_space, address_space))
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    resource.setrlimit(resource.RLIMIT_FSIZE, (0, 0))
    resource.setrlimit(resource.RLIMIT_NOFILE, (max_fd + 8, max_fd + 8))
    resource.setrlimit(resource.RLIMIT_NPROC, (0, 0))
    # Writing past RLIMIT_FSIZE raises SIGXFSZ, which would kill us silently; ignored, the
    # write fails with EFBIG and the code sees an ordinary error.
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)


def _mapped_bytes() -> int:
    """The process's current virtual size (0 if /proc cannot tell). Read with os-level calls:
    once root is dropped the standard library may be unreadable, so nothing here may need
    to import a module (as open() with an encoding would)."""
    try:
        fd = os.open("/proc/self/statm", os.O_RDONLY)
        try:
            pages = int(os.read(fd, 256).split()[0])
        finally:
            os.close(fd)
    except (OSError, ValueError, IndexError):
        return 0
    return pages * os.sysconf("SC_PAGE_SIZE")
