"""No test checks a module against its own constant (issue 46).

A test that builds its expected value from the constant it checks cannot fail when that
constant is wrong: a 10x unit slip cancels out. This scans every test file for numeric
UPPER_CASE constants imported from physcap_drake that appear inside a check (an `assert`,
an `assert_*(...)` call or `pytest.approx(...)`), directly or through a local name assigned
from one. Each must be listed below with why it is not the thing checked; expected values
otherwise are literals from the spec and docs. Values built in helpers or at module level are
not traced (docs/mutation_testing.md).
"""

from __future__ import annotations

import ast
import importlib
import numbers
import re
from pathlib import Path

import numpy as np

TESTS = Path(__file__).resolve().parent
CONSTANT = re.compile(r"^_?[A-Z][A-Z0-9_]*$")
CODEC_IDS = ("a CAN frame identifier or status bit used to pick frames; its value is pinned "
             "against the vendor's SDK in test_can_codec_sdk.py")
PERIOD_GRID = ("the executor's event grid as a tolerance or in a fake robot's timing, in a "
               "test of another system; test_skill_executor.py pins 12 ms")

#: "file:module.NAME" (or "*:module.NAME" for every file) -> why it is not the thing checked.
ALLOWED = {
    **{f"*:physcap_drake.can.codec.{name}": CODEC_IDS for name in (
        "ARM_STATUS", "COLLISION_TRIPPED", "CRASH_PROTECTION_SETTING", "END_POSE_FEEDBACK",
        "FIRMWARE", "GRIPPER_COMMAND", "GRIPPER_DISABLE", "GRIPPER_PARAMETERS", "JOINT_COMMAND",
        "JOINT_END_MOTION", "JOINT_FEEDBACK", "MIT_COMMAND", "MODE_CONTROL", "MOTION_CONTROL",
        "MOTOR_ENABLE")},
    "*:physcap_drake.station.ports.NUM_ARM_JOINTS": "a dimension: the PiPER's six joints",
    "test_can_codec_sdk.py:physcap_drake.can.codec.MILLIDEGREE":
        "checked against a literal: 180 000 millidegrees are pi",
    "test_skill_executor.py:physcap_drake.control.skill_executor.STALL_MOTION":
        "checked against a literal: 1 mm/s",
    "test_skill_executor.py:physcap_drake.control.skill_executor.STALL_WINDOW":
        "checked against a literal: 1 mm/s",
    "test_skill_executor.py:physcap_drake.control.skill_executor.MONITOR_PERIOD":
        "a tolerance of one event on a start time; the first event is pinned as 0.024 s",
    "test_mass_probe.py:physcap_drake.control.skill_executor.MONITOR_PERIOD": PERIOD_GRID,
    "test_robot_stack.py:physcap_drake.control.skill_executor.MONITOR_PERIOD": PERIOD_GRID,
    "test_skills.py:physcap_drake.control.skill_executor.MONITOR_PERIOD": PERIOD_GRID,
    "test_piper_model.py:physcap_drake.kinematics.piper_dh.JOINT_LOWER":
        "checked against the vendor's limits, written out in the test",
    "test_piper_model.py:physcap_drake.kinematics.piper_dh.JOINT_UPPER":
        "checked against the vendor's limits, written out in the test",
    "test_piper_model.py:physcap_drake.kinematics.piper_dh.HOME_Q":
        "checked against a literal: six zeros",
    "test_piper_model.py:physcap_drake.kinematics.piper_dh.TCP_OFFSET":
        "checked against a literal: 0.1358 m",
    "test_render_camera.py:physcap_drake.station.render_world.IDLE_WORLDS":
        "checked against a literal: 2",
    "test_station_ports.py:physcap_drake.station.ports.VECTOR_INPUTS":
        "checked against the port table written out in the test",
    "test_station_ports.py:physcap_drake.station.ports.VECTOR_OUTPUTS":
        "checked against the port table written out in the test",
    "test_hand_eye.py:physcap_drake.perception.hand_eye_calibration.POSES":
        "the inputs: the fit must use every pose given",
    "test_prompt_contract.py:physcap_drake.agent.code_api.EXPLORATIONS_ROBOT_S":
        "the prompt is checked against the code: it must list every exploration",
    "test_hidden_state.py:physcap_drake.station.ports.VECTOR_OUTPUTS":
        "the names of the real arm's outputs, against which sim-only names are checked",
    "test_demo.py:physcap_drake.commands.agent_demo.DEMO_SEED": "an input: the demo's seed",
    "test_mass_estimator.py:physcap_drake.app.calibration.MASS_GRASP_HEIGHT":
        "an input: where the block is grasped",
    "test_can_station.py:physcap_drake.station.can_session.TRIP_MARGIN":
        "the test recomputes the session's own sorting of trips on a real-time run; which "
        "silences fall in the margin varies from run to run, so a literal would make it flaky",
    "test_placing_skills.py:physcap_drake.tasks.placement.TRAY_FLOOR":
        "an argument to the judge; the floor band is pinned by literals in "
        "test_placement_boundaries.py",
}


