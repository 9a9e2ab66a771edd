"""MassEstimator: averages joint torques at a measurement pose and turns their change into
the mass of what the gripper holds."""

from __future__ import annotations

import dataclasses as dc
import enum
import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import Context, EventStatus, LeafSystem, State

from physcap_drake.control.planning_model import ModelAtPositions
from physcap_drake.immutable_state import Immutable
from physcap_drake.station import ports
from physcap_drake.weak_method import weak_method

#: Standard gravity, m/s².
GRAVITY = 9.81
#: Largest horizontal offset of the held object's centre of mass from the fingertip point
#: that the estimate accepts, m: anything further is not between the fingers (and is noise).
MAX_GRASP_OFFSET = 0.02
#: The estimator's ports besides the station's signals.
WINDOW_PORT = "window"
ESTIMATE_PORT = "estimate"


def horizontal_load_offset(jacobian_z: np.ndarray, jacobian_wx: np.ndarray,
                           jacobian_wy: np.ndarray, delta_tau: np.ndarray) -> np.ndarray:
    """Where the load hangs relative to a point P, horizontally: (dx, dy) in m, world frame.

    A load at P + d moves vertically with J_z + d_y·J_ωx − d_x·J_ωy (J_ω: the angular velocity
    Jacobian), so Δτ = g·[J_z, J_ωx, −J_ωy]·[m, m·d_y, m·d_x]: linear least squares in
    (m, m·d_y, m·d_x). The result is limited to MAX_GRASP_OFFSET.
    """
    basis = np.column_stack([jacobian_z, jacobian_wx, -jacobian_wy])
    (m, m_dy, m_dx), *_ = np.linalg.lstsq(basis, np.asarray(delta_tau, dtype=float), rcond=None)
    if abs(m) < 1e-9:
        return np.zeros(2)
    offset = np.array([m_dx, m_dy]) / m
    norm = np.linalg.norm(offset)
    return offset if norm <= MAX_GRASP_OFFSET else offset * (MAX_GRASP_OFFSET / norm)


def mass_from_torque_change(jacobian_z: np.ndarray, delta_tau: np.ndarray,
                            gravity: float = GRAVITY) -> float:
    """The point mass (kg) whose weight best explains a change of holding torques.

    A mass m held at a point whose vertical velocity is J_z·q̇ needs extra holding torques
    Δτ = m·g·J_z (N·m). The least-squares m over all joints is (J_z·Δτ) / (g·|J_z|²).

    jacobian_z: the vertical (world z) row of the point's translational Jacobian, m/rad.
    delta_tau: loaded minus empty holding torques, N·m.
    """
    jacobian_z = np.asarray(jacobian_z, dtype=float)
    norm2 = float(jacobian_z @ jacobian_z)
    if norm2 < 1e-8:
        raise ValueError("the held point cannot move vertically at this pose (|J_z| = 0): "
                         "its weight does not show in the joint torques")
    return float(jacobian_z @ np.asarray(delta_tau, dtype=float)) / (gravity * norm2)


class WindowKind(enum.Enum):
    """Which of a mass measurement's two windows: before or after grasping."""

    EMPTY = "empty"
    LOADED = "loaded"


@dc.dataclass(frozen=True)
class WindowRequest(Immutable):
    """A request on the MassEstimator's `window` port: average the arm's joint positions and
    torques for `duration` s as the `kind` window. `sequence` numbers the requests (1, 2, ...);
    a new number starts a new window."""

    sequence: int = 0
    kind: WindowKind = WindowKind.EMPTY
    duration: float = 0.0


@dc.dataclass(frozen=True)
class TorqueWindow(Immutable):
    """Mean joint positions (rad) and measured torques (N·m) over `count` samples."""

    position: np.ndarray
    torque: np.ndarray
    count: int


@dc.dataclass(frozen=True)
class MassEstimate(Immutable):
    """The MassEstimator's `estimate` output.

    sequence: the last window request that has finished (0: none yet). empty, loaded: the
    latest window of each kind. mass_kg: the mass the latest loaded window shows against the
    empty one before it (NaN until then, or if they cannot show a weight: `reason` says why).
    """

    sequence: int = 0
    empty: TorqueWindow | None = None
    loaded: TorqueWindow | None = None
    mass_kg: float = math.nan
    reason: str = "no loaded window has been averaged yet"


