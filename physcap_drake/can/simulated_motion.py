"""SimulatedMotion: the emulator's arm is the simulated station (MultibodyPlant physics).

The emulator thread feeds the commands that arrived on the bus into the simulated station's
inputs and advances its simulator by one feedback period per cycle, so joint motion, joint
torques and gripper effort come from the same physics as the sim station, with the task's
objects in the scene. The scene is also what an emulated station's camera sees and what the
task's success check reads (ground truth the real arm does not have).
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context

from physcap_drake.can.emulator import EmulatedArm, MotionReading
from physcap_drake.station import ports


class SimulatedMotion:
    """A motion backend for `PiperEmulator` (see module docstring).

    Args:
        scenario: a scenario whose `station` is a `SimPiper` (the scene to simulate).
        gripper_max_effort: the gripper motor effort (N·m) that corresponds to the simulated
            gripper's maximum squeeze force (`station.gripper_servo.max_force`): a commanded
            effort limit e maps to a force limit e / gripper_max_effort · max_force, and the
            normalized effort f̂ is reported as f̂ · gripper_max_effort.
    """

    def __init__(self, scenario, *, gripper_max_effort: float):
        from physcap_drake.station.sim_station import MakeSimStation

        self.station = MakeSimStation(scenario)
        self.plant = self.station.GetSubsystemByName("plant")
        self._max_force = scenario.station.gripper_servo.max_force
        self._max_effort = float(gripper_max_effort)
        self._simulator = Simulator(self.station)
        self._context = self._simulator.get_mutable_context()
        config = scenario.station
        self._fix(np.asarray(config.initial_arm_position, dtype=float),
                  config.initial_gripper_opening, 0.0)
        self._simulator.Initialize()

    @property
    def context(self) -> Context:
        """The simulated station's live context (read it holding the emulator's lock)."""
        return self._context

    @property
    def plant_context(self) -> Context:
        """The plant's part of the live context (read it holding the emulator's lock)."""
        return self.plant.GetMyMutableContextFromRoot(self._context)

    def initial_state(self, arm: EmulatedArm) -> None:
        arm.q = self._output(ports.ARM_POSITION_MEASURED).copy()
        arm.gripper_opening = float(self._output(ports.GRIPPER_POSITION_MEASURED)[0])

    def step(self, arm: EmulatedArm, dt: float) -> MotionReading:
        # Joints that may not move (disabled, or the arm in an error state) hold where they are.
        target = np.where(arm.moving, arm.target, arm.q)
        opening = arm.gripper_target if arm.gripper_enabled else arm.gripper_opening
        effort = arm.gripper_effort if arm.gripper_enabled else 0.0
        force = min(max(effort, 0.0), self._max_effort) / self._max_effort * self._max_force
        self._fix(target, opening, force)
        self._simulator.AdvanceTo(self._context.get_time() + dt)
        arm.q = self._output(ports.ARM_POSITION_MEASURED).copy()
        arm.gripper_opening = float(self._output(ports.GRIPPER_POSITION_MEASURED)[0])
        return MotionReading(
            self._output(ports.ARM_VELOCITY_ESTIMATED).copy(),
            self._output(ports.ARM_TORQUE_MEASURED).copy(),
            float(self._output(ports.GRIPPER_EFFORT_MEASURED)[0]) * self._max_effort)

    def _fix(self, q: np.ndarray, opening: float, force: float) -> None:
        station, context = self.station, self._context
        station.GetInputPort(ports.ARM_POSITION).FixValue(context, q)
        station.GetInputPort(ports.GRIPPER_POSITION).FixValue(context, [opening])
        station.GetInputPort(ports.GRIPPER_FORCE_LIMIT).FixValue(context, [force])

    def _output(self, name: str) -> np.ndarray:
        return self.station.GetOutputPort(name).Eval(self._context)


def simulated_motion(scenario) -> SimulatedMotion:
    """The simulated station of `scenario` as an emulator backend: a PiperCan scenario's
    `emulated` arm with its gripper effort scale, or a SimPiper scenario's arm with the
    default scale."""
    from physcap_drake.station.can_config import PiperCan

    station = scenario.station
    if isinstance(station, PiperCan):
        return SimulatedMotion(dc.replace(scenario, station=station.emulated),
                               gripper_max_effort=station.gripper_max_effort)
    return SimulatedMotion(scenario, gripper_max_effort=PiperCan().gripper_max_effort)
