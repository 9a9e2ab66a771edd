"""The sandbox for generated code: the static check, the protocol, and the process wall.

A fake robot API (plain functions recording their calls) stands in for the real one. Hostile
snippets come in three groups: those the static check rejects, those that pass it but hit a
runtime limit or the runtime layer, and "raw" ones run with the check and the restricted
builtins switched off (a test-only switch) to prove the process wall holds on its own.
After every test no child process of the test process may be left, running or zombie.
"""

from __future__ import annotations

import dataclasses as dc
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
from sandbox_runs import run_sandboxed

from physcap_drake.agent.sandbox import (
    ApiFunction,
    Call,
    CodeOutcome,
    CodeRejected,
    FunctionSpec,
    Meters,
    Number,
    OrNone,
    SandboxLimits,
    SandboxSession,
    Text,
    Vector,
    check_code,
    protocol,
    seccomp,
)

LIMITS = SandboxLimits(cpu_s=2, compute_wall_s=2, total_wall_s=30, memory_mb=512)
# Filling 512 MB page by page (and freeing it after the MemoryError) takes seconds of wall
# time on a loaded machine; these tests are about memory, so time is no constraint here.
MEMORY = SandboxLimits(cpu_s=10, compute_wall_s=20, total_wall_s=30, memory_mb=512)


class SkillRefused(RuntimeError):
    """Stands in for the robot API's own SkillRefused: the parent reports the class name."""


class WeirdError(Exception):
    """An API error class the sandboxed code has never heard of."""


class FakeArmFault(RuntimeError):
    """Stands in for control.errors.ArmFault: fatal, never to be caught by the code."""


class FakeRobot:
    """Records every command; refuses targets outside a 1 m box; `safe` stays True unless
    a command it should never have accepted reached it."""

    WORKSPACE = 1.0

    def __init__(self) -> None:
        self.calls: list[tuple[str, tuple]] = []
        self.position = np.array([0.2, 0.0, 0.2])
        self.safe = True
        self.breakpoints = 0
        self.call_starts: list[float] = []  # monotonic time at which each sleep began
        self.robot_time = 0.0  # s; each goto_pose takes 10 s
        self.knowledge: list[str] = []  # what get_mass "measured"

    def goto_pose(self, position, quaternion_wxyz=None, z_approach=0.0):
        self.calls.append(("goto_pose", (position, quaternion_wxyz, z_approach)))
        self.robot_time += 10.0
        target = np.asarray(position, dtype=float)
        if target.shape != (3,) or not np.all(np.isfinite(target)):
            raise SkillRefused(f"position must be three finite numbers, got {position!r}")
        if np.any(np.abs(target) > self.WORKSPACE):
            raise SkillRefused("target outside the workspace")
        self.position = target
        self.safe = self.safe and bool(np.all(np.abs(self.position) <= self.WORKSPACE))

    def get_mass(self, position, name=None) -> float:
        self.calls.append(("get_mass", (position, name)))
        self.knowledge.append(f"{name}: mass = 0.350 kg")
        return 0.35

    def get_object_pose(self, name):
        self.calls.append(("get_object_pose", (name,)))
        poses = {"cube": np.array([0.3, 0.1, 0.05]), "ghost": np.array([np.nan, np.inf, -np.inf])}
        if name not in poses:
            raise SkillRefused(f"no object called {name!r} in view")
        return poses[name]

    def breakpoint_code_block(self) -> None:
        self.calls.append(("breakpoint_code_block", ()))
        self.breakpoints += 1

    def sleep(self, seconds) -> None:
        self.calls.append(("sleep", (seconds,)))
        self.call_starts.append(time.monotonic())
        time.sleep(seconds)

    def explode(self) -> None:
        self.calls.append(("explode", ()))
        raise KeyError("an unexpected kind of failure inside the API")

    def weird(self) -> None:
        self.calls.append(("weird", ()))
        raise WeirdError("a class the code cannot know")

    def fail_arm(self) -> None:
        self.calls.append(("fail_arm", ()))
        raise FakeArmFault("the arm reports: collision")

    def huge_result(self) -> np.ndarray:
        self.calls.append(("huge_result", ()))
        return np.zeros(10**6)

    def loud_refusal(self) -> None:
        self.calls.append(("loud_refusal", ()))
        raise SkillRefused("no! " * 10**6)

    def meters(self) -> Meters:
        return Meters(lambda: self.robot_time,
                      lambda: sum(len(entry) for entry in self.knowledge))

    def api(self) -> dict:
        """goto_pose and get_mass with parameter kinds (as the robot API declares them), the
        rest checked as plain values."""
        table = {name: getattr(self, name) for name in
                 ("get_object_pose", "breakpoint_code_block", "sleep", "explode", "weird",
                  "fail_arm", "huge_result", "loud_refusal")}
        table["goto_pose"] = ApiFunction(self.goto_pose, FunctionSpec.of(
            "goto_pose", self.goto_pose, {"position": Vector(3),
                                          "quaternion_wxyz": OrNone(Vector(4)),
                                          "z_approach": Number()}, motion=True))
        table["get_mass"] = ApiFunction(self.get_mass, FunctionSpec.of(
            "get_mass", self.get_mass, {"position": Vector(3), "name": OrNone(Text(120))},
            motion=True))
        return table