@dc.dataclass(frozen=True)
class _Averaging(Immutable):
    """The estimator's state: the window being averaged (sums over `count` samples of the
    `request`, which wants `wanted` of them) and the published estimate."""

    request: WindowRequest = WindowRequest()
    wanted: int = 0
    count: int = 0
    sum_q: np.ndarray = dc.field(default_factory=lambda: np.zeros(ports.NUM_ARM_JOINTS))
    sum_tau: np.ndarray = dc.field(default_factory=lambda: np.zeros(ports.NUM_ARM_JOINTS))
    estimate: MassEstimate = MassEstimate()


class MassEstimator(LeafSystem):
    """Averages `piper.torque_measured` and `piper.position_measured` over windows requested on
    its `window` input, and publishes the held mass they show on its `estimate` output, with
    the robot's own model.

    It reads nothing else: no simulator state, no object properties. A new request (a new
    sequence number) starts a window at the next sample (every 1/sample_rate s); after
    round(duration · sample_rate) samples (at least one) the window's means are published as
    its kind's window, and a LOADED window is turned into a mass against the EMPTY one before
    it (`estimate_mass`).

    torque_gain: each joint's torque sensor gain (reported change = gain × true change), as
    fitted with a weight of known mass (physx/torque_gain.py); None: ideal sensors (ones).

    Input ports: piper.position_measured (6, rad), piper.torque_measured (6, N·m),
        window (WindowRequest).
    Output port: estimate (MassEstimate).
    State (abstract): the window being averaged and the published estimate.
    """

    def __init__(self, controller_plant: MultibodyPlant, arm_joints: list, tcp_frame_name: str,
                 *, sample_rate: float, torque_gain=None):
        super().__init__()
        self._plant = controller_plant
        self._rate = float(sample_rate)
        gain = np.ones(ports.NUM_ARM_JOINTS) if torque_gain is None else torque_gain
        self._gain = as_gain(gain)
        # Our model, evaluated at the arguments of each computation (a pure function of them).
        self._model = ModelAtPositions(controller_plant)
        self._tcp = controller_plant.GetFrameByName(tcp_frame_name)
        self._q_index = [j.position_start() for j in arm_joints]
        self._v_index = [j.velocity_start() for j in arm_joints]
        n = ports.NUM_ARM_JOINTS
        self._q = self.DeclareVectorInputPort(ports.ARM_POSITION_MEASURED, n)
        self._tau = self.DeclareVectorInputPort(ports.ARM_TORQUE_MEASURED, n)
        self._window = self.DeclareAbstractInputPort(WINDOW_PORT,
                                                     AbstractValue.Make(WindowRequest()))
        self._state = self.DeclareAbstractState(AbstractValue.Make(_Averaging()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / sample_rate, 0.0, self._sample)
        self.DeclareAbstractOutputPort(
            ESTIMATE_PORT, lambda: AbstractValue.Make(MassEstimate()),
            weak_method(self._output_estimate),
            {self.abstract_state_ticket(self._state)})

    def _sample(self, context: Context, state: State) -> EventStatus | None:
        current: _Averaging = context.get_abstract_state(self._state).get_value()
        request = self._window.Eval(context)
        if request.sequence != current.request.sequence:  # a new window starts now
            wanted = max(1, round(request.duration * self._rate))
            current = _Averaging(request, wanted, estimate=current.estimate)
        elif current.count >= current.wanted:
            return EventStatus.DidNothing()  # finished (or never asked): nothing to average
        current = dc.replace(current, count=current.count + 1,
                             sum_q=current.sum_q + self._q.Eval(context),
                             sum_tau=current.sum_tau + self._tau.Eval(context))
        if current.count == current.wanted:
            current = dc.replace(current, estimate=self._publish(current))
        state.get_mutable_abstract_state(self._state).set_value(current)
        return None

    def _publish(self, done: _Averaging) -> MassEstimate:
        window = TorqueWindow(done.sum_q / done.count, done.sum_tau / done.count, done.count)
        estimate = done.estimate
        if done.request.kind is WindowKind.EMPTY:
            return MassEstimate(done.request.sequence, empty=window)
        if estimate.empty is None:
            return dc.replace(estimate, sequence=done.request.sequence, loaded=window,
                              reason="no empty window was averaged before the loaded one")
        try:
            mass, reason = self.estimate_mass(estimate.empty, window), ""
        except ValueError as error:  # the pose cannot show a weight
            mass, reason = math.nan, str(error)
        return dc.replace(estimate, sequence=done.request.sequence, loaded=window,
                          mass_kg=mass, reason=reason)

    def _output_estimate(self, context: Context, output: AbstractValue) -> None:
        output.set_value(context.get_abstract_state(self._state).get_value().estimate)

    @property
    def torque_gain(self) -> np.ndarray:
        """The torque sensors' gains the estimator divides the torque change by (6,)."""
        return self._gain.copy()

    @property
    def model_plant(self) -> MultibodyPlant:
        """The estimator's own model of the robot (arm and gripper only)."""
        return self._plant

    # Our own model of the arm ---------------------------------------------------------------

    def _at_arm(self, q_arm: np.ndarray) -> Context:
        """The model's context with the arm at `q_arm` (rad), the fingers at 0, to read."""
        q = np.zeros(self._plant.num_positions())
        q[self._q_index] = q_arm
        return self._model.at(q)

    def fingertip_jacobian(self, q_arm: np.ndarray, offset_xy=(0.0, 0.0)) -> np.ndarray:
        """The fingertip point's spatial velocity Jacobian over the arm joints at `q_arm`
        (rows ωx, ωy, ωz in rad/rad, vx, vy, vz in m/rad; world frame), for the point
        `offset_xy` (m, world frame) beside the fingertip — from the robot's model."""
        model = self._at_arm(q_arm)
        world = self._plant.world_frame()
        X_WT = self._tcp.CalcPoseInWorld(model)
        offset_in_tcp = X_WT.rotation().inverse().multiply([*offset_xy, 0.0])
        jacobian = self._plant.CalcJacobianSpatialVelocity(
            model, JacobianWrtVariable.kV, self._tcp, offset_in_tcp, world, world)
        return jacobian[:, self._v_index]

    def vertical_jacobian(self, q_arm: np.ndarray, offset_xy=(0.0, 0.0)) -> np.ndarray:
        """J_z: the world-z row of the translational Jacobian of the point `offset_xy` (m)
        beside the fingertip over the arm joints at `q_arm`, m/rad."""
        return self.fingertip_jacobian(q_arm, offset_xy)[5]

    def arm_gravity_torque(self, q_arm: np.ndarray) -> np.ndarray:
        """Torques (N·m) that hold the unloaded arm at `q_arm`, from the robot's model."""
        return -self._plant.CalcGravityGeneralizedForces(self._at_arm(q_arm))[self._v_index]

    def estimate_mass(self, empty: TorqueWindow, loaded: TorqueWindow) -> float:
        """The held mass (kg) from an empty and a loaded window at the same commanded pose:
        m = (J_z·Δτ) / (g·|J_z|²), J_z taken at the held object.

        The arm sags a little under the load; the change of its own gravity torque between
        the two measured poses is taken out of Δτ first. The held object's centre of mass
        may sit a little beside the fingertip point (a grasp is never perfectly centred); its
        horizontal offset is estimated from the same torques (`horizontal_load_offset`) and
        J_z is taken there. The reported change is divided by the sensors' `torque_gain`
        first (their offsets cancel in the difference).
        """
        delta_tau = self.load_torque(empty, loaded)
        jacobian = self.fingertip_jacobian(loaded.position)
        offset = horizontal_load_offset(jacobian[5], jacobian[0], jacobian[1], delta_tau)
        return mass_from_torque_change(self.vertical_jacobian(loaded.position, offset),
                                       delta_tau)

    def own_torque_change(self, empty: TorqueWindow, loaded: TorqueWindow) -> np.ndarray:
        """How much the arm's own gravity torque changes between the two windows' measured
        poses (the sag under the load), N·m, from the robot's model."""
        return (self.arm_gravity_torque(loaded.position)
                - self.arm_gravity_torque(empty.position))

    def load_torque(self, empty: TorqueWindow, loaded: TorqueWindow) -> np.ndarray:
        """The holding torques the load itself adds, N·m: the reported change divided by the
        sensors' gains, less the arm's own change (`own_torque_change`)."""
        return ((loaded.torque - empty.torque) / self._gain
                - self.own_torque_change(empty, loaded))


def as_gain(values) -> np.ndarray:
    """Six positive torque sensor gains as an array; a ValueError names a bad one."""
    gain = np.asarray(values, dtype=float).reshape(-1)
    if gain.shape != (ports.NUM_ARM_JOINTS,):
        raise ValueError(f"torque_gain needs {ports.NUM_ARM_JOINTS} values, one per arm "
                         f"joint; got {gain.size}")
    bad = [f"J{i + 1} = {g}" for i, g in enumerate(gain) if not (0.5 <= g <= 2.0)]
    if bad:
        raise ValueError(f"torque_gain must lie in [0.5, 2] (a gain is reported over true "
                         f"torque): {', '.join(bad)}")
    return gain
