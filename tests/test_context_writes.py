"""Who writes into a Drake Context from outside a system's own events.

The project's rule: state lives in Contexts and is changed only by the owning system's own
events. A few modules must still write into a context from outside: the clock that owns the
running diagram's simulator, the robot stack's outside-client contract (an exported input
port's value, Drake's way to feed a diagram from outside), initial conditions set on a fresh
context before any simulator holds it, and scratch contexts that one object owns for its own
kinematics or rendering. Each such module is listed here with its reason; any other module
that calls one of WRITES fails this test, naming the file, line and call.

A system's own events change its state through the State Drake hands its update handler
(`state.get_mutable_abstract_state(...)` and the like, STATE_WRITES); those calls are
allowed only there: in a method the class declares as an update handler, on that method's
own parameter (or in a helper only such handlers call).

Like tests/test_layers.py, this reads the source (every call counts, also inside functions).
"""

from __future__ import annotations

import ast
from pathlib import Path

import physcap_drake

ROOT = Path(physcap_drake.__file__).parent

#: Calls that change a context from outside its systems' events: fixing an input port's
#: value, a body's mass parameter, the time, or taking the simulator's (or the clock's)
#: root context, or a subsystem's part of a root context, to write into.
WRITES = frozenset({"FixValue", "SetMass", "get_mutable_context", "SetTime",
                    "mutable_context", "GetMyMutableContextFromRoot",
                    # Posing a plant: a scratch model's positions, or a world's state.
                    "SetPositions", "SetPositionsAndVelocities", "SetFreeBodyPose",
                    "SetFreeBodySpatialVelocity",
                    # A parameter group's values.
                    "get_mutable_numeric_parameter"})

#: file (relative to physcap_drake/) -> {call: why this module may make it}.
ALLOWED = {
    "bench/perception_bench.py": {
        "SetFreeBodyPose": "the perception bench's oracle moves objects in the simulated "
                           "world between two looks (a benchmark, not the robot)",
    },
    "piper_emulator/arm_gravity.py": {
        "SetPositions": "ArmGravity's own scratch context of its own plant (the kinematic "
                        "emulated arm's holding torques), never a running diagram's",
    },
    "clock.py": {
        "get_mutable_context": "the Clock owns the simulator; it hands the root context "
                               "out only for the outside client's exported input",
        "mutable_context": "defines the Clock's door for the outside client's exported input",
    },
    "robot_stack.py": {
        "FixValue": "the outside client's contract: the value of the exported robot.request "
                    "input (RobotStack.put_request), and its initial empty request",
        "mutable_context": "RobotStack.send: the outside client's next request, put on the "
                           "exported input in the clock's root context between two runs",
    },
    "station/simulated_motion.py": {
        "get_mutable_context": "the emulated world owns its simulator (it stands for the "
                               "real world behind the CAN bus)",
        "SetPositionsAndVelocities": ("set_world: an operator placing things in the emulated "
                                      "world, between two steps of its own simulator"),
        "GetMyMutableContextFromRoot": "the emulated world's plant context, in the context "
                                       "its simulator owns: an operator's moves (set_world) "
                                       "between steps",
    },
    "station/can_scene.py": {
        "SetPositionsAndVelocities": ("its private scratch copy of the emulated world, set from "
                                      "the latched state"),
        "GetMyMutableContextFromRoot": "the scene's private scratch copy of the emulated "
                                       "world, set from its own latched state (or, for "
                                       "readers outside the diagram, the published world) "
                                       "before each use",
        "get_mutable_numeric_parameter": "ground_truth: the scratch copy gets the model's "
                                         "parameters back after a block that changed one "
                                         "(which raises: the world's masses cannot change)",
    },
    "station/render_world.py": {
        "GetMyMutableContextFromRoot": "the render world's own context (its private "
                                       "SceneGraph in a diagram of its own), whose geometry "
                                       "it registers and removes as stations lease it",
        "FixValue": ("the render world's frame poses, set from the plant's body poses a "
                     "camera was evaluated with, just before the image is rendered"),
    },
    "control/planning_model.py": {
        "SetPositions": ("the planning model's own scratch contexts (the workcell's, and "
                         "ModelAtPositions' of a robot-only plant, which the mass estimator reads "
                         "its Jacobians and gravity torques from): set in full from the arguments "
                         "of each query"),
        "GetMyMutableContextFromRoot": "the planning model's own scratch contexts (one of "
                                       "them lent to each inverse-kinematics solve in "
                                       "turn, solver_plant_context)",
    },
}


