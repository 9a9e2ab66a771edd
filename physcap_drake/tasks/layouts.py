"""Where a task's objects stand: the slots of a task file's layout, drawn from the seed's
random stream (world frame, m)."""

from __future__ import annotations

import numpy as np


def slots(layout, count: int, rng: np.random.Generator) -> list[tuple[float, float, float]]:
    """(x, y, yaw) of `count` objects laid out by `layout` (a task_file.Layout), in slot
    order; the draws (jitter x, jitter y, then yaw, slot by slot) come from `rng`."""
    if layout.kind == "scatter":
        spots = scatter(rng, np.array(layout.region[0]), np.array(layout.region[1]),
                        layout.min_spacing_m, count)
        return [(float(x), float(y), 0.0) for x, y in spots]
    if layout.kind == "row":
        centres = [(layout.x[0], y) for y in layout.y]
    elif layout.kind == "grid":
        centres = [(x, y) for x in layout.x for y in layout.y]
    else:  # places
        centres = [tuple(place) for place in layout.places]
    out = []
    for x, y in centres[:count]:
        jitter = layout.jitter_m
        xy = (x + rng.uniform(-jitter, jitter), y + rng.uniform(-jitter, jitter))
        yaw = (rng.uniform(-layout.yaw_jitter_rad, layout.yaw_jitter_rad)
               if layout.yaw_jitter_rad > 0 else 0.0)
        out.append((xy[0], xy[1], yaw))
    return out


def scatter(rng: np.random.Generator, lower: np.ndarray, upper: np.ndarray,
            spacing: float, count: int) -> list[np.ndarray]:
    """`count` spots in the box [lower, upper] at least `spacing` apart (rejection
    sampling, starting over when a layout has left no room)."""
    for _ in range(1000):
        spots: list[np.ndarray] = []
        for _ in range(200):
            xy = rng.uniform(lower, upper)
            if all(np.linalg.norm(xy - s) >= spacing for s in spots):
                spots.append(xy)
                if len(spots) == count:
                    return spots
    raise RuntimeError(f"no layout of {count} objects {spacing} m apart fits the region "
                       f"{lower.tolist()}..{upper.tolist()}")


def slot_count(layout) -> int:
    """How many objects the layout has room for (None: any number)."""
    if layout.kind == "row":
        return len(layout.y)
    if layout.kind == "grid":
        return len(layout.x) * len(layout.y)
    if layout.kind == "places":
        return len(layout.places)
    return None
