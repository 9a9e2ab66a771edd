"""Camera images as JPEG, the form in which they go to language models."""

from __future__ import annotations

import cv2
import numpy as np


def encode_jpeg(rgb: np.ndarray, quality: int = 85) -> bytes:
    """An RGB(A) uint8 image (H × W × 3 or 4) as JPEG bytes at `quality` (0–100)."""
    image = cv2.cvtColor(np.ascontiguousarray(rgb[:, :, :3]), cv2.COLOR_RGB2BGR)
    ok, jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise RuntimeError("could not encode the camera image as JPEG")
    return jpeg.tobytes()
