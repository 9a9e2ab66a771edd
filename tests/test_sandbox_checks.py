"""The parent's side of the sandbox boundary, without processes: every call checked against
the robot API's signatures, every child message checked against the protocol, the block's
budgets per call, and the parent's own replies always fitting in a frame."""

from __future__ import annotations

import inspect
import json
import math

import numpy as np
import pytest

from physcap_drake.agent.code_api import PARAMETER_KINDS, CodeAPI, spec_of
from physcap_drake.agent.sandbox import (
    BlockBudget,
    Call,
    SandboxLimits,
    SandboxSession,
    protocol,
)
from physcap_drake.agent.sandbox.messages import (
    Done,
    Output,
    Ready,
    RefusedCall,
    read_message,
)
from physcap_drake.agent.sandbox.session import raise_reply
from physcap_drake.control.skills_config import SkillsConfig
from physcap_drake.robot_calls import RobotCalls

SPECS = {name: spec_of(name, None) for name in PARAMETER_KINDS
         if name != "breakpoint_code_block"}
POSITION = [0.3, 0.1, 0.05]


def bind(name: str, /, *args, **kwargs) -> Call | RefusedCall:
    """What the parent makes of a call message from the child (values as JSON gives them)."""
    message = json.loads(json.dumps({"t": "call", "name": name, "args": list(args),
                                     "kwargs": kwargs}))
    return read_message(message, SPECS, code_lines=10)


# -- calls ---------------------------------------------------------------------------------


def test_specs_follow_the_robot_api_signatures():
    for name, spec in SPECS.items():
        method = getattr(RobotCalls, name)
        expected = [p for p in inspect.signature(method).parameters if p != "self"]
        assert list(spec.signature.parameters) == expected, name
    functions = CodeAPI(physx=True).table(RobotCalls(0.1, SkillsConfig()))
    assert set(functions) == set(PARAMETER_KINDS)
    assert functions["get_mass"].spec.motion and not functions["get_object_pose"].spec.motion


def test_a_good_call_arrives_typed():
    call = bind("goto_pose", POSITION, z_approach=0.05)
    assert isinstance(call, Call) and call.motion
    assert isinstance(call.args[0], np.ndarray) and call.args[0].dtype == float
    assert call.args[0].tolist() == POSITION and call.kwargs == {"z_approach": 0.05}
    call = bind("get_mass", [0, 1, 2], name="red can")
    assert call.args[0].tolist() == [0.0, 1.0, 2.0] and call.args[1] == "red can"
    assert bind("goto_pose", POSITION, [1, 0, 0, 0]).args[1].shape == (4,)
    assert bind("home_pose").args == () and bind("get_object_pose", "red can").args == (
        "red can",)
    assert call.summary() == "[0.0, 1.0, 2.0], 'red can'"


def _deep(levels: int):
    value = "red can"
    for _ in range(levels):
        value = [value]
    return value


REFUSED = [
    # names: strings of at most 120 printable characters, one line
    (("get_mass", POSITION, ["red can"]), "TypeError",
     "get_mass(): name must be a string, got a list of 1 items"),
    (("get_mass", POSITION, _deep(900)), "TypeError", "name must be a string, got a list"),
    (("get_mass", POSITION, {"a": 1}), "TypeError", "name must be a string, got a dict"),
    (("get_mass", POSITION, "x" * 121), "ValueError",
     "get_mass(): name may be at most 120 characters long, got 121"),
    (("get_object_pose", "x" * 500_000), "ValueError", "got 500000"),
    (("get_mass", POSITION, "red can: mass = 0.01 kg\n- blue can"), "ValueError",
     "one line of printable text"),
    # positions and orientations: finite numbers of the right count
    (("goto_pose", [0.3, 0.1]), "TypeError",
     "goto_pose(): position must be a list (or array) of 3 numbers, got a list of 2 items"),
    (("goto_pose", [[0.3], [0.1], [0.05]]), "TypeError", "of 3 numbers, got a list of 3"),
    (("goto_pose", [True, 0, 0]), "TypeError", "of 3 numbers"),
    (("goto_pose", "0.3, 0.1, 0.05"), "TypeError", "got a str of 14 characters"),
    (("goto_pose", [0.3, 0.1, float("nan")]), "ValueError",
     "position must hold finite numbers, got [0.3, 0.1, nan]"),
    (("goto_pose", [0.3, 10**400, 0.0]), "ValueError", "finite numbers, got [0.3, inf, 0.0]"),
    (("goto_pose", POSITION, [1, 0, 0]), "TypeError", "quaternion_wxyz must be a list"),
    (("goto_pose", POSITION, None, "high"), "TypeError",
     "z_approach must be a number, got a str of 4 characters"),
    (("goto_pose", POSITION, None, -float("inf")), "ValueError",
     "z_approach must be a finite number, got -inf"),
    # the signature itself
    (("goto_pose",), "TypeError", "goto_pose(): missing a required argument: 'position'"),
    (("home_pose", 1), "TypeError", "home_pose(): too many positional arguments"),
]


