"""The wooden tray as the tray tasks' scenarios place it and the camera names it (the task
files in tasks/files/ say the same in their `destination`)."""

from __future__ import annotations

import numpy as np

#: The tray's floor centre (as placed in the task scenarios), m.
TRAY_BOTTOM = np.array([0.30, -0.27, 0.0])
#: The tray as the camera describes it (perception's name for it).
TRAY_NAME = "wooden tray"