@pytest.fixture
def robot() -> FakeRobot:
    return FakeRobot()


def _children_of_this_process() -> list[int]:
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", encoding="ascii", errors="replace") as handle:
                text = handle.read()
        except OSError:
            continue
        if text[text.rfind(")") + 2:].split()[1] == str(os.getpid()):
            found.append(int(entry))
    return found


@pytest.fixture(autouse=True)
def no_leftover_processes():
    before = set(_children_of_this_process())  # e.g. the fork server an emulator test left
    yield
    left = set(_children_of_this_process()) - before
    assert left == set(), "a sandbox process (or zombie) was left behind"


def run(code: str, robot: FakeRobot, limits: SandboxLimits = LIMITS, **private) -> CodeOutcome:
    return run_sandboxed(code, robot.api(), limits, **private)


def run_raw(code: str, robot: FakeRobot, limits: SandboxLimits = LIMITS) -> CodeOutcome:
    """No static check and the real builtins: only the process wall stands."""
    return run(code, robot, limits, _skip_ast_check=True, _real_builtins=True)


# -- normal code -------------------------------------------------------------------------


def test_normal_code_prints_and_uses_api_results_as_arrays(robot):
    code = (
        "import numpy as np\n"
        "pos = get_object_pose('cube')\n"
        "print('cube at', pos, 'ndarray' if isinstance(pos, np.ndarray) else '?')\n"
        "goto_pose(pos + np.array([0, 0, 0.1]), z_approach=0.05)\n"
        "mass = get_mass(pos)\n"
        "print(f'mass {mass:.2f} kg, norm {np.linalg.norm(pos):.3f}')\n"
    )
    outcome = run(code, robot)
    assert outcome.ok, outcome.error
    assert outcome.kind == "ok" and outcome.error is None
    assert "cube at [0.3  0.1  0.05] ndarray" in outcome.stdout
    assert "mass 0.35 kg, norm 0.320" in outcome.stdout
    assert [name for name, _ in outcome.api_calls] == ["get_object_pose", "goto_pose",
                                                        "get_mass"]
    name, (position, quaternion, z_approach) = robot.calls[1]
    assert name == "goto_pose" and position == pytest.approx([0.3, 0.1, 0.15])
    assert quaternion is None and z_approach == 0.05
    assert "rlimits" in outcome.isolation and "fds_closed" in outcome.isolation


def test_api_errors_are_catchable_by_class_name(robot):
    code = (
        "try:\n"
        "    goto_pose([5.0, 0, 0])\n"
        "except SkillRefused as error:\n"
        "    print('refused:', error)\n"
        "try:\n"
        "    explode()\n"
        "except KeyError as error:\n"
        "    print('key error:', error)\n"
        "print(issubclass(SkillRefused, SkillError), issubclass(SkillError, RuntimeError))\n"
        "try:\n"
        "    weird()\n"
        "except RuntimeError as error:\n"
        "    print('runtime error:', error)\n"
    )
    outcome = run(code, robot)
    assert outcome.ok, outcome.error
    assert "refused: target outside the workspace" in outcome.stdout
    assert "key error:" in outcome.stdout and "failure inside the API" in outcome.stdout
    assert "True True" in outcome.stdout
    assert "runtime error: WeirdError: a class the code cannot know" in outcome.stdout
    assert robot.safe and np.allclose(robot.position, [0.2, 0.0, 0.2])


def test_uncaught_api_error_names_class_message_and_line(robot):
    outcome = run("x = 1\ny = 2\nget_object_pose('unicorn')\n", robot)
    assert outcome.kind == "exception" and not outcome.ok
    assert "SkillRefused at line 3" in outcome.error
    assert "no object called 'unicorn' in view" in outcome.error
    assert "get_object_pose('unicorn')" in outcome.error


def test_exception_in_a_function_reports_the_innermost_generated_line(robot):
    code = "def f(values):\n    return values[10]\n\nprint('before')\nf([1, 2])\n"
    outcome = run(code, robot)
    assert outcome.kind == "exception"
    assert outcome.error.startswith("IndexError at line 2: list index out of range")
    assert outcome.stdout == "before\n"


def test_nan_and_inf_reach_the_code_but_never_the_api(robot):
    code = ("p = get_object_pose('ghost')\n"
            "print(np.isnan(p[0]), np.isposinf(p[1]), np.isneginf(p[2]))\n"
            "try:\n"
            "    get_mass([0.3, float('inf'), 0.0])\n"
            "except ValueError as error:\n"
            "    print('refused:', error)\n"
            "get_mass([float('nan'), 0.0, 0.0])\n")
    outcome = run(code, robot)
    assert "True True True" in outcome.stdout
    assert "refused: get_mass(): position must hold finite numbers, got [0.3, inf, 0.0]" in (
        outcome.stdout)
    assert outcome.kind == "exception"
    assert outcome.error.startswith("ValueError at line 7: get_mass(): position must hold "
                                    "finite numbers, got [nan, 0.0, 0.0]")
    assert [name for name, _ in robot.calls] == ["get_object_pose"]


