"""The emulated firmware's motion planner: each cycle, the joint reference the arm follows.

Plans: a joint move (MOVE J targets, MOVE P after inverse kinematics, going home), a
Cartesian path (MOVE L lines, MOVE C arcs: inverse kinematics every cycle, seeded with the
previous reference) and a replay of recorded samples (drag teach). Speeds are the joint
(0x474) or end-effector (0x479) limits scaled by the speed percentage (0x151); the fast
joint mode (MOVE J with 0xAD) follows targets at the joints' full speed.
"""

from __future__ import annotations

import numpy as np

from physcap_drake.can.joint_profile import step_towards
from physcap_drake.piper_emulator.arm_state import EmulatedArm
from physcap_drake.piper_emulator.end_pose import flange_transform, is_singular, solve_ik
from physcap_drake.piper_emulator.paths import PathTiming, Segment

#: Acceleration of the fast joint mode, rad/s² (the drivers' own, far above 0x475's).
FAST_ACCELERATION = 50.0
#: A Cartesian step needing more than this times the joint speed limit is a singularity.
SINGULAR_SPEED_FACTOR = 1.5
#: arm_status codes the planner reports.
NO_SOLUTION, SINGULARITY = 2, 3


class Planner:
    """Plans for `arm` (see module docstring); `dh_is_offset` selects the firmware's DH
    table. `step(dt)` advances the reference and returns the arm_status a failed plan
    reports (0 when all is well)."""

    def __init__(self, arm: EmulatedArm, dh_is_offset: int = 1):
        self.arm = arm
        self._dh = dh_is_offset
        self._plan: list[PathTiming] | None = None
        self._segments: list[Segment] = []
        self._replay: list[np.ndarray] = []
        #: How fast the streamed target moves (rad/s), from the times its updates were sent.
        self.stream_velocity = np.zeros(6)
        self.paused = False

    # Plans ------------------------------------------------------------------------------

    def hold(self) -> None:
        """Stops where the reference is (a quick stop) and forgets the plan."""
        arm = self.arm
        self._plan, self._replay = None, []
        arm.target = arm.reference.copy()
        arm.reference_speed = np.zeros(6)
        self.stream_velocity = np.zeros(6)

    def stream(self, velocity: np.ndarray) -> None:
        """From now on the reference follows `arm.target`, which moves at `velocity` (rad/s)
        between its updates (MOVE J)."""
        self._plan, self._replay = None, []
        self.stream_velocity = velocity

    def move_to(self, q_goal: np.ndarray) -> None:
        """A point-to-point joint move to q_goal (rad)."""
        self.arm.target = np.asarray(q_goal, dtype=float).copy()
        self.stream_velocity = np.zeros(6)  # a target standing still
        self._plan = None

    def follow(self, segments: list[Segment]) -> None:
        """Moves the flange along `segments` (MOVE L, MOVE C)."""
        end_speeds, scale = self.arm.end_speeds, self._speed_scale()
        self._plan = [PathTiming(s, end_speeds.linear_speed * scale,
                                 end_speeds.angular_speed * scale,
                                 end_speeds.linear_acceleration,
                                 end_speeds.angular_acceleration) for s in segments]
        self._segments = list(segments)

    def replay(self, samples: list[np.ndarray]) -> None:
        """Moves to the first sample, then follows the samples, one per cycle."""
        self.move_to(samples[0])
        self._replay = list(samples[1:])

    @property
    def busy(self) -> bool:
        """Whether a plan is running or the reference has not reached its target."""
        return (self._plan is not None or bool(self._replay)
                or float(np.max(np.abs(self.arm.reference - self.arm.target))) > 1e-6)

    # The cycle ----------------------------------------------------------------------------

    def step(self, dt: float, fast: bool = False) -> int:
        arm = self.arm
        if self.paused:
            arm.reference_speed = np.zeros(6)
            return 0
        if self._plan is not None:
            return self._path_step(dt)
        if self._replay and float(np.max(np.abs(arm.reference - arm.target))) <= 1e-6:
            sample = self._replay.pop(0)  # one sample per cycle: their speed is the step's
            self.stream_velocity = (sample - arm.target) / dt
            arm.target = sample
        v_max = arm.max_speed * (1.0 if fast else self._speed_scale())
        a_max = np.full(6, FAST_ACCELERATION) if fast else arm.max_acceleration
        arm.reference, arm.reference_speed = step_towards(
            arm.reference, arm.reference_speed, arm.target, self.stream_velocity, v_max, a_max,
            dt)
        return 0

    def _path_step(self, dt: float) -> int:
        arm = self.arm
        timing, segment = self._plan[0], self._segments[0]
        s = timing.advance(dt)
        q = solve_ik(segment.pose(s), arm.reference, arm.lower, arm.upper, self._dh,
                     fallback=False)
        if q is None:
            self.hold()
            return NO_SOLUTION
        if (np.any(np.abs(q - arm.reference) > SINGULAR_SPEED_FACTOR * arm.max_speed * dt)
                or is_singular(q, self._dh)):
            self.hold()
            return SINGULARITY
        arm.reference_speed = (q - arm.reference) / dt
        arm.reference, arm.target = q, q.copy()
        if timing.finished:
            self._plan.pop(0)
            self._segments.pop(0)
            if not self._plan:
                self._plan = None
                arm.reference_speed = np.zeros(6)
        return 0

    def _speed_scale(self) -> float:
        """The speed percentage as a fraction (at least 1 %)."""
        return max(self.arm.speed_percent, 1) / 100.0

    def flange(self) -> np.ndarray:
        """The flange's pose at the current reference (4×4)."""
        return flange_transform(self.arm.reference, self._dh)
