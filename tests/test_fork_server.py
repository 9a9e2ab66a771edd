"""Children forked from the program's fork server (`ChildProcess(..., forked=True)`, how the
emulated arm's process starts): they get the descriptors handed to them and the parent's
environment, ignore Ctrl-C, never run the parent's script again, and end when their parent
dies."""

from __future__ import annotations

import importlib.util
import os
import signal
import socket
import subprocess
import sys
import textwrap
import time
from multiprocessing import forkserver
from pathlib import Path

from physcap_drake.can.child_process import ChildProcess, PassedFd
from physcap_drake.fork_server import PRELOADED, fork_context

HERE = Path(__file__).parent
#: How long a child may take to notice its parent is gone, s (it reads its pipe's EOF).
GONE_WITHIN = 10.0


def greet_and_serve(conn, sock_fd: int, greeting: str) -> None:
    """A child: writes `greeting` on the socket it was handed, then answers ("pid",) with its
    process id and ("env", NAME) with its environment's NAME until its parent closes the
    pipe."""
    with socket.socket(fileno=sock_fd) as sock:
        sock.sendall(greeting.encode())
    while True:
        try:
            kind, *args = conn.recv()
        except (EOFError, OSError):
            return
        if kind == "close":
            conn.send(("ok", None))
            return
        conn.send(("ok", os.getpid() if kind == "pid" else os.environ.get(args[0])))


def _gone(pid: int, within: float) -> bool:
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (FileNotFoundError, ProcessLookupError):
            return True
        if state == "Z":  # ended, not reaped yet by the fork server
            return True
        time.sleep(0.05)
    return False


def test_a_forked_child_gets_its_descriptor_and_environment_and_ignores_ctrl_c(monkeypatch):
    fork_context()
    forkserver.ensure_running()  # the server's environment is from before the change
    monkeypatch.setenv("PHYSCAP_TEST_FORKED", "as the parent has it now")
    ours, theirs = socket.socketpair()
    child = ChildProcess(f"{__name__}:greet_and_serve", (PassedFd(theirs.fileno()), "hello"),
                         name="greeter", forked=True)
    theirs.close()
    try:
        ours.settimeout(30.0)
        assert ours.recv(5) == b"hello"
        pid = child.request(("pid",), timeout=10.0)
        assert pid != os.getpid() and child.alive
        assert child.request(("env", "PHYSCAP_TEST_FORKED"), timeout=10.0) == \
            "as the parent has it now"
        os.kill(pid, signal.SIGINT)  # as a Ctrl-C to the process group would
        assert child.request(("pid",), timeout=10.0) == pid and child.alive
    finally:
        child.close()
        ours.close()
    assert not child.alive and _gone(pid, GONE_WITHIN)


SCRIPT = """\
import socket, sys
from physcap_drake.can.child_process import ChildProcess, PassedFd
print("script ran", flush=True)  # no main guard: a child that ran the script again says so
ours, theirs = socket.socketpair()
child = ChildProcess("test_fork_server:greet_and_serve", (PassedFd(theirs.fileno()), "hi"),
                     forked=True)
theirs.close()
ours.settimeout(30.0)
assert ours.recv(2) == b"hi"
print(child.request(("pid",), timeout=30.0), flush=True)
sys.stdin.readline()  # until the test kills this process
"""


def test_a_script_is_not_run_again_in_the_child_and_the_child_ends_with_it(tmp_path):
    script = tmp_path / "start_a_child.py"
    script.write_text(SCRIPT)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(HERE), str(HERE.parent), os.environ.get("PYTHONPATH", "")])}
    parent = subprocess.Popen([sys.executable, str(script)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              env=env)
    try:
        assert parent.stdout.readline() == "script ran\n"
        child_pid = int(parent.stdout.readline())
        parent.kill()  # no goodbye: the child reads the end of its pipe
        out, err = parent.communicate(timeout=30)
    finally:
        if parent.poll() is None:
            parent.kill()
    assert "script ran" not in out, textwrap.shorten(out + err, 500)
    assert _gone(child_pid, GONE_WITHIN), "the forked child outlived its parent"


def test_every_preloaded_module_exists():
    """The server skips a name it cannot import without a word: a misspelt one would only
    make every fork import it again."""
    for name in PRELOADED:
        assert importlib.util.find_spec(name) is not None, name