def test_breakpoint_code_block_is_allowed_but_breakpoint_is_not(robot):
    assert run("breakpoint_code_block()\n", robot).ok
    assert robot.breakpoints == 1
    outcome = run("breakpoint()\n", robot)
    assert outcome.kind == "rejected" and "'breakpoint'" in outcome.error
    assert robot.breakpoints == 1


def test_values_that_cannot_be_sent_raise_in_the_code(robot):
    outcome = run("goto_pose(np)\n", robot)
    assert outcome.kind == "exception"
    assert "TypeError at line 1: goto_pose(): values of type SandboxedModule" in outcome.error
    assert robot.calls == []


def test_api_call_time_does_not_count_as_compute_time(robot):
    limits = SandboxLimits(cpu_s=2, compute_wall_s=0.8, total_wall_s=30, memory_mb=512)
    outcome = run("sleep(0.6)\nsleep(0.6)\nprint('done')\n", robot, limits)
    assert outcome.ok, outcome.error


OWN_WALL = SandboxLimits(cpu_s=10, compute_wall_s=20, total_wall_s=1.0, memory_mb=512)
OWN_WALL_STOP = "1 s of the block's own wall time (robot calls not counted)"


def test_slow_robot_calls_do_not_use_up_the_blocks_own_wall_time(robot):
    """The parent answering a call (a robot motion simulated on a slow host) is not the
    code's time: two calls of 0.75 s each outlast the 1 s limit and the block still ends."""
    outcome = run("sleep(0.75)\nsleep(0.75)\nprint('done')\n", robot, OWN_WALL)
    assert outcome.ok, outcome.error
    assert outcome.stdout == "done\n"
    assert time.monotonic() - robot.call_starts[0] > OWN_WALL.total_wall_s


@pytest.mark.parametrize("code", ["while True:\n    pass\n",
                                  "while True:\n    get_object_pose('cube')\n"],
                         ids=["busy loop", "loop of quick robot calls"])
def test_code_that_runs_past_its_own_wall_time_is_stopped(robot, code):
    limits = dc.replace(OWN_WALL, max_api_calls=10**7)
    outcome = run(code, robot, limits)
    assert outcome.kind == "wall_limit", outcome
    assert OWN_WALL_STOP in outcome.error
    assert outcome.duration_s >= limits.total_wall_s


def test_the_owner_idling_while_the_code_runs_counts_as_the_blocks_time(robot):
    """Between answering a call and asking for the next one the code runs on: that time is
    the block's, however the owner spends it; time spent answering is not."""
    code = "get_object_pose('cube')\nget_object_pose('cube')\nget_object_pose('cube')\n"
    with SandboxSession(code, robot.api(), OWN_WALL) as session:
        assert session.start() is None
        call = session.next_call()
        time.sleep(1.2)  # answering: not counted
        assert session.answer(robot.get_object_pose(*call.args)) is None
        call = session.next_call()
        assert isinstance(call, Call), call
        assert session.answer(robot.get_object_pose(*call.args)) is None
        time.sleep(1.2)  # idling while the code runs: counted
        outcome = session.next_call()
    assert outcome.kind == "wall_limit", outcome
    assert OWN_WALL_STOP in outcome.error
    assert len(robot.calls) == 2


def test_every_common_numpy_path_works_after_the_lockdown(robot):
    code = (
        "import numpy as np\nimport math\nfrom numpy.linalg import norm\n"
        "a = np.array([[2.0, 1.0], [1.0, 3.0]])\n"
        "print(np.linalg.inv(a), np.linalg.eigh(a), np.linalg.svd(a), norm(a))\n"
        "print(np.median(a), np.unique([3, 1, 1]), np.percentile(a, 50), np.histogram([1, 2]))\n"
        "print(np.polyfit([0, 1, 2], [0, 1, 4], 2), np.fft.rfft([1, 0, 0, 0]))\n"
        "print(np.random.default_rng(0).normal(size=2), np.random.default_rng().uniform())\n"
        "print(np.polynomial.Polynomial.fit([0, 1, 2], [1, 2, 5], 2), math.hypot(3, 4))\n"
        "with np.errstate(divide='ignore'):\n    print(np.array([1.0]) / 0)\n"
        "print(np.array([1.0]) / 0)\n"
    )
    outcome = run(code, robot)
    assert outcome.ok, outcome.error
    assert "RuntimeWarning: divide by zero" in outcome.stdout


# -- hostile code the static check rejects -------------------------------------------------