def _numeric(value) -> bool:
    if isinstance(value, bool):
        return False
    if isinstance(value, numbers.Number):
        return True
    if isinstance(value, np.ndarray):
        return value.dtype.kind in "fiu"
    if isinstance(value, (tuple, list)) and value:
        return all(_numeric(item) for item in value)
    if isinstance(value, dict) and value:
        return all(_numeric(item) for item in value.values())
    return False


def _value(module: str, name: str):
    try:
        owner = importlib.import_module(module)
    except ModuleNotFoundError:  # `from package import module`
        parent, _, child = module.rpartition(".")
        owner = getattr(importlib.import_module(parent), child)
    return getattr(owner, name)


def _imported(tree: ast.Module) -> tuple[dict[str, str], dict[str, str]]:
    """(constant name -> module, module alias -> module) of a test's physcap_drake imports."""
    constants, modules = {}, {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("physcap_drake"):
            for alias in node.names:
                target = constants if CONSTANT.match(alias.name) else modules
                target[alias.asname or alias.name] = (
                    (node.module, alias.name) if target is constants
                    else f"{node.module}.{alias.name}")
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("physcap_drake"):
                    modules[alias.asname or alias.name] = alias.name
    return constants, modules


def _checks(tree: ast.Module):
    """The nodes that check: asserts, assert_*(...) calls and pytest.approx(...)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Assert):
            yield node
        elif isinstance(node, ast.Call):
            called = node.func.attr if isinstance(node.func, ast.Attribute) else \
                getattr(node.func, "id", "")
            if called.startswith("assert") or called == "approx":
                yield node


def _constant_of(node: ast.AST, constants: dict, modules: dict) -> tuple[str, str] | None:
    if isinstance(node, ast.Name) and node.id in constants:
        return constants[node.id]
    if (isinstance(node, ast.Attribute) and CONSTANT.match(node.attr)
            and isinstance(node.value, ast.Name) and node.value.id in modules):
        return modules[node.value.id], node.attr
    return None


def checked_constants(source: str) -> set[str]:
    """"module.NAME" of each numeric constant of physcap_drake used in a check of a test,
    directly or through a local name assigned from it."""
    tree = ast.parse(source)
    constants, modules = _imported(tree)
    derived: dict[str, set[tuple[str, str]]] = {}  # local name -> the constants it holds
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign):
            held = {found for part in ast.walk(node.value)
                    if (found := _constant_of(part, constants, modules))}
            for target in node.targets:
                if isinstance(target, ast.Name) and held:
                    derived.setdefault(target.id, set()).update(held)
    found = set()
    for check in _checks(tree):
        for node in ast.walk(check):
            used = _constant_of(node, constants, modules)
            for module, name in ({used} if used else derived.get(getattr(node, "id", ""), ())):
                if _numeric(_value(module, name)):
                    found.add(f"{module}.{name}")
    return found


def test_no_test_checks_a_module_against_its_own_numeric_constant():
    seen, unexplained = set(), []
    for path in sorted(TESTS.glob("*.py")):
        for constant in checked_constants(path.read_text()):
            key = next((k for k in (f"{path.name}:{constant}", f"*:{constant}")
                        if k in ALLOWED), None)
            if key is None:
                unexplained.append(f"{path.name}: {constant}")
            seen.add(key)
    assert not unexplained, ("write the expected value out (from the spec or docs), or add "
                             f"the use to ALLOWED with its reason: {unexplained}")
    assert not set(ALLOWED) - seen, f"no longer used: {sorted(set(ALLOWED) - seen)}"


def test_the_scan_finds_mirrored_constants_in_checks_only():
    # The first two bugs: expected values built with the codec's scale and the mass
    # estimator's g (here through a local name). Names that are not numbers are not reported.
    source = ("from physcap_drake.can import codec\n"
              "from physcap_drake.physx.mass_estimator import GRAVITY\n"
              "from physcap_drake.station import ports\n"
              "def test():\n"
              "    weight = 0.2 * GRAVITY\n"
              "    assert decode(raw) == pytest.approx(raw * codec.MICROMETRE)\n"
              "    np.testing.assert_allclose(measured, [0.0, 0.0, weight])\n"
              "    assert read(ports.ARM_POSITION_MEASURED) is not None\n")
    assert checked_constants(source) == {"physcap_drake.can.codec.MICROMETRE",
                                         "physcap_drake.physx.mass_estimator.GRAVITY"}
    literal = source.replace("0.2 * GRAVITY", "0.2 * 9.81")
    assert checked_constants(literal) == {"physcap_drake.can.codec.MICROMETRE"}
