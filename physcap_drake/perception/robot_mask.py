"""The robot's own body in the camera's view, from its measured joint positions.

The arm stands on the table in front of the camera, so its links, gripper and base would
look like objects standing above the table. A real robot knows where it is: forward
kinematics of the measured joints (the vendor's DH model, `kinematics.piper_dh`) places a
chain of capsules along its links, and every point inside one belongs to the robot and is
left out of the scene. The arm's base is the world origin (as in every scenario's
directives and on the real rig, whose camera is calibrated in the arm's base frame).
"""

from __future__ import annotations

import numpy as np

from physcap_drake.kinematics.piper_dh import link_transforms, tcp_transform

#: Capsule radii, m: the base column and links (the widest link is 0.09 m across, plus
#: margin for depth noise), and the gripper (0.14 m wide across its fingers' rail).
LINK_RADIUS = 0.075
GRIPPER_RADIUS = 0.10
#: The gripper's capsule reaches this far past the fingertip point (the finger pads and
#: whatever it holds), m.
BEYOND_FINGERTIPS = 0.05


class RobotSelfFilter:
    """`self(points)`: which world points (N × 3, m) lie on the arm at joint positions `q`
    (J1..J6, rad)."""

    def __init__(self, q):
        frames = link_transforms(np.asarray(q, dtype=float))
        tcp = tcp_transform(np.asarray(q, dtype=float))
        chain = [np.zeros(3)] + [frame[:3, 3] for frame in frames]
        self.segments = [(a, b, LINK_RADIUS) for a, b in zip(chain[:-1], chain[1:], strict=True)
                         if np.linalg.norm(b - a) > 1e-6]
        flange = frames[-1][:3, 3]
        beyond = tcp[:3, 3] + BEYOND_FINGERTIPS * tcp[:3, 2]
        self.segments.append((flange, beyond, GRIPPER_RADIUS))

    def __call__(self, points: np.ndarray) -> np.ndarray:
        points = np.atleast_2d(points)
        inside = np.zeros(len(points), dtype=bool)
        for a, b, radius in self.segments:
            axis = b - a
            t = np.clip((points - a) @ axis / (axis @ axis), 0.0, 1.0)
            nearest = a + t[:, None] * axis
            inside |= np.einsum("ij,ij->i", points - nearest, points - nearest) < radius**2
        return inside