#: Calls that set a model's defaults: what every Context made from the plant later starts
#: from. They write into no Context (none exists while a plant is built), but they decide
#: what a Context holds, so they too are allowed only where a model is built.
DEFAULTS = frozenset({"SetDefaultPositions", "set_default_positions", "set_default_damping",
                      "SetDefaultFloatingBaseBodyPose", "SetDefaultFreeBodyPose",
                      "set_default_translation", "set_default_rotation",
                      "SetDefaultState", "SetDefaultContext", "SetDefaultParameters"})

#: file -> {call: why this module sets a model default}. All of them run while the plant is
#: built, before Finalize, as Drake's own parser sets the defaults a file declares.
ALLOWED_DEFAULTS = {
    "station/directive_loader.py": {
        "set_default_positions": "a directive's default_joint_positions, as Drake's "
                                 "ProcessModelDirectives sets them (also the sim station's "
                                 "initial arm and finger joints, put there by "
                                 "with_joint_positions)",
        "SetDefaultFloatingBaseBodyPose": "a directive's default_free_body_pose (the task "
                                          "layout's placements), as ProcessModelDirectives "
                                          "sets it",
    },
}


#: Calls that change the State a Drake update handler is handed (`state` of an unrestricted
#: or discrete update event): a system changing its own state. Allowed only there.
STATE_WRITES = frozenset({"get_mutable_abstract_state", "get_mutable_discrete_state",
                          "get_mutable_vector", "get_mutable_state", "SetAbstractState"})


def _handlers(cls: ast.ClassDef) -> set[str]:
    """Methods of `cls` it declares as update handlers (`self.Declare...UpdateEvent(...,
    self.<method>)`), and helpers of theirs: methods called only from them."""
    declared = set()
    for node in ast.walk(cls):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr.startswith("Declare")
                and node.func.attr.endswith("UpdateEvent")):
            declared |= {arg.attr for arg in node.args if isinstance(arg, ast.Attribute)
                         and isinstance(arg.value, ast.Name) and arg.value.id == "self"}
    methods = {f.name: f for f in cls.body if isinstance(f, ast.FunctionDef)}
    callers: dict[str, set[str]] = {}
    for name, method in methods.items():
        for node in ast.walk(method):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and isinstance(node.func.value, ast.Name) and node.func.value.id == "self"
                    and node.func.attr in methods):
                callers.setdefault(node.func.attr, set()).add(name)
    helpers = {name for name, by in callers.items() if name not in declared and by <= declared}
    return declared | helpers


def _state_writes_outside_handlers(path: Path) -> list[str]:
    """Each STATE_WRITES call of `path` that is not made, on one of its own parameters, by an
    update handler of its class (or a helper only handlers call), as "line: name"."""
    tree = ast.parse(path.read_text(), filename=str(path))
    allowed: set[int] = set()
    for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)):
        handlers = _handlers(cls)
        for method in cls.body:
            if not isinstance(method, ast.FunctionDef) or method.name not in handlers:
                continue
            params = {a.arg for a in method.args.args[1:]}
            allowed |= {id(node) for node in ast.walk(method)
                        if isinstance(node, ast.Attribute) and node.attr in STATE_WRITES
                        and isinstance(node.value, ast.Name) and node.value.id in params}
    outside = sorted((node.lineno, node.attr) for node in ast.walk(tree)
                     if isinstance(node, ast.Attribute) and node.attr in STATE_WRITES
                     and id(node) not in allowed)
    return [f"{line}: {name}" for line, name in outside]