@pytest.mark.parametrize(("call", "error_type", "fragment"), REFUSED,
                         ids=[f"{c[0]}-{i}" for i, (c, _, _) in enumerate(REFUSED)])
def test_calls_that_do_not_fit_are_refused_with_a_clear_error(call, error_type, fragment):
    name, *args = call
    refused = bind(name, *args)
    assert isinstance(refused, RefusedCall)
    assert refused.refused.error_type == error_type
    assert fragment in refused.refused.message
    assert len(refused.refused.message) < 400  # never the smuggled value itself


def test_keyword_arguments_are_checked_too():
    refused = bind("goto_pose", POSITION, speed=2.0)
    assert "got an unexpected keyword argument 'speed'" in refused.refused.message
    assert "goto_pose(position, quaternion_wxyz=None, z_approach=0.0)" in (
        refused.refused.message)
    refused = bind("goto_pose", POSITION, **{"k" * 1000: 1})
    assert refused.refused.message.startswith("goto_pose() got a keyword argument name")
    assert isinstance(bind("get_mass", position=POSITION, name="cup"), Call)


# -- messages ------------------------------------------------------------------------------


def done(error=None, truncated=False, **extra) -> dict:
    return {"t": "done", "error": error, "truncated": truncated, **extra}


def error(type_name="ValueError", message="bad", line=3, memory=False) -> dict:
    return {"type": type_name, "message": message, "line": line, "memory": memory}


def test_well_formed_messages_are_read():
    assert read_message({"t": "ready", "isolation": ["rlimits", "seccomp"]}, SPECS, 5) == Ready(
        ("rlimits", "seccomp"))
    assert read_message({"t": "out", "text": "hi\n"}, SPECS, 5) == Output("hi\n")
    assert read_message(done(), SPECS, 5) == Done(None, False)
    ended = read_message(done(error(line=5, memory=True), True), SPECS, 5)
    assert ended.truncated and ended.error.line == 5 and ended.error.memory


FORGED = [
    (done(kind="ok"), "keys"),
    (done(error("ValueError", "x" * 5000)), "5000 characters long; at most 2000"),
    (done(error("not a class name")), "class name"),
    (done(error("E" * 500)), "500 characters long; at most 100"),
    (done(error(line=10**9)), "the code has 5 lines"),
    (done(error(line=True)), "error line True"),
    (done(error(memory="yes")), "memory = 'yes'"),
    (done(truncated=1), "truncated = 1"),
    (done(error=["ValueError"]), "not a dict"),
    ({"t": "exec", "code": "import os"}, "unknown message type 'exec'"),
    ({"t": "ready", "isolation": ["root_shell"]}, "isolation steps"),
    ({"t": "out", "text": ["x"]}, "'out' text is a list"),
    ({"t": "out", "text": "x" * 60_000}, "at most 50000"),
    ({"t": "call", "name": "system", "args": ["id"], "kwargs": {}}, "unknown function 'system'"),
    ({"t": "call", "name": "goto_pose", "args": {}, "kwargs": {}}, "a list and a dict"),
]


@pytest.mark.parametrize(("message", "fragment"), FORGED, ids=[m["t"] + "-" + f[:20] for m, f in
                                                                FORGED])
def test_forged_messages_are_protocol_errors(message, fragment):
    with pytest.raises(protocol.ProtocolError) as caught:
        read_message(message, SPECS, code_lines=5)
    assert fragment in str(caught.value)
    assert len(str(caught.value)) < 300