REJECTED = [
    ("import os", "'os'"),
    ("import subprocess", "'subprocess'"),
    ("import socket", "'socket'"),
    ("import sys", "'sys'"),
    ("import ctypes", "'ctypes'"),
    ("import importlib", "'importlib'"),
    ("import builtins", "'builtins'"),
    ("from os import system", "'os'"),
    ("__import__('os')", "'__import__'"),
    ("().__class__.__bases__[0].__subclasses__()", "'__class__'"),
    ("(lambda: 0).__globals__", "'__globals__'"),
    ("open('/etc/passwd').read()", "'open'"),
    ("eval('1 + 1')", "'eval'"),
    ("exec('x = 1')", "'exec'"),
    ("compile('1', 'f', 'eval')", "'compile'"),
    ("getattr(np, 'load')", "'getattr'"),
    ("np.load('x.npy')", "'load'"),
    ("np.save('x.npy', np.ones(3))", "'save'"),
    ("np.ctypeslib", "'ctypeslib'"),
    ("np.lib.format", "'lib'"),
    ("np.ones(3).tofile('x')", "'tofile'"),
    ("np.ones(3).dump('x')", "'dump'"),
    ("from numpy import ctypeslib", "'ctypeslib'"),
    ("import numpy.testing", "'numpy.testing'"),
    ("from numpy import *", "import *"),
    ("globals()['x'] = 1", "'globals'"),
    ("type('X', (), {})", "'type'"),
    ("x = 0\ndef f():\n    global x\n    x = 1", "'global'"),
    ("breakpoint()", "'breakpoint'"),
    ("np.__dict__", "'__dict__'"),
    ("math.__loader__", "'__loader__'"),
    ("'{0.__class__}'.format(1)", "'format'"),
    ("format(1, 'x')", "'format'"),
    ("g = (x for x in [1])\ng.gi_frame.f_globals", "'gi_frame'"),
    ("class X(metaclass=abc.ABCMeta):\n    pass", "metaclass"),
    ("async def f():\n    await g()", "'async def'"),
    ("def f():\n    yield 1", "'yield'"),
    ("int.mro()", "'mro'"),
    ("vars(np)", "'vars'"),
    ("match x:\n    case {'a': 1}:\n        pass", "'match'"),
]


@pytest.mark.parametrize(("code", "fragment"), REJECTED, ids=[c for c, _ in REJECTED])
def test_static_check_rejects_hostile_code(robot, code, fragment):
    outcome = run(code, robot)
    assert outcome.kind == "rejected" and not outcome.ok
    assert fragment in outcome.error and "line " in outcome.error
    assert outcome.isolation == []  # no process was started
    assert robot.calls == [] and robot.safe


def test_code_rejected_names_line_and_construct():
    with pytest.raises(CodeRejected) as caught:
        check_code("x = 1\ny = x\nz = y.__class__\n")
    assert caught.value.line == 3
    assert "'__class__'" in caught.value.construct
    assert str(caught.value).startswith("code rejected: line 3: the attribute '__class__'")
    with pytest.raises(CodeRejected, match="syntax error: line 1"):
        check_code("def (:\n")
    for pathological in ("(" * 10_000 + ")" * 10_000, "x" + ".y" * 30_000, "1" * 200_000):
        with pytest.raises(CodeRejected):
            check_code(pathological)


def test_static_check_accepts_ordinary_robot_code():
    check_code(
        "import numpy as np\nimport math\nfrom numpy.linalg import norm\n"
        "for _ in range(3):\n    pass\n"
        "class Grip:\n    width = 0.04\n"
        "def lift(p, dz=0.1):\n    return p + np.array([0.0, 0.0, dz])\n"
        "try:\n    goto_pose(lift(get_object_pose('cube')))\nexcept SkillRefused as e:\n"
        "    print(f'{e!r:>10}')\n"
        "breakpoint_code_block()\n"
        "values = [v * 2 for v in range(3) if v]\nsquares = {k: k * k for k in values}\n"
        "with np.errstate(divide='ignore'):\n    r = np.array([1.0]) / 0\n"
    )


# -- hostile code that passes the static check: runtime limits and the runtime layer --------

RUNTIME = [
    ("while True:\n    pass",
     SandboxLimits(cpu_s=10, compute_wall_s=1, memory_mb=512), "wall_limit", "computed for"),
    ("x = 0\nwhile True:\n    x += 1",
     SandboxLimits(cpu_s=1, compute_wall_s=10, memory_mb=512), "cpu_limit", "CPU time"),
    ("x = [0] * 10**10", MEMORY, "memory_limit", "MemoryError at line 1"),
    ("x = np.ones(10**10)", MEMORY, "memory_limit", "Unable to allocate"),
    ("x = []\nwhile True:\n    x.append([1.5] * 10**6)", MEMORY, "memory_limit", "line 3"),
    ("for i in range(1000):\n    get_mass([0.3, 0.0, 0.0])",
     SandboxLimits(cpu_s=2, compute_wall_s=2, memory_mb=512, max_api_calls=20),
     "api_call_limit", "more than 20 robot API calls"),
    ("print(np.char)", LIMITS, "exception", "numpy.char is not available"),
    ("print(np.rec.array)", LIMITS, "exception", "not available in the sandbox"),
    ("while True:\n    print('spam')",
     SandboxLimits(cpu_s=10, compute_wall_s=1, memory_mb=512), "wall_limit", "computed for"),
]


