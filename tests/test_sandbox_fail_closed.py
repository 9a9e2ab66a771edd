"""Fail closed: no code block runs without every layer of the wall the platform gives, and
`physcap run` / `physcap eval` refuse to start where libseccomp cannot be loaded.

libseccomp is hidden, never uninstalled: in this process by taking the loaded binding away
from `seccomp`, in the child by the switch its loader honours (`seccomp.HIDE_ENV`).
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from test_sandbox import FakeRobot, no_leftover_processes, run  # noqa: F401 - fixture

from physcap_drake import cli
from physcap_drake.agent.sandbox import isolation, seccomp

PRINTS_AND_CALLS = "print('ran')\nget_object_pose('cube')\n"


@pytest.fixture
def robot() -> FakeRobot:
    return FakeRobot()


@pytest.mark.parametrize("command", [
    ["run", "--task", "identify_empty_can", "--seed", "3"],
    ["eval", "--tasks", "identify_empty_can"],
])
def test_the_commands_refuse_to_start_without_libseccomp(monkeypatch, capsys, command):
    monkeypatch.setattr(seccomp, "pyseccomp", None)
    with pytest.raises(SystemExit) as exit_:
        cli.main(command)
    assert exit_.value.code == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith("error: the sandbox's system-call filter cannot be loaded")
    assert "libseccomp2" in lines[0] and "pyseccomp" in lines[0] and "./run setup" in lines[0]


def test_the_commands_start_with_libseccomp(monkeypatch, capsys):
    """The same line up, with the filter there, gets past the check (to the task check)."""
    assert seccomp.available()
    with pytest.raises(SystemExit) as exit_:
        cli.main(["run", "--task", "no_such_task"])
    assert exit_.value.code == 2
    assert "unknown task 'no_such_task'" in capsys.readouterr().err


def test_the_loader_honours_the_hiding_switch():
    probe = ("from physcap_drake.agent.sandbox import seccomp\n"
             "print(seccomp.available(), seccomp.install())\n")
    environment = {**os.environ, seccomp.HIDE_ENV: "1"}
    hidden = subprocess.run([sys.executable, "-c", probe], env=environment,
                            capture_output=True, text=True, check=True, timeout=60)
    assert hidden.stdout.split() == ["False", "False"]


def test_the_parent_refuses_a_child_without_the_filter(robot, monkeypatch):
    monkeypatch.setenv(seccomp.HIDE_ENV, "1")
    with pytest.raises(isolation.IsolationMissing, match="lacks seccomp.*libseccomp2"):
        run(PRINTS_AND_CALLS, robot)
    assert robot.calls == []


def test_the_child_itself_runs_nothing_without_a_required_layer(robot, monkeypatch):
    """With the parent's check switched off, the child still runs no code."""
    monkeypatch.setenv(seccomp.HIDE_ENV, "1")
    monkeypatch.setattr(isolation, "check_reported", lambda reported: None)
    outcome = run(PRINTS_AND_CALLS, robot)
    assert outcome.kind == "crashed" and "seccomp" not in outcome.isolation
    assert outcome.stdout == "" and robot.calls == []


def test_a_namespace_the_kernel_gives_is_required(robot, monkeypatch):
    """A layer the platform is expected to give (here: one the child never makes as root)
    is missing: refused. One the kernel does not give is not required."""
    given = isolation.kernel_namespaces()
    assert run("print('ran')\n", robot).stdout == "ran\n"
    reported = run("pass\n", robot).isolation
    absent = next((name for name in isolation.WHERE_ALLOWED if name not in reported), None)
    if absent is None:
        pytest.skip("the child makes every namespace here")
    monkeypatch.setattr(isolation, "kernel_namespaces", lambda: given | {absent})
    with pytest.raises(isolation.IsolationMissing, match=f"lacks {absent}"):
        run(PRINTS_AND_CALLS, robot)
    monkeypatch.setattr(isolation, "kernel_namespaces", lambda: frozenset())
    assert run("print('ran')\n", robot).stdout == "ran\n"
