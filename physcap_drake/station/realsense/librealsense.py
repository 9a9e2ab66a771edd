"""Importing pyrealsense2 (the optional extra `realsense`) with an error that says how to get it."""

from __future__ import annotations

from types import ModuleType


def librealsense() -> ModuleType:
    """The `pyrealsense2` module. Raises ImportError naming the extra to install."""
    try:
        import pyrealsense2
    except ImportError as error:
        raise ImportError(
            "a RealSense camera needs librealsense's Python package: pip install "
            f"'physcap-drake[realsense]' (pyrealsense2; it needs libusb-1.0) ({error})"
        ) from None
    return pyrealsense2
