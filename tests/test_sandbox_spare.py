"""A child started ahead of its code block (`SpareChild`): the block runs in it behind the
same wall as in a child started for it, its idle wait counts against no budget, it serves one
block only, and one nobody uses is killed, reaped and its folder deleted.
After every test no child process the test started may be left, running or zombie."""

from __future__ import annotations

import gc
import os
import subprocess
import sys
import time

import pytest

from physcap_drake.agent.sandbox import SandboxLimits, SandboxSession, SpareChild
from physcap_drake.agent.sandbox.child_process import children_of, scan_children_of

LIMITS = SandboxLimits(cpu_s=2, compute_wall_s=5, total_wall_s=5, memory_mb=512, startup_s=5)
# Hostile code run with the static check and the restricted builtins off: the process wall
# alone must stop each attempt, in a spare as in a child started for the code.
ATTACKS = ("import os\n"
           "for attack in (lambda: os.fork(), lambda: open('/etc/hostname').read(),\n"
           "               lambda: os.kill(os.getppid(), 0), lambda: open('x', 'w')):\n"
           "    try:\n"
           "        attack()\n"
           "        print('allowed')\n"
           "    except OSError as error:\n"
           "        print(type(error).__name__)\n")


@pytest.fixture(autouse=True)
def no_leftover_processes():
    """No child process (or zombie) the test started is left; children that other tests of
    the session left running (e.g. a Ray instance) are not this test's."""
    before = set(children_of(os.getpid()))
    yield
    left = set(children_of(os.getpid())) - before
    assert not left, f"a sandbox process (or zombie) was left behind: {sorted(left)}"


def run(code: str, spare: SpareChild | None = None, **private):
    with SandboxSession(code, {}, LIMITS, spare=spare, **private) as session:
        return session.start() or session.next_call()


def test_a_block_runs_in_the_spare_behind_the_same_wall_as_in_a_fresh_child():
    spare = SpareChild()
    pid, home = spare.pid, spare.home
    assert pid in children_of(os.getpid()) and os.path.isdir(home)
    warm = run(ATTACKS, spare, skip_ast_check=True, real_builtins=True)
    cold = run(ATTACKS, skip_ast_check=True, real_builtins=True)
    assert warm.ok and cold.ok, (warm.error, cold.error)
    assert "allowed" not in warm.stdout
    assert warm.stdout == cold.stdout and warm.isolation == cold.isolation
    assert spare.pid is None and spare.home is None  # taken: the session owned and ended it
    assert pid not in children_of(os.getpid()) and not os.path.exists(home)


def test_a_spare_serves_one_block_only():
    spare = SpareChild()
    assert run("print(np.arange(3))\n", spare).stdout == "[0 1 2]\n"
    with pytest.raises(RuntimeError, match="already taken"):
        run("print(1)\n", spare)


def test_the_spares_idle_wait_counts_against_no_budget_of_its_block(monkeypatch):
    """The spare waits, by the parent's clock, far longer than the block's start-up and
    wall-time limits (the clock jumps ahead); its block still starts and runs."""
    spare = SpareChild()
    real = time.monotonic
    monkeypatch.setattr(time, "monotonic", lambda: real() + 100 * LIMITS.total_wall_s)
    outcome = run("total = 0\nfor i in range(1000):\n    total += i\nprint(total)\n", spare)
    assert outcome.ok, outcome.error
    assert outcome.stdout == "499500\n"


def test_an_unused_spare_is_killed_and_its_folder_deleted():
    spare = SpareChild()
    pid, home = spare.pid, spare.home
    spare.close()
    assert pid not in children_of(os.getpid()) and not os.path.exists(home)
    spare.close()  # idempotent
    with pytest.raises(RuntimeError, match="already closed"):
        spare.take()


def test_a_spare_nobody_closes_is_killed_when_it_is_dropped():
    spare = SpareChild()
    pid, home = spare.pid, spare.home
    del spare
    gc.collect()
    assert pid not in children_of(os.getpid()) and not os.path.exists(home)


def test_a_spare_left_open_when_the_interpreter_exits_is_killed_with_it(tmp_path):
    """The last resort for an owner that never closes its spare (e.g. a Drake Context that
    Python cannot collect): the spare goes when the interpreter exits."""
    script = ("import tempfile\n"
              f"tempfile.tempdir = {str(tmp_path)!r}\n"
              "from physcap_drake.agent.sandbox import SpareChild\n"
              "spare = SpareChild()\n"
              "print(spare.pid, flush=True)\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=60, check=True)
    pid = int(done.stdout)
    assert not os.path.exists(f"/proc/{pid}") and list(tmp_path.iterdir()) == []


def test_rejected_code_starts_no_child_and_its_session_kills_the_spare():
    spare = SpareChild()
    pid, home = spare.pid, spare.home
    with SandboxSession("import os\n", {}, LIMITS, spare=spare) as session:
        assert session.start().kind == "rejected"
        assert spare.pid == pid  # never taken: the code did not run
    assert pid not in children_of(os.getpid()) and not os.path.exists(home)


def _process_state(pid: int) -> str:
    with open(f"/proc/{pid}/stat", encoding="ascii") as stat:
        text = stat.read()
    return text[text.rfind(")") + 2]


def test_children_of_finds_running_and_zombie_children_as_a_scan_of_proc_does():
    """children_of reads the kernel's per-thread lists of children: it must find what the
    scan of every process's /proc/<pid>/stat finds, a child not yet reaped (a zombie)
    included, for a code process must never outlive its sandbox child unnoticed."""
    running = subprocess.Popen(["sleep", "30"])
    zombie = subprocess.Popen(["true"])
    try:
        deadline = time.monotonic() + 10
        while _process_state(zombie.pid) != "Z":
            assert time.monotonic() < deadline, "the child never exited"
            time.sleep(0.01)
        listed, scanned = set(children_of(os.getpid())), set(scan_children_of(os.getpid()))
        assert {running.pid, zombie.pid} <= listed
        assert {running.pid, zombie.pid} <= scanned
    finally:
        running.kill()
        running.wait()
        zombie.wait()
    assert not {running.pid, zombie.pid} & set(children_of(os.getpid()))
