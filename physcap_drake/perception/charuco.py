"""The ChArUco calibration board: its layout, finding its corners in an image, and the camera
pose that explains them (OpenCV's `aruco` module).

Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import dataclasses as dc

import cv2
import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

#: Squares along the long and the short side, the side of a square and of a marker (m),
#: and the marker dictionary: 4 x 4 bit markers, large enough to decode from above the table
#: (a marker spans about 15 px in the station camera's view; smaller ones do not decode).
SQUARES = (6, 4)
SQUARE = 0.09
MARKER = 0.068
DICTIONARY = cv2.aruco.DICT_4X4_50
#: The board's size, m.
SIZE = (SQUARES[0] * SQUARE, SQUARES[1] * SQUARE)
#: How marker corners are refined to sub-pixel accuracy before the chessboard corners are
#: interpolated between them (without it they sit half a pixel off).
REFINEMENT = cv2.aruco.CORNER_REFINE_CONTOUR
#: Fewest corners for a pose.
MIN_CORNERS = 6


@dc.dataclass(frozen=True)
class BoardSpec:
    """A ChArUco board's layout: squares along the long and the short side, the side of a
    square and of a marker (m); the dictionary is DICTIONARY."""

    squares: tuple[int, int] = SQUARES
    square: float = SQUARE
    marker: float = MARKER

    @property
    def size(self) -> tuple[float, float]:
        """The board's long and short side, m."""
        return self.squares[0] * self.square, self.squares[1] * self.square

    def with_square(self, square: float) -> BoardSpec:
        """The same board printed at another scale: squares of `square` m."""
        return BoardSpec(self.squares, square, self.marker * square / self.square)


#: The board of the simulated scenes (models/calibration/charuco_board).
MODEL_BOARD = BoardSpec()


def board(spec: BoardSpec = MODEL_BOARD) -> cv2.aruco.CharucoBoard:
    return cv2.aruco.CharucoBoard(spec.squares, spec.square, spec.marker,
                                  cv2.aruco.getPredefinedDictionary(DICTIONARY))


def board_image(pixels_per_metre: float, spec: BoardSpec = MODEL_BOARD) -> np.ndarray:
    """The board as a printable grey image (rows × columns, uint8), no margin."""
    size = (round(spec.size[0] * pixels_per_metre), round(spec.size[1] * pixels_per_metre))
    return board(spec).generateImage(size, marginSize=0, borderBits=1)


def corner_points(spec: BoardSpec = MODEL_BOARD) -> np.ndarray:
    """The inner corners in the board frame B (N × 3, m), in OpenCV's numbering."""
    corners = board(spec).getChessboardCorners().astype(np.float64)  # top-left, y down
    width, height = spec.size
    return np.column_stack([corners[:, 0] - width / 2, height / 2 - corners[:, 1],
                            np.zeros(len(corners))])


def detect_corners(rgb: np.ndarray,
                   spec: BoardSpec = MODEL_BOARD) -> tuple[np.ndarray, np.ndarray]:
    """The board corners found in `rgb` (H × W × 3 or 4, uint8): their ids (N) and pixels
    (N × 2, sub-pixel). Empty arrays if the board is not seen."""
    gray = cv2.cvtColor(np.ascontiguousarray(rgb[:, :, :3]), cv2.COLOR_RGB2GRAY)
    markers = cv2.aruco.DetectorParameters()
    markers.cornerRefinementMethod = REFINEMENT
    detector = cv2.aruco.CharucoDetector(board(spec), detectorParams=markers)
    corners, ids, _, _ = detector.detectBoard(gray)
    if ids is None or len(ids) == 0:
        return np.zeros(0, dtype=int), np.zeros((0, 2))
    return ids.ravel().astype(int), corners.reshape(-1, 2).astype(np.float64)


@dc.dataclass(frozen=True)
class PoseFit:
    """The camera pose that best explains the corners seen: X_WC (the colour camera's
    optical frame in the world), the RMS reprojection error (px) and how many corners."""

    X_WC: RigidTransform
    reprojection_error_px: float
    corners: int


class BoardNotSeen(ValueError):
    """Too few board corners in the images for a camera pose."""


def fit_camera_pose(world_points: np.ndarray, pixels: np.ndarray,
                    intrinsics: tuple[float, float, float, float]) -> PoseFit:
    """The camera pose from corners at known world points (N × 3, m) seen at `pixels`
    (N × 2) by a pinhole camera (fx, fy, cx, cy; px, no distortion): OpenCV's iterative
    PnP, refined by Levenberg-Marquardt. Raises BoardNotSeen below MIN_CORNERS corners."""
    if len(world_points) < MIN_CORNERS:
        raise BoardNotSeen(f"only {len(world_points)} board corners seen (need "
                           f"{MIN_CORNERS}): is the board in view and lit?")
    fx, fy, cx, cy = intrinsics
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    ok, rvec, tvec = cv2.solvePnP(world_points, pixels, K, None,
                                  flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise BoardNotSeen("no camera pose fits the board corners seen")
    rvec, tvec = cv2.solvePnPRefineLM(world_points, pixels, K, None, rvec, tvec)
    projected, _ = cv2.projectPoints(world_points, rvec, tvec, K, None)
    error = float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - pixels) ** 2, axis=1))))
    X_CW = RigidTransform(RotationMatrix(cv2.Rodrigues(rvec)[0]), tvec.ravel())
    return PoseFit(X_CW.inverse(), error, len(world_points))