def _calls(path: Path, names: frozenset[str] = WRITES) -> list[tuple[int, str]]:
    """(line, name) of every call or attribute named in `names` in `path`."""
    tree = ast.parse(path.read_text(), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and node.attr in names:
            found.append((node.lineno, node.attr))
        elif isinstance(node, ast.FunctionDef) and node.name in names:
            found.append((node.lineno, node.name))
    return sorted(found)


def _writes(names: frozenset[str] = WRITES) -> dict[str, list[tuple[int, str]]]:
    writes = {}
    for path in sorted(ROOT.rglob("*.py")):
        calls = _calls(path, names)
        if calls:
            writes[path.relative_to(ROOT).as_posix()] = calls
    return writes


def test_only_the_listed_modules_write_into_a_context_from_outside():
    unexpected = [f"physcap_drake/{file}:{line}: {name}"
                  for file, calls in _writes().items() for line, name in calls
                  if name not in ALLOWED.get(file, {})]
    assert not unexpected, ("these write into a Drake Context from outside a system's own "
                            "events (use an input port, an event of the owning system, or a "
                            "scratch context; or list the file in ALLOWED with its reason):\n"
                            + "\n".join(unexpected))


def test_systems_change_their_state_only_in_their_own_update_events():
    """What the stop hook counts as "reaching into a Context" (a State's mutable parts) is
    allowed only as a system's own event: the State Drake hands one of its update handlers."""
    found = {path.relative_to(ROOT).as_posix(): _state_writes_outside_handlers(path)
             for path in sorted(ROOT.rglob("*.py"))}
    unexpected = [f"physcap_drake/{file}:{where}" for file, lines in found.items()
                  for where in lines]
    assert not unexpected, ("these change a State outside the owning system's update "
                            "handlers:\n" + "\n".join(unexpected))
    owners = {file for file, _ in _writes(STATE_WRITES).items()}
    assert {"control/skill_executor.py", "agent/agent_system.py",
            "station/firmware_command.py"} <= owners  # the check sees the real handlers


def test_the_handler_check_tells_an_event_from_an_outside_write(tmp_path):
    source = tmp_path / "module.py"
    source.write_text(
        "class S:\n"
        "    def __init__(self):\n"
        "        self.DeclarePeriodicUnrestrictedUpdateEvent(0.1, 0.0, self._update)\n"
        "    def _update(self, context, state):\n"
        "        self._set(state, 1)\n"
        "    def _set(self, state, value):\n"
        "        state.get_mutable_abstract_state(0).set_value(value)\n"
        "    def poke(self, state):\n"
        "        state.get_mutable_abstract_state(0).set_value(2)\n"
        "def reach(context):\n"
        "    context.get_mutable_state().SetFrom(None)\n")
    assert _state_writes_outside_handlers(source) == ["9: get_mutable_abstract_state",
                                                      "11: get_mutable_state"]


def test_every_allowance_is_still_needed():
    writes = _writes()
    stale = [f"{file}: {name}" for file, names in ALLOWED.items() for name in names
             if name not in {n for _, n in writes.get(file, [])}]
    assert not stale, f"ALLOWED lists calls these files no longer make: {stale}"


def test_only_the_model_builders_set_model_defaults():
    writes = _writes(DEFAULTS)
    unexpected = [f"physcap_drake/{file}:{line}: {name}"
                  for file, calls in writes.items() for line, name in calls
                  if name not in ALLOWED_DEFAULTS.get(file, {})]
    assert not unexpected, ("these set a model's defaults outside the modules that build "
                            "models (set it where the plant is built, or list the file in "
                            "ALLOWED_DEFAULTS with its reason):\n" + "\n".join(unexpected))
    stale = [f"{file}: {name}" for file, names in ALLOWED_DEFAULTS.items() for name in names
             if name not in {n for _, n in writes.get(file, [])}]
    assert not stale, f"ALLOWED_DEFAULTS lists calls these files no longer make: {stale}"


def test_the_check_sees_calls_inside_functions(tmp_path):
    source = tmp_path / "module.py"
    source.write_text("def f(port, ctx):\n    def g():\n        port.FixValue(ctx, 1)\n"
                      "    ctx.SetTime(2.0)\n    return g\n")
    assert _calls(source) == [(3, "FixValue"), (4, "SetTime")]
    source.write_text("def f(plant, arm, q):\n    plant.SetDefaultPositions(arm, q)\n")
    assert _calls(source, DEFAULTS) == [(2, "SetDefaultPositions")]
