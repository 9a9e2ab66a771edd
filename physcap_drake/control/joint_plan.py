"""JointPlan: a timed sequence of joint-space segments, evaluated by absolute sim time."""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.trajectories import Trajectory


@dc.dataclass(frozen=True)
class JointPlan:
    """Arm joint positions over time: `segments` run back to back from `start_time` (s).

    Each segment is a Drake Trajectory over a finite time span (rad, rad/s, rad/s²). Before
    the start the plan holds its first position; after the end it holds its last one, so a
    finished plan is also the command that keeps the arm still. A plan without segments
    holds `initial_position`.
    """

    start_time: float
    initial_position: np.ndarray
    segments: tuple[Trajectory, ...] = ()

    @staticmethod
    def hold(q: np.ndarray, start_time: float = 0.0) -> JointPlan:
        return JointPlan(start_time, np.asarray(q, dtype=float).copy())

    @property
    def duration(self) -> float:
        return float(sum(s.end_time() - s.start_time() for s in self.segments))

    @property
    def end_time(self) -> float:
        return self.start_time + self.duration

    @property
    def final_position(self) -> np.ndarray:
        if not self.segments:
            return self.initial_position
        last = self.segments[-1]
        return last.value(last.end_time()).ravel()

    def _locate(self, t: float) -> tuple[Trajectory, float]:
        local = t - self.start_time
        for segment in self.segments:
            length = segment.end_time() - segment.start_time()
            if local <= length:
                return segment, segment.start_time() + max(local, 0.0)
            local -= length
        last = self.segments[-1]
        return last, last.end_time()

    def position(self, t: float) -> np.ndarray:
        """Joint positions at sim time t, rad."""
        if not self.segments:
            return self.initial_position
        segment, local = self._locate(t)
        return segment.value(local).ravel()

    def positions(self, times: np.ndarray) -> np.ndarray:
        """Joint positions at the sim times `times` (s), one column each, rad. A NaN time
        raises ValueError (it has no position)."""
        times = np.asarray(times, dtype=float)
        if np.isnan(times).any():
            raise ValueError(f"a joint plan has no position at a NaN time ({times.tolist()})")
        if not self.segments:
            return np.repeat(self.initial_position[:, None], len(times), axis=1)
        if times.shape == (1,):
            return self._sampled_at(float(times[0]))
        result = np.empty((len(self.initial_position), len(times)))
        local = np.clip(times - self.start_time, 0.0, self.duration)
        offset = 0.0
        for index, segment in enumerate(self.segments):
            length = segment.end_time() - segment.start_time()
            last = index == len(self.segments) - 1
            inside = (local >= offset) & ((local <= offset + length) | last)
            if np.any(inside):
                at = segment.start_time() + np.minimum(local[inside] - offset, length)
                result[:, inside] = segment.vector_values(at)
            local = np.where(inside, -1.0, local)  # each time once: its first segment
            offset += length
        return result

    def _sampled_at(self, t: float) -> np.ndarray:
        """`positions` at the one time `t` (s; not NaN), one column, rad: the same arithmetic
        on Python floats (clip, minimum and the segment's start as NumPy does them per
        element), without the array work that costs more than the sampling."""
        duration = self.duration
        local = t - self.start_time
        local = local if local > 0.0 else 0.0
        local = local if local < duration else duration
        offset = 0.0
        for index, segment in enumerate(self.segments):
            length = segment.end_time() - segment.start_time()
            if local >= offset and (local <= offset + length or index == len(self.segments) - 1):
                from_start = local - offset
                at = segment.start_time() + (from_start if from_start <= length else length)
                return segment.vector_values(np.array([at]))
            offset += length
        raise AssertionError("a clipped time lies in one of the plan's segments")
