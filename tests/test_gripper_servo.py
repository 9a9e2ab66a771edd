"""The GripperServo (the simulated gripper's firmware loop) through its ports: commands and
finger states fixed on its inputs, force, opening and effort read from its outputs."""

from __future__ import annotations

import pytest
from pydrake.systems.framework import DiagramBuilder

from physcap_drake.clock import Clock
from physcap_drake.station.gripper_servo import GripperServo
from physcap_drake.station.sim_config import GripperServoConfig

STEP = 0.004  # s, the servo's period
TRAVEL = 0.05  # m, each finger's travel
CONFIG = GripperServoConfig()  # k = 2000 N/m, 0.1 m/s of opening, max_force 25 N
MAX_STEP = 0.5 * CONFIG.max_opening_speed * STEP  # m a finger's reference moves per period


class Rig:
    """A GripperServo with its inputs exported (fixed by the test) and the fingers held at
    `finger` m from the centre line, at rest."""

    def __init__(self, opening: float, force_limit: float, finger: float = 0.02):
        builder = DiagramBuilder()
        servo = builder.AddSystem(GripperServo(CONFIG, finger_travel=TRAVEL,
                                               actuator_effort_limit=60.0, period=STEP))
        for name in ("opening_commanded", "force_limit", "finger_state"):
            builder.ExportInput(servo.GetInputPort(name), name)
        for name in ("finger_force", "opening_measured", "effort"):
            builder.ExportOutput(servo.GetOutputPort(name), name)
        self.servo, self.diagram = servo, builder.Build()
        context = self.diagram.CreateDefaultContext()
        for name, value in (("finger_state", [finger, finger, 0.0, 0.0]),
                            ("opening_commanded", [opening]), ("force_limit", [force_limit])):
            self.diagram.GetInputPort(name).FixValue(context, value)
        self.clock = Clock(self.diagram, context=context)  # starts where the fingers are

    def command(self, opening: float) -> None:
        self.diagram.GetInputPort("opening_commanded").FixValue(self.clock.mutable_context,
                                                                [opening])

    def read(self, name: str) -> float:
        return float(self.diagram.GetOutputPort(name).Eval(self.clock.context)[0])


def test_the_reference_moves_at_the_speed_limit_and_the_fingers_are_pushed_towards_it():
    rig = Rig(opening=0.05, force_limit=20.0)  # 10 mm wider than the fingers stand
    assert rig.read("opening_measured") == pytest.approx(0.04)
    assert rig.read("finger_force") == pytest.approx(0.0)  # the reference starts there
    rig.clock.run_for(10 * STEP)  # ten updates: the reference moved 10 · MAX_STEP = 2 mm
    force = CONFIG.stiffness * 10 * MAX_STEP  # per finger, N
    assert rig.read("finger_force") == pytest.approx(2 * force)  # the actuator drives both
    assert rig.read("effort") == pytest.approx(force / CONFIG.max_force)
    rig.clock.run_for(0.2)  # the reference reached the command: 5 mm out from each finger
    assert rig.read("finger_force") == pytest.approx(2 * CONFIG.stiffness * 0.005)


def test_against_an_object_the_fingers_squeeze_with_the_commanded_limit():
    rig = Rig(opening=0.0, force_limit=12.0)  # closing on an object that holds them at 40 mm
    rig.clock.run_for(0.5)
    assert rig.read("finger_force") == pytest.approx(-24.0)
    assert rig.read("effort") == pytest.approx(12.0 / CONFIG.max_force)


def test_the_force_limit_is_capped_at_the_servos_largest_force():
    rig = Rig(opening=0.0, force_limit=40.0)
    rig.clock.run_for(0.5)
    assert rig.read("finger_force") == pytest.approx(-2 * CONFIG.max_force)
    assert rig.read("effort") == pytest.approx(1.0)


def test_after_a_squeeze_reopening_pushes_outwards_without_unwinding_first():
    rig = Rig(opening=0.0, force_limit=12.0)
    rig.clock.run_for(1.0)  # long enough for an unlimited reference to reach 0
    rig.command(0.06)
    # The reference waited at the force limit's band (6 mm inside the fingers), so 31 steps
    # later it is outside them; unwound from 0 it would still be 14 mm inside.
    rig.clock.run_for(31 * STEP)
    assert rig.read("finger_force") > 0.0


def test_the_reported_effort_does_not_follow_the_commands_directly():
    servo = Rig(opening=0.0, force_limit=12.0).servo
    for command in ("opening_commanded", "force_limit"):
        for output in ("effort", "finger_force", "opening_measured"):
            assert not servo.HasDirectFeedthrough(servo.GetInputPort(command).get_index(),
                                                  servo.GetOutputPort(output).get_index())


def test_a_servo_stronger_than_the_finger_actuator_is_refused():
    with pytest.raises(ValueError, match="max_force = 25.0 N per finger needs 50.0 N"):
        GripperServo(CONFIG, finger_travel=TRAVEL, actuator_effort_limit=40.0, period=STEP)
