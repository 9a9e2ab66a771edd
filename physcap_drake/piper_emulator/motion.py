"""How the emulated arm moves: the interface between the emulated firmware and its motion
backend, and the kinematic backend.

Each firmware cycle hands the backend a MotionCommand (the joint reference its planner
produced, in the joints' physical angles, and the gripper's command) and
gets a MotionReading back. `KinematicMotion` (here) puts the joints exactly on their
reference; `physcap_drake.station.simulated_motion.SimulatedMotion` runs the simulated station.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable

import numpy as np

from physcap_drake.piper_emulator.arm_state import GRIPPER_SPEED, MECHANICAL_LOWER, MECHANICAL_UPPER


@dc.dataclass(frozen=True)
class MotionCommand:
    """reference: joint positions to follow (rad, physical); powered: which joints are
    enabled; gripper: target opening (m), effort limit (N·m), enabled; load: the end load
    setting (0 empty, 1 half, 2 full) the firmware compensates."""

    reference: np.ndarray
    powered: np.ndarray
    gripper_target: float
    gripper_effort_limit: float
    gripper_enabled: bool
    load: int = 0


@dc.dataclass(frozen=True)
class MotionReading:
    """What one step measured: joint positions (rad, physical) and speeds (rad/s), joint
    torques (N·m), the torque beyond what the firmware's model expects (N·m, what collision
    detection watches), gripper opening (m) and motor effort (N·m)."""

    q: np.ndarray
    velocity: np.ndarray
    torque: np.ndarray
    external_torque: np.ndarray
    gripper_opening: float
    gripper_effort: float


class KinematicMotion:
    """Joints sit exactly on their reference, within their mechanical stops; holding torques
    from `gravity_torque(q)` (N·m, e.g. `arm_gravity.ArmGravity()`; default none)."""

    def __init__(self, gravity_torque: Callable[[np.ndarray], np.ndarray] | None = None,
                 q0=None, opening0: float = 0.0):
        self._gravity = gravity_torque or (lambda q: np.zeros(6))
        self._q = np.zeros(6) if q0 is None else np.asarray(q0, dtype=float).copy()
        if self._q.shape != (6,):
            raise ValueError(f"power-up joints: six angles J1..J6, got {self._q.size}")
        for joint in np.flatnonzero((self._q < MECHANICAL_LOWER - 1e-9)
                                    | (self._q > MECHANICAL_UPPER + 1e-9)):
            raise ValueError(f"power-up joints: J{joint + 1} at {np.degrees(self._q[joint]):g}° "
                             f"is past its mechanical stops "
                             f"({np.degrees(MECHANICAL_LOWER[joint]):.0f}° .. "
                             f"{np.degrees(MECHANICAL_UPPER[joint]):.0f}°)")
        self._opening = float(opening0)

    def initial_state(self) -> tuple[np.ndarray, float]:
        """(joint positions rad, gripper opening m) at power-up."""
        return self._q.copy(), self._opening

    def step(self, command: MotionCommand, dt: float) -> MotionReading:
        q = np.clip(np.where(command.powered, command.reference, self._q), MECHANICAL_LOWER,
                    MECHANICAL_UPPER)  # nothing moves a joint past its stop
        velocity = (q - self._q) / dt
        self._q = q
        if command.gripper_enabled:
            gap = command.gripper_target - self._opening
            self._opening += float(np.clip(gap, -GRIPPER_SPEED * dt, GRIPPER_SPEED * dt))
        effort = command.gripper_effort_limit if command.gripper_enabled else 0.0
        return MotionReading(q.copy(), velocity, np.asarray(self._gravity(q), dtype=float),
                             np.zeros(6), self._opening, effort)
