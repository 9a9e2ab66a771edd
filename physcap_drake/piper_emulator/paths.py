"""Cartesian paths of the flange, as the firmware's MOVE L (a line) and MOVE C (an arc
through three points) follow them, and the timing along them.

Poses are 4×4 transforms in the arm's base frame (m). Along a path the orientation turns
uniformly from the start's to the end's (about one fixed axis).
"""

from __future__ import annotations

import math

import numpy as np

from physcap_drake.piper_emulator.end_pose import rotation_error


def rotation_from_vector(w: np.ndarray) -> np.ndarray:
    """The rotation by |w| rad about w (Rodrigues)."""
    angle = float(np.linalg.norm(w))
    if angle < 1e-12:
        return np.eye(3)
    k = w / angle
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * K @ K


class Segment:
    """A piece of path from `start` to `end` (4×4); `position(s)` for s in [0, 1] is the
    point a fraction s along it. `length` (m) and `turn` (rad) size it for timing."""

    def __init__(self, start: np.ndarray, end: np.ndarray, length: float):
        self.start, self.end, self.length = start, end, length
        self._turn = rotation_error(end[:3, :3], start[:3, :3])
        self.turn = float(np.linalg.norm(self._turn))

    def position(self, s: float) -> np.ndarray:
        raise NotImplementedError

    def pose(self, s: float) -> np.ndarray:
        X = np.eye(4)
        X[:3, :3] = rotation_from_vector(s * self._turn) @ self.start[:3, :3]
        X[:3, 3] = self.position(s)
        return X


class Line(Segment):
    def __init__(self, start: np.ndarray, end: np.ndarray):
        super().__init__(start, end, float(np.linalg.norm(end[:3, 3] - start[:3, 3])))

    def position(self, s: float) -> np.ndarray:
        return self.start[:3, 3] + s * (self.end[:3, 3] - self.start[:3, 3])


class Arc(Segment):
    """The circular arc from `start` through `middle` to `end` (positions); ValueError when
    the three points lie on one line (no circle passes through them)."""

    def __init__(self, start: np.ndarray, middle: np.ndarray, end: np.ndarray):
        a, b, c = start[:3, 3], middle[:3, 3], end[:3, 3]
        normal = np.cross(b - a, c - a)
        if np.linalg.norm(normal) < 1e-9:
            raise ValueError("MOVE C: the three points are on one line")
        # Circumcentre of the triangle a, b, c.
        ab, ac = b - a, c - a
        centre = a + (np.dot(ac, ac) * np.cross(normal, ab) + np.dot(ab, ab)
                      * np.cross(ac, normal)) / (2.0 * np.dot(normal, normal))
        self._centre, self._radius = centre, float(np.linalg.norm(a - centre))
        self._u = (a - centre) / self._radius
        self._w = normal / np.linalg.norm(normal)
        self._v = np.cross(self._w, self._u)
        self._angle = self._angle_of(c)
        super().__init__(start, end, self._radius * self._angle)

    def _angle_of(self, p: np.ndarray) -> float:
        d = p - self._centre
        angle = math.atan2(np.dot(d, self._v), np.dot(d, self._u))
        return angle if angle > 0 else angle + 2.0 * math.pi

    def position(self, s: float) -> np.ndarray:
        phi = s * self._angle
        return self._centre + self._radius * (math.cos(phi) * self._u + math.sin(phi) * self._v)


class PathTiming:
    """Progress along a segment at bounded linear/angular speed and acceleration, braking to
    stop at its end. `advance(dt)` returns the fraction s reached after dt s."""

    def __init__(self, segment: Segment, linear_speed: float, angular_speed: float,
                 linear_acceleration: float, angular_acceleration: float):
        # Work in "seconds at full speed": the segment takes `duration` s at full speed, and
        # the speed fraction may change by `ramp` per s.
        self.duration = max(segment.length / max(linear_speed, 1e-9),
                            segment.turn / max(angular_speed, 1e-9))
        self._ramp = min(linear_acceleration / max(linear_speed, 1e-9),
                         angular_acceleration / max(angular_speed, 1e-9))
        self._done, self._speed = 0.0, 0.0

    @property
    def finished(self) -> bool:
        return self._done >= self.duration

    def advance(self, dt: float) -> float:
        if self.duration <= 0.0:
            self._done = self.duration
            return 1.0
        remaining = self.duration - self._done
        ramp_dt = self._ramp * dt
        # The sampled form of sqrt(2·ramp·remaining), and no overshoot of the end.
        brake = ramp_dt * (math.sqrt(0.25 + 2.0 * remaining / (ramp_dt * dt)) - 0.5)
        wanted = min(1.0, brake, remaining / dt)
        self._speed += min(max(wanted - self._speed, -ramp_dt), ramp_dt)
        self._done = min(self.duration, self._done + self._speed * dt)
        if self.duration - self._done < 1e-9:
            self._done = self.duration
        return self._done / self.duration
