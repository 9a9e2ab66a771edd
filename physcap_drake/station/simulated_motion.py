"""SimulatedMotion: the emulator's arm is the simulated station (MultibodyPlant physics).

Design notes: docs/design/station.md.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, DiagramBuilder

from physcap_drake.piper_emulator.arm_state import DEFAULT_MAX_SPEED
from physcap_drake.piper_emulator.motion import MotionCommand, MotionReading
from physcap_drake.station import ports
from physcap_drake.station.end_load import EndLoadWeight
from physcap_drake.station.firmware_command import (
    END_LOAD_MASS,
    CommandMailbox,
    FirmwareCommandSource,
)

#: Payload of the end-load settings 0 (empty), 1 (half), 2 (full), kg: the PiPER's rated
#: payload is 1.5 kg.
LOAD_MASS = {0: 0.0, 1: 0.75, 2: 1.5}
#: The simulated joint interpolator's acceleration bound in the emulated world, rad/s²: far
#: above anything the emulated firmware plans, so the interpolator just passes it on.
PASS_THROUGH_ACCELERATION = 1000.0
#: How far past a joint-loop update a period's sub-step ends, s (never on an update).
PAST_UPDATE = 1e-7
#: The fastest the emulated arm's joint reference moves, rad/s (the PiPER's top joint speed).
MAX_JOINT_SPEED = DEFAULT_MAX_SPEED
#: How many non-finite state entries a failed step names.
NAMED_NON_FINITE = 6


class SimulatedMotion:
    """A motion backend for `PiperEmulator` (see the design notes).

    Args:
        scenario: a scenario whose `station` is a `SimPiper` (the scene to simulate); its
            `body_masses` are its plant's model data (see `body_masses`).
        gripper_max_effort: the gripper motor effort (N·m) that corresponds to the simulated
            gripper's maximum squeeze force (`station.gripper_servo.max_force`): a commanded
            effort limit e maps to a force limit e / gripper_max_effort · max_force, and the
            normalized effort f̂ is reported as f̂ · gripper_max_effort.
    """

    def __init__(self, scenario, *, gripper_max_effort: float):
        from physcap_drake.station.sim_station import MakeSimStation

        # The emulated firmware (`piper_emulator.planner`) plans the joint reference; the simulated
        # station's own joint interpolator only has to pass it on. Bounding its acceleration
        # as well would filter the reference a second time (the firmware's 5 ms steps are
        # sampled at the plant's 8 ms), so the world is built with that bound lifted.
        servo = scenario.station.joint_servo
        scenario = dc.replace(scenario, station=dc.replace(
            scenario.station, joint_servo=dc.replace(
                servo, max_acceleration=PASS_THROUGH_ACCELERATION)))
        config = scenario.station
        self._mailbox = CommandMailbox(np.asarray(config.initial_arm_position, dtype=float),
                                       config.initial_gripper_opening, 0.0)
        builder = DiagramBuilder()
        self.station = builder.AddNamedSystem("station", MakeSimStation(
            scenario, external_forces=True))
        self.plant = self.station.GetSubsystemByName("plant")
        command = builder.AddNamedSystem("firmware_command", FirmwareCommandSource(
            self._mailbox))
        for name in ports.VECTOR_INPUTS:
            builder.Connect(command.GetOutputPort(name), self.station.GetInputPort(name))
        end_load = builder.AddNamedSystem("end_load", EndLoadWeight(
            self.plant, self.plant.GetFrameByName("tcp", self.plant.GetModelInstanceByName(
                config.gripper_model))))
        builder.Connect(command.GetOutputPort(END_LOAD_MASS), end_load.get_input_port())
        builder.Connect(end_load.get_output_port(),
                        self.station.GetInputPort(ports.APPLIED_SPATIAL_FORCE))
        world = builder.Build()
        world.set_name("emulated_world")
        self._max_force = config.gripper_servo.max_force
        self._max_effort = float(gripper_max_effort)
        # The hidden masses are the plant's model data (`body_masses`): the world weighs them
        # from its first step on.
        self._simulator = Simulator(world)
        self._context = self._simulator.get_mutable_context()
        self._station_context = self.station.GetMyContextFromRoot(self._context)
        self._feedforward = (self.station.GetSubsystemByName("arm_feedforward")
                             if self.station.HasSubsystemNamed("arm_feedforward") else None)
        self._reference: np.ndarray | None = None  # the last period's joint reference
        self._simulator.Initialize()

    @property
    def context(self) -> Context:
        """The emulated world's live root context (read it holding the emulator's lock)."""
        return self._context

    @property
    def plant_context(self) -> Context:
        """The plant's part of the live context (read it holding the emulator's lock)."""
        return self.plant.GetMyMutableContextFromRoot(self._context)

    def set_world(self, state: np.ndarray) -> None:
        """An operator's move of the world between two steps: every position and velocity
        of the plant (the layout of `plant.GetPositionsAndVelocities`); hold the emulator's
        lock."""
        self.plant.SetPositionsAndVelocities(self.plant_context, state)

    def initial_state(self) -> tuple[np.ndarray, float]:
        return (self._output(ports.ARM_POSITION_MEASURED).copy(),
                float(self._output(ports.GRIPPER_POSITION_MEASURED)[0]))

    def step(self, command: MotionCommand, dt: float) -> MotionReading:
        """Advances the world by dt. The reference is reached at the end of the period and
        moves linearly through it: the simulated joint loop, which updates at the plant's
        own rate, sees it move as smoothly as the firmware's servo loop does."""
        q_now = self._output(ports.ARM_POSITION_MEASURED)
        # Joints that may not move (disabled) hold where they are.
        reference = np.where(command.powered, command.reference, q_now)
        start = self._reference if self._reference is not None else reference
        # A world that fell behind the firmware (see paced_world) gets a reference that
        # moved further than `dt` allows: it catches up at the arm's top joint speed, as the
        # arm's servo would, never in a jump that would fling what the gripper holds.
        reach = MAX_JOINT_SPEED * dt
        reference = start + np.clip(reference - start, -reach, reach)
        opening = command.gripper_target
        effort = command.gripper_effort_limit if command.gripper_enabled else 0.0
        force = min(max(effort, 0.0), self._max_effort) / self._max_effort * self._max_force
        load = LOAD_MASS.get(command.load, 0.0)
        t0 = self._context.get_time()
        period, end = self.plant.time_step(), t0 + dt
        update = (np.floor(t0 / period + 1e-9) + 1.0) * period

        def what() -> str:
            return (f"world step from t = {t0:.4f} s by {dt * 1000:.0f} ms: joints at "
                    f"{np.round(q_now, 4).tolist()}, reference from {np.round(start, 4).tolist()} "
                    f"to {np.round(reference, 4).tolist()}, gripper to {opening:.4f} m at "
                    f"{force:.1f} N")

        try:
            while update <= end + 1e-9:  # the joint loop's updates within this period
                # Fixed before the update and advanced just past it: the update sees this
                # value whichever side of a boundary Drake handles it on.
                fraction = min((update - t0) / dt, 1.0)
                self._mailbox.put(start + fraction * (reference - start), opening, force,
                                  load)
                self._simulator.AdvanceTo(update + PAST_UPDATE)
                update += period
            self._mailbox.put(reference, opening, force, load)
            if self._context.get_time() < end:
                self._simulator.AdvanceTo(end)
        except RuntimeError as error:
            raise RuntimeError(f"{error} [{what()}]") from None
        # A step whose physics left a non-finite state fails here, naming itself and what
        # went non-finite (the next step's geometry query would only see the result).
        state = self.plant.GetPositionsAndVelocities(self.plant_context)
        if not np.isfinite(state).all():
            all_names = self.plant.GetStateNames(False)
            names = [all_names[i] for i in np.flatnonzero(~np.isfinite(state))]
            shown = ", ".join(names[:NAMED_NON_FINITE])
            extra = len(names) - NAMED_NON_FINITE
            more = f" and {extra} more" if extra > 0 else ""
            raise RuntimeError(f"the simulated world's state went non-finite ({shown}{more}) "
                               f"[{what()}]")
        self._reference = reference
        torque = self._output(ports.ARM_TORQUE_MEASURED).copy()
        return MotionReading(
            self._output(ports.ARM_POSITION_MEASURED).copy(),
            self._output(ports.ARM_VELOCITY_ESTIMATED).copy(), torque,
            torque - self._model_torque(),
            float(self._output(ports.GRIPPER_POSITION_MEASURED)[0]),
            float(self._output(ports.GRIPPER_EFFORT_MEASURED)[0]) * self._max_effort)

    # The firmware's model ------------------------------------------------------------------------

    def _model_torque(self) -> np.ndarray:
        """The torques the firmware's model expects (its feed-forward), N·m."""
        if self._feedforward is None:
            return np.zeros(6)
        return self._feedforward.get_output_port().Eval(
            self._feedforward.GetMyContextFromRoot(self._context)).copy()

    # Station I/O -------------------------------------------------------------------------

    def _output(self, name: str) -> np.ndarray:
        return self.station.GetOutputPort(name).Eval(self._station_context)


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