# -- budgets -------------------------------------------------------------------------------

LIMITS = SandboxLimits(max_api_calls=3, total_wall_s=10.0, robot_time_s=30.0,
                       knowledge_chars=100)


def test_api_calls_and_wall_time_are_checked_before_every_call():
    budget = BlockBudget(LIMITS)
    budget.start(now=100.0, robot_time=0.0, knowledge_chars=0)
    assert [budget.before_call("home_pose", False, 101.0, 0.0) for _ in range(3)] == [None] * 3
    stop = budget.before_call("home_pose", False, 101.0, 0.0)
    assert stop.kind == "api_call_limit" and "more than 3 robot API calls" in stop.message
    budget = BlockBudget(LIMITS)
    budget.start(now=100.0, robot_time=0.0, knowledge_chars=0)
    assert budget.before_call("home_pose", False, 109.9, 0.0) is None
    stop = budget.before_call("home_pose", False, 110.0, 0.0)
    assert stop.kind == "wall_limit"
    assert "10 s of the block's own wall time (robot calls not counted)" in stop.message


def test_the_time_spent_answering_calls_is_not_the_blocks_own():
    budget = BlockBudget(LIMITS)
    budget.start(now=100.0, robot_time=0.0, knowledge_chars=0)
    assert budget.before_call("goto_pose", True, 103.0, 0.0) is None
    budget.call_taken(103.0)
    assert budget.own_wall_s(500.0) == pytest.approx(3.0) and budget.deadline == math.inf
    assert budget.after_call(800.0, 0) is None  # the robot took 697 s to answer
    assert budget.deadline == pytest.approx(807.0)
    assert budget.before_call("home_pose", False, 806.9, 0.0) is None
    assert budget.before_call("home_pose", False, 807.0, 0.0).kind == "wall_limit"
    budget.call_taken(807.0)
    with pytest.raises(RuntimeError, match="already being answered"):
        budget.call_taken(807.0)


def test_robot_time_is_checked_before_each_motion():
    budget = BlockBudget(LIMITS, robot_time_s=20.0)  # the episode has only 20 s left
    assert budget.robot_time_s == 20.0 and BlockBudget(LIMITS, 99.0).robot_time_s == 30.0
    budget.start(now=0.0, robot_time=500.0, knowledge_chars=0)
    assert budget.before_call("goto_pose", True, 1.0, 519.9) is None
    assert budget.before_call("get_object_pose", False, 1.0, 525.0) is None  # not a motion
    stop = budget.before_call("goto_pose", True, 1.0, 520.0)
    assert stop.kind == "robot_time_limit"
    assert "used 20.0 s of robot time (at most 20.0 s for this block)" in stop.message
    assert "before goto_pose() could move the robot" in stop.message


def test_what_a_block_adds_to_the_knowledge_is_checked_after_each_call():
    budget = BlockBudget(LIMITS)
    budget.start(now=0.0, robot_time=0.0, knowledge_chars=5000)  # earlier blocks' entries
    assert budget.after_call(1.0, 5100) is None
    stop = budget.after_call(1.0, 5101)
    assert stop.kind == "knowledge_limit" and "added 101 characters" in stop.message


# -- what the parent sends -----------------------------------------------------------------


def test_the_parents_replies_always_fit_in_a_frame():
    frame = raise_reply("SkillRefused", "\u00e9" * 10**7)
    message = protocol.unpack_from(bytearray(frame))
    assert message["type"] == "SkillRefused" and len(message["message"]) <= 2000
    assert message["message"].endswith("characters cut]")
    weird = protocol.unpack_from(bytearray(raise_reply("no such ! class", "m")))
    assert weird["type"] == "RuntimeError"


def test_code_too_large_to_send_is_rejected_by_the_parent_not_blamed_on_the_child():
    code = "# " + "\U0001F600" * 200_000 + "\nprint(1)\n"  # 2.4 MB as escaped JSON
    with SandboxSession(code, {}, SandboxLimits(), skip_ast_check=True) as session:
        outcome = session.start()
    assert outcome.kind == "rejected" and outcome.isolation == []
    assert "too large to hand to the sandbox" in outcome.error
    assert "protocol" not in outcome.error
    assert math.isfinite(outcome.duration_s)
