"""Open-loop commands for exercising a station: hold a pose, or sweep all six joints.

Used by `physcap sim` and `physcap bench station`; real controllers (the skill executor)
replace these by connecting to the same station input ports.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from physcap_drake.station import MakeStation, ports

#: Where the sweep turns back, rad (J1..J6): well inside the limits, clear of the table.
SWEEP_FAR_POSE = np.array([0.6, 0.9, -0.9, 0.8, -0.6, 1.0])
#: Time for one home -> far -> home cycle of the sweep, s.
SWEEP_PERIOD = 4.0
#: Widest gripper opening of the sweep, m.
SWEEP_GRIPPER_OPENING = 0.06
#: Squeeze force the demo commands use, N.
DEMO_FORCE_LIMIT = 20.0


def sweep_trajectory(home: np.ndarray, duration: float) -> PiecewisePolynomial:
    """A smooth joint sweep home -> SWEEP_FAR_POSE -> home, repeated for `duration` s.

    q(t) = home + (far − home)·(1 − cos(2πt/T))/2: peak speed π/T·|far − home| (≤ 0.8 rad/s),
    peak acceleration 2π²/T²·|far − home| (≤ 1.2 rad/s²), within the firmware's limits.
    """
    times = np.arange(0.0, duration + 0.02, 0.02)
    blend = 0.5 * (1.0 - np.cos(2.0 * np.pi * times / SWEEP_PERIOD))
    samples = home[:, None] + (SWEEP_FAR_POSE - home)[:, None] * blend[None, :]
    return PiecewisePolynomial.CubicShapePreserving(times, samples, zero_end_point_derivatives=True)


def gripper_sweep_trajectory(duration: float) -> PiecewisePolynomial:
    """The gripper's part of the sweep: open to SWEEP_GRIPPER_OPENING and close, once per
    SWEEP_PERIOD (opening in m)."""
    times = np.arange(0.0, duration + 0.02, 0.02)
    blend = 0.5 * (1.0 - np.cos(2.0 * np.pi * times / SWEEP_PERIOD))
    return PiecewisePolynomial.FirstOrderHold(times, SWEEP_GRIPPER_OPENING * blend[None, :])


def build_commanded_station(scenario, *, meshcat=None, sweep: bool = False,
                            duration: float = 5.0, arm_position=None,
                            gripper_opening: float | None = None,
                            force_limit: float = DEMO_FORCE_LIMIT) -> tuple[Diagram, Diagram]:
    """The station with the arm holding `arm_position` (rad; default: its initial pose) or
    sweeping, and the gripper holding `gripper_opening` (m; default: its initial opening) with
    `force_limit` (N) or sweeping too. Returns (diagram, station)."""
    builder = DiagramBuilder()
    station = builder.AddNamedSystem("station", MakeStation(scenario, meshcat))
    # Over CAN the arm starts where the emulated arm starts (the real arm: put it at home).
    arm_config = getattr(scenario.station, "emulated", scenario.station)
    home = np.asarray(arm_config.initial_arm_position, dtype=float)
    if sweep:
        arm = TrajectorySource(sweep_trajectory(home, duration))
    else:
        arm = ConstantVectorSource(home if arm_position is None else np.asarray(arm_position))
    builder.AddNamedSystem("arm_command", arm)
    builder.Connect(arm.get_output_port(), station.GetInputPort(ports.ARM_POSITION))
    opening = arm_config.initial_gripper_opening if gripper_opening is None else (
        gripper_opening)
    if sweep:
        gripper = TrajectorySource(gripper_sweep_trajectory(duration))
    else:
        gripper = ConstantVectorSource([opening])
    builder.AddNamedSystem("gripper_command", gripper)
    builder.Connect(gripper.get_output_port(), station.GetInputPort(ports.GRIPPER_POSITION))
    force = builder.AddNamedSystem("force_limit_command", ConstantVectorSource([force_limit]))
    builder.Connect(force.get_output_port(), station.GetInputPort(ports.GRIPPER_FORCE_LIMIT))
    return builder.Build(), station
