"""Eye-to-hand calibration: a fixed camera's pose from a ChArUco board carried by the arm.

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Sequence

import cv2
import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from physcap_drake.perception import charuco

#: Fewest views with the board seen; fewer than three cannot fix both unknown poses.
MIN_VIEWS = 3
#: Pairs of views whose flange turned less than this are left out of the closed-form start
#: (their rotation axis is noise), rad.
MIN_PAIR_ROTATION = np.radians(5.0)
#: The second-largest singular value of the rotation axes' cross-covariance, relative to
#: the largest, below which the views' rotations are taken to share one axis.
MIN_AXIS_SPREAD = 0.05
#: Levenberg-Marquardt: iterations, the finite-difference step of the pose parameters (rad
#: and m), and the relative change of the squared error at which it stops.
LM_ITERATIONS = 60
LM_STEP = 1e-6
LM_TOLERANCE = 1e-12


@dc.dataclass(frozen=True)
class HandView:
    """One view: the flange pose X_WG from the arm's joint angles `q` (rad), and the
    corners seen (ids, N; pixels, N × 2)."""

    q: np.ndarray
    X_WG: RigidTransform
    ids: np.ndarray
    pixels: np.ndarray
    board: charuco.BoardSpec = charuco.MODEL_BOARD


@dc.dataclass(frozen=True)
class HandEyeFit:
    """The camera pose X_WC and the board's mount on the flange X_GB that best explain all
    views; the RMS reprojection error (px), the corners and the views used."""

    X_WC: RigidTransform
    X_GB: RigidTransform
    reprojection_error_px: float
    corners: int
    views: int


def _camera_matrix(intrinsics: tuple[float, float, float, float]) -> np.ndarray:
    fx, fy, cx, cy = intrinsics
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def board_in_camera(view: HandView, intrinsics) -> RigidTransform:
    """X_CB of one view from its corners alone (PnP)."""
    points = charuco.corner_points(view.board)[view.ids]
    ok, rvec, tvec = cv2.solvePnP(points, view.pixels, _camera_matrix(intrinsics), None,
                                  flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise charuco.BoardNotSeen("no board pose fits the corners of one view")
    return RigidTransform(RotationMatrix(cv2.Rodrigues(rvec)[0]), tvec.ravel())


def _rotation_vector(R: RotationMatrix) -> np.ndarray:
    return cv2.Rodrigues(np.ascontiguousarray(R.matrix()))[0].ravel()


def _closed_form(X_WG: Sequence[RigidTransform],
                 X_CB: Sequence[RigidTransform]) -> tuple[RigidTransform, RigidTransform]:
    """The start: X_WC from A · X = X · B over all pairs, then X_GB as the mean of each
    view's X_WG_i⁻¹ · X_WC · X_CB_i. Raises ValueError if the rotations share one axis."""
    motions = []
    for i in range(len(X_WG)):
        for j in range(i + 1, len(X_WG)):
            A = X_WG[j] @ X_WG[i].inverse()
            B = X_CB[j] @ X_CB[i].inverse()
            if np.linalg.norm(_rotation_vector(A.rotation())) >= MIN_PAIR_ROTATION:
                motions.append((A, B))
    a = np.array([_rotation_vector(A.rotation()) for A, _ in motions]).reshape(-1, 3)
    b = np.array([_rotation_vector(B.rotation()) for _, B in motions]).reshape(-1, 3)
    U, singular, Vt = np.linalg.svd(b.T @ a) if len(motions) else (None, np.zeros(3), None)
    if len(motions) < 2 or singular[1] < MIN_AXIS_SPREAD * singular[0]:
        raise ValueError("the arm's poses turn the board about one axis only (or not at "
                         "all): the camera's pose is not determined; vary the wrist's "
                         "orientation between views")
    flip = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R_WC = Vt.T @ flip @ U.T
    lhs = np.vstack([A.rotation().matrix() - np.eye(3) for A, _ in motions])
    rhs = np.concatenate([R_WC @ B.translation() - A.translation() for A, B in motions])
    p_WC = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    X_WC = RigidTransform(RotationMatrix(R_WC), p_WC)
    mounts = [X_WG[i].inverse() @ X_WC @ X_CB[i] for i in range(len(X_WG))]
    return X_WC, _mean_pose(mounts)