@pytest.mark.parametrize(("code", "limits", "kind", "fragment"), RUNTIME,
                         ids=[c.splitlines()[-1].strip() for c, *_ in RUNTIME])
def test_runtime_limits_stop_hostile_code(robot, code, limits, kind, fragment):
    outcome = run(code, robot, limits)
    assert outcome.kind == kind and not outcome.ok, outcome
    assert fragment in outcome.error
    assert len(outcome.stdout) <= limits.max_output_chars + 200
    assert robot.safe and all(name == "get_mass" for name, _ in robot.calls)


def test_huge_output_is_truncated_not_an_error(robot):
    outcome = run("print('x' * 10**7)\nfor i in range(10**5):\n    print('line', i)\n", robot)
    assert outcome.ok and outcome.output_truncated
    assert outcome.stdout.startswith("xxxx")
    assert len(outcome.stdout) <= LIMITS.max_output_chars + 200
    assert "[output truncated: more than 20000 characters]" in outcome.stdout


def test_runtime_layer_alone_stops_imports_and_module_attributes(robot):
    """With the static check off, the restricted builtins and module views still hold."""
    for code, fragment in [("import os", "import of 'os' is not allowed"),
                           ("np.lib", "numpy.lib is not available"),
                           ("open('/etc/passwd')", "NameError"),
                           ("np.pi = 3", "read-only")]:
        outcome = run(code, robot, _skip_ast_check=True)
        assert outcome.kind == "exception", code
        assert fragment in outcome.error, (code, outcome.error)


# -- the process wall (static check and restricted builtins off) ---------------------------


def test_fork_bomb_is_stopped(robot):
    outcome = run_raw("import os\nwhile True:\n    os.fork()\n", robot)
    assert outcome.kind == "exception"
    assert "PermissionError" in outcome.error or "BlockingIOError" in outcome.error


def test_subprocesses_cannot_start(robot):
    outcome = run_raw("import subprocess\nsubprocess.run(['/bin/true'])\n", robot)
    assert outcome.kind == "exception" and "line 2" in outcome.error


def test_files_cannot_be_written(robot, tmp_path):
    tmp_path.chmod(0o777)
    target = tmp_path / "pwned.txt"
    code = (f"with open({str(target)!r}, 'w') as f:\n    f.write('x' * 100)\n")
    outcome = run_raw(code, robot)
    assert outcome.kind == "exception"
    assert not target.exists() or target.stat().st_size == 0
    outcome = run_raw("with open('here.txt', 'w') as f:\n    f.write('x' * 100)\n", robot)
    assert outcome.kind == "exception"


def test_files_cannot_be_read(robot):
    outcome = run_raw("print(open('/etc/hostname').read())\n", robot)
    assert outcome.kind == "exception" and outcome.stdout == ""


def test_network_is_unreachable(robot):
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        server.setblocking(False)
        port = server.getsockname()[1]
        code = (f"import socket\ns = socket.create_connection(('127.0.0.1', {port}), timeout=1)\n"
                "s.sendall(b'secret')\n")
        outcome = run_raw(code, robot)
        assert outcome.kind == "exception"
        with pytest.raises(BlockingIOError):
            server.accept()


def test_parent_cannot_be_signalled(robot):
    me = os.getpid()
    code = ("import os, signal, ctypes\n"
            "results = []\n"
            f"for attempt in (lambda: os.kill({me}, 9), lambda: os.kill(os.getppid(), 9),\n"
            "                lambda: os.kill(-1, 9), lambda: os.killpg(0, signal.SIGSTOP)):\n"
            "    try:\n"
            "        attempt()\n"
            "        results.append('sent')\n"
            "    except OSError as error:\n"
            "        results.append(type(error).__name__)\n"
            f"results.append(ctypes.CDLL(None).syscall(62, {me}, 9))\n"
            "print(results)\n")
    outcome = run_raw(code, robot)
    assert os.getpid() == me  # still here
    assert outcome.ok, outcome.error
    assert "sent" not in outcome.stdout


def test_signal_tampering_does_not_lift_the_limits(robot):
    code = ("import signal\n"
            "for s in (signal.SIGXCPU, signal.SIGALRM, signal.SIGTERM):\n"
            "    signal.signal(s, signal.SIG_IGN)\n"
            "signal.alarm(0)\n"
            "while True:\n    pass\n")
    outcome = run_raw(code, robot, SandboxLimits(cpu_s=1, compute_wall_s=10, memory_mb=512))
    assert outcome.kind == "cpu_limit", outcome
    outcome = run_raw("import signal, time\nsignal.signal(signal.SIGALRM, signal.SIG_IGN)\n"
                      "time.sleep(100)\n", robot,
                      SandboxLimits(cpu_s=5, compute_wall_s=1, memory_mb=512))
    assert outcome.kind == "wall_limit", outcome


