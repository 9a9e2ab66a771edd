"""The table plane, found in the depth image alone.

The camera's extrinsics put its points in the world frame, but nothing tells perception
where the table is: `fit_table_plane` finds it as the largest near-horizontal plane among
the points (RANSAC, then a least-squares fit of its inliers), so a table that is not at
z = 0, or a camera calibration that is slightly off in height, still gives heights above
the real surface.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np

#: RANSAC: hypotheses tried, inlier distance (m; the depth noise at the table is ~1 cm RMS),
#: and the largest tilt of the table from the world's horizontal (rad).
HYPOTHESES = 120
INLIER_DISTANCE = 0.02
MAX_TILT = np.radians(20.0)
#: The final fit uses the points this close to the first one, m (about 2 sigma of the noise:
#: it leaves out a tray's floor and the feet of objects).
REFINED_DISTANCE = 0.012
#: Points used for the hypotheses (a random subset is enough and keeps it fast).
SAMPLE = 6000


@dc.dataclass(frozen=True)
class Plane:
    """The plane n·p = offset (world frame, m), `normal` a unit vector pointing up."""

    normal: np.ndarray
    offset: float

    def heights(self, points: np.ndarray) -> np.ndarray:
        """Signed distances (m) of points (N × 3) above the plane."""
        return points @ self.normal - self.offset


class NoTableFound(ValueError):
    """The depth image shows no near-horizontal plane."""


def fit_table_plane(points: np.ndarray, seed: int = 0) -> Plane:
    """The dominant near-horizontal plane of `points` (N × 3, world frame, m). Raises
    NoTableFound if fewer than 1000 points fit one."""
    rng = np.random.default_rng(seed)
    if len(points) < 1000:
        raise NoTableFound(f"only {len(points)} points with depth: no table in view")
    sample = points[rng.choice(len(points), min(SAMPLE, len(points)), replace=False)]
    triples = sample[rng.integers(len(sample), size=(HYPOTHESES, 3))]
    normals = np.cross(triples[:, 1] - triples[:, 0], triples[:, 2] - triples[:, 0])
    norms = np.linalg.norm(normals, axis=1)
    usable = norms > 1e-9
    normals = normals[usable] / norms[usable, None]
    normals *= np.where(normals[:, 2] < 0, -1.0, 1.0)[:, None]
    upright = np.arccos(np.clip(normals[:, 2], -1.0, 1.0)) <= MAX_TILT
    normals, anchors = normals[upright], triples[usable][upright, 0]
    if len(normals) == 0:
        raise NoTableFound("no near-horizontal plane in the depth image")
    offsets = np.einsum("ij,ij->i", normals, anchors)
    counts = (np.abs(sample @ normals.T - offsets) < INLIER_DISTANCE).sum(axis=0)
    best = Plane(normals[np.argmax(counts)], float(offsets[np.argmax(counts)]))
    plane = best
    for distance in (INLIER_DISTANCE, REFINED_DISTANCE):  # refit on the inliers, twice
        inliers = points[np.abs(plane.heights(points)) < distance]
        if len(inliers) < 1000:
            raise NoTableFound(f"the best table plane has only {len(inliers)} points")
        centre = inliers.mean(axis=0)
        normal = np.linalg.svd(inliers - centre, full_matrices=False)[2][-1]
        normal = normal * np.sign(normal[2])
        plane = Plane(normal, float(normal @ centre))
    return plane