def _mean_pose(poses: Sequence[RigidTransform]) -> RigidTransform:
    """The chordal mean of poses: the rotation nearest the mean matrix, the mean position."""
    U, _, Vt = np.linalg.svd(sum(X.rotation().matrix() for X in poses))
    R = U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt
    return RigidTransform(RotationMatrix(R), np.mean([X.translation() for X in poses], axis=0))


def _perturbed(X: RigidTransform, delta: np.ndarray) -> RigidTransform:
    """X moved by a small twist: rotation vector delta[:3] (rad, about X's own origin in the
    outer frame) and translation delta[3:] (m)."""
    R = RotationMatrix(cv2.Rodrigues(np.asarray(delta[:3], dtype=float))[0])
    return RigidTransform(R @ X.rotation(), X.translation() + delta[3:])


def _residuals(params: np.ndarray, X_WC: RigidTransform, X_GB: RigidTransform,
               views: Sequence[HandView], K: np.ndarray) -> np.ndarray:
    X_CW = _perturbed(X_WC, params[:6]).inverse()
    mount = _perturbed(X_GB, params[6:])
    errors = []
    for view in views:
        corners = charuco.corner_points(view.board)
        p_C = (X_CW @ view.X_WG @ mount).multiply(corners[view.ids].T)
        uv = (K @ p_C)[:2] / p_C[2]
        errors.append((uv.T - view.pixels).ravel())
    return np.concatenate(errors)


def _refine(X_WC: RigidTransform, X_GB: RigidTransform, views: Sequence[HandView],
            K: np.ndarray) -> tuple[RigidTransform, RigidTransform, np.ndarray]:
    """Levenberg-Marquardt over both poses; returns them and the final residuals (px)."""
    damping = 1e-3
    residuals = _residuals(np.zeros(12), X_WC, X_GB, views, K)
    cost = residuals @ residuals
    for _ in range(LM_ITERATIONS):
        jacobian = np.empty((len(residuals), 12))
        for k in range(12):
            step = np.zeros(12)
            step[k] = LM_STEP
            jacobian[:, k] = (_residuals(step, X_WC, X_GB, views, K) - residuals) / LM_STEP
        normal = jacobian.T @ jacobian
        gradient = jacobian.T @ residuals
        while True:
            delta = -np.linalg.solve(normal + damping * np.diag(np.diag(normal) + 1e-12),
                                     gradient)
            trial = _residuals(delta, X_WC, X_GB, views, K)
            if trial @ trial < cost or damping > 1e8:
                break
            damping *= 10.0
        if trial @ trial >= cost:
            break
        X_WC, X_GB = _perturbed(X_WC, delta[:6]), _perturbed(X_GB, delta[6:])
        improvement = (cost - trial @ trial) / max(cost, 1e-300)
        residuals, cost, damping = trial, trial @ trial, max(damping / 10.0, 1e-9)
        if improvement < LM_TOLERANCE:
            break
    return X_WC, X_GB, residuals


def solve_eye_to_hand(views: Sequence[HandView],
                      intrinsics: tuple[float, float, float, float]) -> HandEyeFit:
    """The camera pose and the board's mount from `views` (see the design notes), for a
    pinhole camera (fx, fy, cx, cy; px, no distortion). Views with fewer than
    `charuco.MIN_CORNERS` corners are left out. Raises BoardNotSeen for fewer than
    MIN_VIEWS usable views, ValueError for rotations about one axis only."""
    usable = [view for view in views if len(view.ids) >= charuco.MIN_CORNERS]
    if len(usable) < MIN_VIEWS:
        raise charuco.BoardNotSeen(
            f"the board was seen well ({charuco.MIN_CORNERS}+ corners) in {len(usable)} of "
            f"{len(views)} views; hand-eye calibration needs at least {MIN_VIEWS}")
    K = _camera_matrix(intrinsics)
    X_CB = [board_in_camera(view, intrinsics) for view in usable]
    X_WC, X_GB = _closed_form([view.X_WG for view in usable], X_CB)
    X_WC, X_GB, residuals = _refine(X_WC, X_GB, usable, K)
    corners = sum(len(view.ids) for view in usable)
    error = float(np.sqrt(np.sum(residuals ** 2) / corners))
    return HandEyeFit(X_WC, X_GB, error, corners, len(usable))
