"""The station's port contract: the same names and sizes for the simulated and the real arm.

Units: joint positions rad, velocities rad/s, torques N·m (joint order J1..J6); gripper
opening m (total gap between the fingers); gripper force limit N (squeeze force of
each finger); gripper effort normalized to [0, 1] of the station's maximum force (the paper's f̂).
"""

NUM_ARM_JOINTS = 6

# Inputs: what a controller commands.
ARM_POSITION = "piper.position"  # 6: joint targets, rad (the firmware's joint mode)
GRIPPER_POSITION = "gripper.position"  # 1: commanded opening, m
GRIPPER_FORCE_LIMIT = "gripper.force_limit"  # 1: largest squeeze force of each finger, N

# Outputs: what the arm reports.
ARM_POSITION_MEASURED = "piper.position_measured"  # 6: rad
ARM_VELOCITY_ESTIMATED = "piper.velocity_estimated"  # 6: rad/s
ARM_TORQUE_MEASURED = "piper.torque_measured"  # 6: N·m, net motor torque (noisy, quantized)
GRIPPER_POSITION_MEASURED = "gripper.position_measured"  # 1: opening, m
GRIPPER_EFFORT_MEASURED = "gripper.effort_measured"  # 1: normalized effort, 0..1
# str: what stopped the arm (an error state it reports, feedback lost), "" while nothing
# did; latched for the rest of the run. The simulated arm never faults: always "".
ARM_FAULT = "piper.fault"

# Camera outputs (images).
CAMERA_RGB = "camera.rgb"  # ImageRgba8U
CAMERA_DEPTH = "camera.depth"  # ImageDepth32F, m
CAMERA_LABEL = "camera.label"  # ImageLabel16I, one label per body (simulation only)

# Simulation-only ground truth: for success checks, never for agents or estimators.
BODY_POSES = "body_poses"  # list of RigidTransform, world frame, indexed by BodyIndex

# Simulation-only input, exported on request (MakeSimStation(..., external_forces=True)):
# forces from outside the station's own model on the plant's bodies, e.g. the emulated
# firmware's end-load compensation (station/end_load.py).
APPLIED_SPATIAL_FORCE = "plant.applied_spatial_force"  # list of ExternallyAppliedSpatialForce

VECTOR_INPUTS = {ARM_POSITION: NUM_ARM_JOINTS, GRIPPER_POSITION: 1, GRIPPER_FORCE_LIMIT: 1}
VECTOR_OUTPUTS = {
    ARM_POSITION_MEASURED: NUM_ARM_JOINTS,
    ARM_VELOCITY_ESTIMATED: NUM_ARM_JOINTS,
    ARM_TORQUE_MEASURED: NUM_ARM_JOINTS,
    GRIPPER_POSITION_MEASURED: 1,
    GRIPPER_EFFORT_MEASURED: 1,
}
IMAGE_OUTPUTS = (CAMERA_RGB, CAMERA_DEPTH, CAMERA_LABEL)
SIM_ONLY_OUTPUTS = (CAMERA_LABEL, BODY_POSES)


def camera_port(camera_name: str, image: str) -> str:
    """Port name of one image of a camera: camera_port("camera", "rgb") == "camera.rgb"."""
    return f"{camera_name}.{image}"