def test_limits_cannot_be_raised(robot):
    code = ("import resource\n"
            "resource.setrlimit(resource.RLIMIT_CPU, (resource.RLIM_INFINITY,) * 2)\n")
    outcome = run_raw(code, robot)
    assert outcome.kind == "exception" and "line 2" in outcome.error


def test_garbage_on_the_pipe_is_a_protocol_error(robot):
    code = ("import os\nfor fd in range(3, 10):\n    try:\n"
            "        os.write(fd, b'\\xff' * 8 + b'garbage')\n"
            "    except OSError:\n        pass\n"
            "while True:\n    pass\n")
    outcome = run_raw(code, robot)
    assert outcome.kind == "protocol_error" and "protocol" in outcome.error


def test_a_forged_call_of_an_unknown_function_is_a_protocol_error(robot):
    code = ("import json, os\n"
            "body = json.dumps({'t': 'call', 'name': 'system', 'args': ['id'], 'kwargs': {}})\n"
            "frame = len(body).to_bytes(4, 'big') + body.encode()\n"
            "for fd in range(3, 10):\n    try:\n        os.write(fd, frame)\n"
            "    except OSError:\n        pass\n"
            "while True:\n    pass\n")
    outcome = run_raw(code, robot)
    assert outcome.kind == "protocol_error" and "'system'" in outcome.error


def test_stderr_floods_and_early_exit(robot):
    outcome = run_raw("import os\nfor _ in range(50):\n    os.write(2, b'e' * 100000)\n"
                      "    os.write(1, b'o' * 100000)\n"
                      "print('still talking')\n", robot)
    assert outcome.ok and outcome.stdout == "still talking\n"
    outcome = run_raw("import os\nos._exit(3)\n", robot)
    assert outcome.kind == "crashed" and "status 3" in outcome.error


def test_no_credentials_and_no_project_code_in_the_child(robot, monkeypatch):
    monkeypatch.setenv("FAKE_API_KEY", "s3cret")
    monkeypatch.setenv("GITHUB_TOKEN", "s3cret")
    code = ("import os, sys\nprint(sorted(os.environ))\n"
            "print([m for m in sys.modules if 'drake' in m])\n")
    outcome = run_raw(code, robot)
    assert outcome.ok, outcome.error
    assert "s3cret" not in outcome.stdout and "API_KEY" not in outcome.stdout
    assert "TOKEN" not in outcome.stdout
    assert outcome.stdout.splitlines()[1] == "[]"


def test_the_private_folder_is_deleted(robot, tmp_path, monkeypatch):
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr(tempfile, "tempdir", None)
    assert run("print(1)\n", robot).ok
    assert list(tmp_path.iterdir()) == []


LOCKDOWN_PROBE = Path(__file__).with_name("lockdown_probe.py")


