"""The faults of a stereo depth camera, applied to a perfect rendered depth image.

Design notes: docs/design/station.md.
"""

# No `from __future__ import annotations`: yaml_load_typed reads the field types at run time.
import dataclasses as dc

import cv2
import numpy as np

from physcap_drake.config_checks import ConfigChecker


@dc.dataclass
class StereoDepthFaults:
    """Stereo depth errors of an emulated RealSense (see the design notes for the
    sources of each figure). `enabled: false` passes the rendered depth through unchanged
    except for the range limits and the z16 quantization."""

    enabled: bool = True
    # RMS depth noise at 2 m as a fraction of the distance (datasheet: <= 2 %); grows with z².
    rms_at_2m: float = 0.02
    # Distance between the two infrared imagers, m (D435: 0.050, D415: 0.055).
    baseline: float = 0.050
    # Nearest and farthest depth the camera reports, m (D435 minimum Z at 848 x 480: 0.105).
    min_depth: float = 0.105
    max_depth: float = 10.0
    # A depth step larger than this between neighbouring pixels is an edge, m.
    edge_jump: float = 0.02
    # Probability that a pixel next to an edge has no depth.
    edge_hole_fraction: float = 0.3
    # Luminance (fraction of full scale) below which a surface is too dark to match, and the
    # fraction of black pixels without depth (rising linearly from 0 at the threshold).
    dark_luminance: float = 0.12
    dark_hole_fraction: float = 0.6
    # Luminance above which a pixel is saturated (a specular highlight), and the fraction of
    # such pixels without depth.
    bright_luminance: float = 0.98
    bright_hole_fraction: float = 0.8
    # Size of the blobs in which dark and bright holes come, px.
    hole_size: float = 2.0

    def check(self, at: ConfigChecker) -> None:
        at.number("rms_at_2m", self.rms_at_2m, minimum=0.0, maximum=0.2)
        at.number("baseline", self.baseline, minimum=0.0, maximum=0.5, open_minimum=True)
        at.number("min_depth", self.min_depth, minimum=0.0)
        at.number("max_depth", self.max_depth, minimum=self.min_depth, open_minimum=True)
        at.number("edge_jump", self.edge_jump, minimum=0.0, open_minimum=True)
        for key in ("edge_hole_fraction", "dark_hole_fraction", "bright_hole_fraction",
                    "dark_luminance", "bright_luminance"):
            at.number(key, getattr(self, key), minimum=0.0, maximum=1.0)
        at.number("hole_size", self.hole_size, minimum=0.0)

    def rms(self, depth: np.ndarray) -> np.ndarray:
        """The RMS depth noise (m) at depth `depth` (m)."""
        return self.rms_at_2m * 2.0 * (np.asarray(depth) / 2.0) ** 2

    def apply(self, depth: np.ndarray, rgb: np.ndarray, focal_x: float,
              rng: np.random.Generator) -> np.ndarray:
        """The depth image (H × W float32, m, 0 = no depth) a stereo camera would report for
        the perfect `depth` (m; inf or 0 where nothing was rendered) of the scene whose colour
        image is `rgb` (H × W × 3 or 4, uint8), both in the colour camera's frame with focal
        length `focal_x` (px)."""
        depth = np.asarray(depth, dtype=np.float32).reshape(rgb.shape[:2])
        valid = np.isfinite(depth) & (depth >= self.min_depth) & (depth <= self.max_depth)
        out = np.where(valid, depth, np.float32(0.0))
        if not self.enabled:
            return out
        noise = rng.standard_normal(out.shape, dtype=np.float32)
        out = np.where(valid, out + self.rms(out).astype(np.float32) * noise, np.float32(0.0))
        holes = occlusion_shadow(np.where(valid, depth, np.inf), focal_x * self.baseline)
        holes |= self._edge_holes(depth, valid, rng)
        holes |= self._reflectance_holes(rgb, rng)
        out[holes | (out < self.min_depth) | (out > self.max_depth)] = 0.0
        return out

    def _edge_holes(self, depth, valid, rng) -> np.ndarray:
        filled = np.where(valid, depth, np.float32(0.0))
        edge = np.zeros(depth.shape, dtype=bool)
        for axis in (0, 1):
            step = np.abs(np.diff(filled, axis=axis)) > self.edge_jump
            if axis == 0:
                edge[1:] |= step
                edge[:-1] |= step
            else:
                edge[:, 1:] |= step
                edge[:, :-1] |= step
        return edge & valid & (rng.random(depth.shape, dtype=np.float32)
                               < self.edge_hole_fraction)

    def _reflectance_holes(self, rgb, rng) -> np.ndarray:
        luminance = cv2.cvtColor(np.ascontiguousarray(rgb[:, :, :3]),
                                 cv2.COLOR_RGB2GRAY).astype(np.float32) / 255.0
        probability = np.zeros(luminance.shape, dtype=np.float32)
        if self.dark_luminance > 0:
            probability += self.dark_hole_fraction * np.clip(
                (self.dark_luminance - luminance) / self.dark_luminance, 0.0, 1.0)
        probability[luminance > self.bright_luminance] = self.bright_hole_fraction
        holes = np.zeros(luminance.shape, dtype=bool)
        rows, cols = np.nonzero(probability)
        if len(rows) == 0:
            return holes
        box = (slice(rows.min(), rows.max() + 1), slice(cols.min(), cols.max() + 1))
        shape = (box[0].stop - box[0].start, box[1].stop - box[1].start)
        holes[box] = _blob_uniform(shape, self.hole_size, rng) < probability[box]
        return holes


def occlusion_shadow(depth: np.ndarray, focal_baseline: float) -> np.ndarray:
    """Pixels of the left imager's depth image (`depth`, m, inf where empty) that the right
    imager, `baseline` to the right, cannot see: a point at column u appears in the right
    image at u − d(u), d = f·B / z (`focal_baseline` = f·B in px·m), and is hidden if a
    point further right lands at or left of that spot (being nearer)."""
    width = depth.shape[1]
    columns = np.arange(width, dtype=np.float32)
    shifted = columns - focal_baseline / depth  # inf depth: no disparity
    # The smallest landing column of any pixel strictly to the right, per row.
    suffix_min = np.minimum.accumulate(shifted[:, ::-1], axis=1)[:, ::-1]
    right_min = np.full(depth.shape, np.inf)
    right_min[:, :-1] = suffix_min[:, 1:]
    return np.isfinite(depth) & (right_min < shifted - 1e-3)


def _blob_uniform(shape, size: float, rng: np.random.Generator) -> np.ndarray:
    """Values uniform in [0, 1) per pixel, correlated over about `size` pixels (blobs):
    white Gaussian noise blurred over `size` px, rescaled to unit variance, through the
    normal distribution's CDF."""
    noise = rng.standard_normal(shape, dtype=np.float32)
    if size > 0:
        noise = cv2.GaussianBlur(noise, (0, 0), sigmaX=size)
        noise /= max(float(noise.std()), 1e-9)
    return _normal_cdf(noise)


def _normal_cdf(z: np.ndarray) -> np.ndarray:
    """The standard normal CDF (Abramowitz and Stegun 7.1.26 for erf, error < 2e-7)."""
    x = np.abs(z) / np.sqrt(2.0)
    t = 1.0 / (1.0 + 0.3275911 * x)
    poly = t * (0.254829592 + t * (-0.284496736 + t * (1.421413741 + t * (
        -1.453152027 + t * 1.061405429))))
    erf = 1.0 - poly * np.exp(-x * x)
    return 0.5 * (1.0 + np.sign(z) * erf)
