"""MassEstimator: averages joint torques at a measurement pose and turns their change into
the mass of what the gripper holds."""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from physcap_drake.station import ports

#: Standard gravity, m/s².
GRAVITY = 9.81
#: Largest horizontal offset of the held object's centre of mass from the fingertip point
#: that the estimate accepts, m: anything further is not between the fingers (and is noise).
MAX_GRASP_OFFSET = 0.02


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


@dc.dataclass(frozen=True)
class TorqueWindow:
    """Mean joint positions (rad) and measured torques (N·m) over `count` samples."""

    position: np.ndarray
    torque: np.ndarray
    count: int


class MassEstimator(LeafSystem):
    """Averages `piper.torque_measured` and `piper.position_measured` over a window, and
    computes a held mass from two windows (empty, then loaded) with the robot's own model.

    It reads nothing else: no simulator state, no object properties. `begin_window(context)`
    starts averaging (every 1/sample_rate s), `end_window(context)` returns the mean.

    Input ports: piper.position_measured (6, rad), piper.torque_measured (6, N·m).
    Discrete state: [averaging (0/1), sample count, Σq (6), Στ (6)].
    """

    def __init__(self, controller_plant: MultibodyPlant, arm_joints: list, tcp_frame_name: str,
                 *, sample_rate: float):
        super().__init__()
        self._plant = controller_plant
        # Scratch context of our model: set from the arguments of each computation.
        self._scratch = controller_plant.CreateDefaultContext()
        self._tcp = controller_plant.GetFrameByName(tcp_frame_name)
        self._q_index = [j.position_start() for j in arm_joints]
        self._v_index = [j.velocity_start() for j in arm_joints]
        n = ports.NUM_ARM_JOINTS
        self._q = self.DeclareVectorInputPort(ports.ARM_POSITION_MEASURED, n)
        self._tau = self.DeclareVectorInputPort(ports.ARM_TORQUE_MEASURED, n)
        self._state = self.DeclareDiscreteState(2 + 2 * n)
        self.DeclarePeriodicDiscreteUpdateEvent(1.0 / sample_rate, 0.0, self._sample)

    def _sample(self, context: Context, state: DiscreteValues) -> None:
        x = context.get_discrete_state(self._state).get_value().copy()
        if x[0] < 0.5:
            return
        n = ports.NUM_ARM_JOINTS
        x[1] += 1
        x[2:2 + n] += self._q.Eval(context)
        x[2 + n:] += self._tau.Eval(context)
        state.get_mutable_vector(self._state).SetFromVector(x)

    @property
    def model_plant(self) -> MultibodyPlant:
        """The estimator's own model of the robot (arm and gripper only)."""
        return self._plant

    def begin_window(self, context: Context) -> None:
        """Starts a new averaging window now (discarding any running one)."""
        x = np.zeros(2 + 2 * ports.NUM_ARM_JOINTS)
        x[0] = 1.0
        context.SetDiscreteState(self._state, x)

    def end_window(self, context: Context) -> TorqueWindow:
        """Stops averaging; the mean of the samples since begin_window."""
        x = context.get_discrete_state(self._state).get_value().copy()
        count = int(x[1])
        if x[0] < 0.5 or count == 0:
            raise RuntimeError("no torque samples were averaged: call begin_window and let "
                               "simulated time pass before end_window")
        n = ports.NUM_ARM_JOINTS
        context.SetDiscreteState(self._state, np.zeros_like(x))
        return TorqueWindow(x[2:2 + n] / count, x[2 + n:] / count, count)

    # Our own model of the arm ---------------------------------------------------------------

    def _set_arm(self, q_arm: np.ndarray) -> None:
        q = np.zeros(self._plant.num_positions())
        q[self._q_index] = q_arm
        self._plant.SetPositions(self._scratch, q)

    def fingertip_jacobian(self, q_arm: np.ndarray, offset_xy=(0.0, 0.0)) -> np.ndarray:
        """The fingertip point's spatial velocity Jacobian over the arm joints at `q_arm`
        (rows ωx, ωy, ωz in rad/rad, vx, vy, vz in m/rad; world frame), for the point
        `offset_xy` (m, world frame) beside the fingertip — from the robot's model."""
        self._set_arm(q_arm)
        world = self._plant.world_frame()
        X_WT = self._tcp.CalcPoseInWorld(self._scratch)
        offset_in_tcp = X_WT.rotation().inverse().multiply([*offset_xy, 0.0])
        jacobian = self._plant.CalcJacobianSpatialVelocity(
            self._scratch, JacobianWrtVariable.kV, self._tcp, offset_in_tcp, world, world)
        return jacobian[:, self._v_index]

    def vertical_jacobian(self, q_arm: np.ndarray, offset_xy=(0.0, 0.0)) -> np.ndarray:
        """J_z: the world-z row of the translational Jacobian of the point `offset_xy` (m)
        beside the fingertip over the arm joints at `q_arm`, m/rad."""
        return self.fingertip_jacobian(q_arm, offset_xy)[5]

    def arm_gravity_torque(self, q_arm: np.ndarray) -> np.ndarray:
        """Torques (N·m) that hold the unloaded arm at `q_arm`, from the robot's model."""
        self._set_arm(q_arm)
        return -self._plant.CalcGravityGeneralizedForces(self._scratch)[self._v_index]

    def estimate_mass(self, empty: TorqueWindow, loaded: TorqueWindow) -> float:
        """The held mass (kg) from an empty and a loaded window at the same commanded pose:
        m = (J_z·Δτ) / (g·|J_z|²), J_z taken at the held object.

        The arm sags a little under the load; the change of its own gravity torque between
        the two measured poses is taken out of Δτ first. The held object's centre of mass
        may sit a little beside the fingertip point (a grasp is never perfectly centred); its
        horizontal offset is estimated from the same torques (`horizontal_load_offset`) and
        J_z is taken there.
        """
        own_change = (self.arm_gravity_torque(loaded.position)
                      - self.arm_gravity_torque(empty.position))
        delta_tau = loaded.torque - empty.torque - own_change
        jacobian = self.fingertip_jacobian(loaded.position)
        offset = horizontal_load_offset(jacobian[5], jacobian[0], jacobian[1], delta_tau)
        return mass_from_torque_change(self.vertical_jacobian(loaded.position, offset),
                                       delta_tau)