def _probe_lockdown_as_ordinary_user(layer: str) -> str:
    """Runs lockdown_probe.py in a fresh interpreter: it becomes an ordinary user, builds one
    layer of the wall only, then tries to fork and to signal this (the parent) process.
    Returns its report."""
    done = subprocess.run([sys.executable, str(LOCKDOWN_PROBE), layer, str(os.getpid())],
                          capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0, f"the probe broke ({done.returncode}): {done.stderr[-2000:]}"
    return done.stdout.strip()


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to become an ordinary user")
@pytest.mark.parametrize("layer", ["namespaces+rlimits", "seccomp"])
def test_each_layer_alone_stops_forks_and_signals_for_an_ordinary_user(layer):
    """The runner drops root itself; this checks the path ordinary users take, one layer of
    the wall at a time (each should hold without the other)."""
    report = _probe_lockdown_as_ordinary_user(layer)
    if layer == "seccomp" and "seccomp=False" in report:
        pytest.skip("seccomp filters are not available here")
    if layer != "seccomp" and "pid_ns" not in report:
        pytest.skip(f"the kernel allowed only these namespaces: {report.split()[0]!r}")
    assert "fork:allowed" not in report and "signal:allowed" not in report, report


def test_benign_code_still_runs_after_the_hostile_ones(robot):
    outcome = run("p = get_object_pose('cube')\ngoto_pose(p + np.array([0, 0, 0.1]))\n"
                  "print('ok')\n", robot)
    assert outcome.ok and outcome.stdout == "ok\n"
    assert robot.safe and np.allclose(robot.position, [0.3, 0.1, 0.15])


# -- the protocol --------------------------------------------------------------------------


def test_protocol_round_trip_and_array_conversion():
    message = {"t": "return", "value": protocol.to_wire(
        {"pose": np.array([[1.0, 0.0], [0.0, 1.0]]), "n": np.int64(3), "nan": float("nan"),
         "names": ("a", "b"), "flag": np.bool_(True)})}
    buffer = bytearray(protocol.pack(message))
    decoded = protocol.unpack_from(buffer)
    assert buffer == bytearray()
    value = protocol.from_wire(decoded["value"])
    assert isinstance(value["pose"], np.ndarray) and value["pose"].shape == (2, 2)
    assert value["n"] == 3 and np.isnan(value["nan"]) and value["names"] == ["a", "b"]
    assert value["flag"] is True
    assert protocol.from_wire([1, 2, 3]).dtype == float
    assert protocol.from_wire([True, False]) == [True, False]
    assert protocol.from_wire([]) == []


def test_protocol_rejects_oversized_and_malformed_frames():
    oversized = bytearray((protocol.MAX_MESSAGE_BYTES + 1).to_bytes(4, "big"))
    with pytest.raises(protocol.ProtocolError, match="limit"):
        protocol.unpack_from(oversized)
    for body in (b"not json", b"[1, 2]", b'{"no_type": 1}', b"[" * 100_000):
        with pytest.raises(protocol.ProtocolError):
            protocol.unpack_from(bytearray(len(body).to_bytes(4, "big") + body))
    assert protocol.unpack_from(bytearray(b"\x00\x00")) is None
    with pytest.raises(TypeError):
        protocol.to_wire(object())
    with pytest.raises(protocol.ProtocolError):
        protocol.pack({"t": "out", "text": "x" * (protocol.MAX_MESSAGE_BYTES + 1)})


def test_limits_are_validated():
    with pytest.raises(ValueError):
        SandboxLimits(cpu_s=0)
    with pytest.raises(ValueError):
        SandboxLimits(max_output_chars=10**7)
    with pytest.raises(ValueError):
        run_sandboxed("pass", {"_hidden": print})



# -- the parent trusts nothing that crosses the boundary ------------------------------------


def test_values_smuggled_past_the_childs_checks_are_refused_by_the_parent(robot):
    """An ndarray subclass overriding tolist() sends whatever it likes: the parent refuses
    each such call with a clear error the code can catch, and the robot never sees it."""
    code = (
        "class Sneaky(np.ndarray):\n"
        "    def tolist(self):\n"
        "        return PAYLOADS[int(self[0])]\n"
        "deep = 0\n"
        "for _ in range(30):\n"
        "    deep = [deep]\n"
        "PAYLOADS = [['red can'], 'x' * 500000, 'a\\nb', deep]\n"
        "for i in range(4):\n"
        "    try:\n"
        "        get_mass([0.3, 0.0, 0.05], np.array([i, 0.0]).view(Sneaky))\n"
        "    except TypeError as error:\n"
        "        print('TypeError', error)\n"
        "    except ValueError as error:\n"
        "        print('ValueError', error)\n"
        "print(get_mass([0.3, 0.0, 0.05], 'red can'))\n"
    )
    outcome = run(code, robot)
    assert outcome.ok, outcome.error
    lines = outcome.stdout.splitlines()
    assert lines[0] == "TypeError get_mass(): name must be a string, got a list of 1 items"
    assert lines[1] == ("ValueError get_mass(): name may be at most 120 characters long, "
                        "got 500000")
    assert lines[2] == ("ValueError get_mass(): name must be one line of printable text (no "
                        "line breaks or control characters)")
    assert lines[3] == "TypeError get_mass(): name must be a string, got a list of 1 items"
    assert lines[4] == "0.35"
    assert robot.calls == [("get_mass", (pytest.approx([0.3, 0.0, 0.05]), "red can"))]
    assert [summary[:8] for _, summary in outcome.api_calls] == ["refused:"] * 4 + ["[0.3, 0."]


FORGED_DONE = [
    ({"t": "done", "error": {"type": "ValueError", "message": "x" * 100_000, "line": 1,
                             "memory": False}, "truncated": False}, "100000 characters long"),
    ({"t": "done", "error": None, "truncated": False, "kind": "ok"}, "keys"),
    ({"t": "done", "error": {"type": "Bad Name", "message": "", "line": None,
                             "memory": False}, "truncated": False}, "class name"),
]


@pytest.mark.parametrize(("message", "fragment"), FORGED_DONE,
                         ids=["huge message", "unknown key", "bad class name"])
def test_a_forged_outcome_is_a_protocol_error(robot, message, fragment):
    code = ("import json, os\n"
            f"body = json.dumps({message!r}).encode()\n"
            "frame = len(body).to_bytes(4, 'big') + body\n"
            "for fd in range(3, 10):\n    try:\n        os.write(fd, frame)\n"
            "    except OSError:\n        pass\n"
            "while True:\n    pass\n")
    outcome = run_raw(code, robot)
    assert outcome.kind == "protocol_error" and fragment in outcome.error
    assert len(outcome.error) < 500


def test_sysv_ipc_and_other_unmetered_kernel_memory_are_denied(robot):
    """RLIMIT_AS does not count SysV shared memory, message queues, semaphores, memfd or
    pipe buffers: the syscall filter refuses them all (EPERM) whatever the code does."""
    code = (
        "import ctypes, os\n"
        "libc = ctypes.CDLL(None, use_errno=True)\n"
        "def attempt(name, call):\n"
        "    ctypes.set_errno(0)\n"
        "    try:\n"
        "        result = call()\n"
        "    except OSError as error:\n"
        "        return f'{name}:{error.errno}'\n"
        "    return f'{name}:{result}:{ctypes.get_errno()}'\n"
        "IPC_CREAT = 0o1000\n"
        "print(attempt('shmget', lambda: libc.shmget(0, 1 << 30, IPC_CREAT | 0o600)),\n"
        "      attempt('msgget', lambda: libc.msgget(0, IPC_CREAT | 0o600)),\n"
        "      attempt('semget', lambda: libc.semget(0, 1, IPC_CREAT | 0o600)),\n"
        "      attempt('memfd', lambda: os.memfd_create('x')),\n"
        "      attempt('pipe', os.pipe),\n"
        "      attempt('mlock', lambda: libc.mlockall(3)),\n"
        "      attempt('getcwd', os.getcwd),\n"
        "      attempt('unknown', lambda: libc.syscall(1000)))\n"
    )
    outcome = run_raw(code, robot)
    assert outcome.ok, outcome.error
    assert "seccomp" in outcome.isolation
    # errno 1 is EPERM; harmless but unlisted calls (getcwd) and calls no kernel knows yet
    # (which would fail with ENOSYS) are refused the same way: the list fails closed
    assert outcome.stdout.split() == ["shmget:-1:1", "msgget:-1:1", "semget:-1:1", "memfd:1",
                                      "pipe:1", "mlock:-1:1", "getcwd:1", "unknown:-1:1"]


def test_the_allow_list_names_real_system_calls_on_x86_64_and_aarch64():
    """libseccomp resolves each name per architecture; a misspelt name would silently allow
    nothing. aarch64 has no time() (its C library uses clock_gettime)."""
    import pyseccomp

    for arch, missing in ((pyseccomp.Arch.X86_64, set()), (pyseccomp.Arch.AARCH64, {"time"})):
        unknown = {name for name in (*seccomp.ALLOWED, seccomp.READ_ONLY_PRLIMIT)
                   if pyseccomp.resolve_syscall(arch, name) < 0}
        assert unknown == missing, arch
    assert not {"shmget", "shmat", "msgget", "semget", "memfd_create", "pipe2", "socket",
                "clone", "openat", "ioctl"} & set(seccomp.ALLOWED)


def test_a_fatal_api_error_stops_the_code_at_once(robot):
    code = ("print('moving')\n"
            "try:\n"
            "    fail_arm()\n"
            "except BaseException as error:\n"
            "    print('caught', error)\n"
            "goto_pose([0.3, 0.1, 0.2])\n")
    outcome = run_sandboxed(code, robot.api(), LIMITS, fatal=(FakeArmFault,))
    assert outcome.kind == "fault" and not outcome.ok
    assert outcome.error == ("fail_arm() failed with FakeArmFault: the arm reports: collision; "
                             "the code was stopped at once")
    assert outcome.stdout == "moving\n"
    assert [name for name, _ in robot.calls] == ["fail_arm"]


def test_robot_time_runs_out_inside_a_block(robot):
    code = "for i in range(100):\n    get_object_pose('cube')\n    goto_pose([0.3, 0.1, 0.2])\n"
    outcome = run_sandboxed(code, robot.api(), LIMITS, meters=robot.meters(),
                            robot_time_s=25.0)
    assert outcome.kind == "robot_time_limit"
    assert "used 30.0 s of robot time (at most 25.0 s for this block)" in outcome.error
    assert [name for name, _ in robot.calls].count("goto_pose") == 3
    assert robot.calls[-1][0] == "get_object_pose"  # looking is not moving: still allowed


def test_a_knowledge_flood_is_stopped(robot):
    limits = SandboxLimits(cpu_s=2, compute_wall_s=2, memory_mb=512, knowledge_chars=500)
    code = "for i in range(100):\n    get_mass([0.3, 0.0, 0.05], f'can {i} ' + 'x' * 100)\n"
    outcome = run_sandboxed(code, robot.api(), limits, meters=robot.meters())
    assert outcome.kind == "knowledge_limit"
    assert "at most 500 per block" in outcome.error
    assert len(robot.knowledge) == 5 and sum(len(e) for e in robot.knowledge) < 500 + 130


def test_the_parents_own_oversized_replies_are_its_errors(robot):
    code = ("try:\n    huge_result()\nexcept RuntimeError as error:\n    print(error)\n"
            "try:\n    loud_refusal()\nexcept SkillRefused as error:\n"
            "    print(len(str(error)), str(error)[-30:])\n")
    outcome = run(code, robot)
    assert outcome.ok, outcome.error
    first, second = outcome.stdout.splitlines()
    assert first.startswith("huge_result() returned a value the sandbox cannot hand to the "
                            "code: message of")
    assert 1900 < int(second.split()[0]) <= 2000 and second.endswith("characters cut]")


def test_any_code_the_static_check_accepts_fits_in_the_start_message(robot):
    code = "# " + "\U0001F600" * 99_000 + "\nprint('ran')\n"  # 1.2 MB as escaped JSON
    outcome = run(code, robot)
    assert outcome.ok and outcome.stdout == "ran\n", outcome.error
