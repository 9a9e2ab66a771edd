"""TargetPlayback: the diagram's joint targets, replayed at the arm's steady pace.

Design notes: docs/design/can.md.
"""

from __future__ import annotations

from collections import deque

import numpy as np

#: How far (simulated s) the playback aims to stay behind the newest sample: pauses in the
#: diagram's samples up to about this long do not disturb the arm's motion.
DELAY = 0.08
#: The playback's pace (simulated s per wall s) is a PI controller on that distance, averaged
#: over AVERAGING s: it settles on the diagram's own pace (below 1 when the diagram runs
#: behind wall time) without following each burst.
AVERAGING = 0.1
PROPORTIONAL_TIME = 0.5  # s to make up a distance error at the proportional pace
INTEGRAL_TIME = 1.0  # s
MAX_RATE = 1.5
#: The deceleration (rad/s², each joint) with which the playback can always stop on the
#: newest sample: it never goes faster than that allows, so when the samples stop coming
#: the arm does not run past the last one.
BRAKING = 4.0
#: Samples further ahead of the playback than this are not waited for: the playback jumps
#: (the rate limiter in front of the arm then takes over), s of simulated time.
MAX_LEAD = 0.3
#: The longest wall-clock step the playback takes in one go, s.
MAX_STEP = 0.05


class TargetPlayback:
    """Samples in (`add`), the target of each streaming cycle out (`next`). A sample is a
    vector whose first `braked` entries are joint positions (rad), held to `BRAKING`;
    the rest (the gripper's) are played back in step with them."""

    def __init__(self, braked: int = 6):
        self._braked = braked
        self._samples: deque[tuple[float, np.ndarray]] = deque()
        self._play: float | None = None  # the simulated time being played
        self._lead = DELAY  # how far the newest sample is ahead of it, averaged, s
        self._pace = 1.0  # the diagram's pace as the integral term sees it
        self._rolling = False  # False until DELAY of samples came in: the playback holds

    def reset(self) -> None:
        """Forgets the samples (the targets no longer come from a trajectory)."""
        self._samples.clear()
        self._play = None
        self._lead, self._pace, self._rolling = DELAY, 1.0, False

    def add(self, q: np.ndarray, sim_time: float) -> None:
        """A target q for the simulated time `sim_time` (s). A sample from before the newest
        one (a new simulation) starts the playback over."""
        if self._samples and sim_time <= self._samples[-1][0]:
            if sim_time == self._samples[-1][0]:
                self._samples[-1] = (sim_time, np.array(q, dtype=float))
                return
            self.reset()
        self._samples.append((sim_time, np.array(q, dtype=float)))
        if self._play is None:
            self._play = sim_time

    @property
    def empty(self) -> bool:
        return not self._samples

    def next(self, elapsed: float) -> tuple[np.ndarray, np.ndarray]:
        """The target and its speed (per s) `elapsed` wall seconds after the last call.
        Requires a sample."""
        newest = self._samples[-1][0]
        lead = newest - self._play
        if lead > MAX_LEAD:
            self._play = newest - MAX_LEAD
            lead = MAX_LEAD
        self._rolling = self._rolling or lead >= DELAY
        dt = min(max(elapsed, 0.0), MAX_STEP) if self._rolling else 0.0
        self._lead += min(dt / AVERAGING, 1.0) * (lead - self._lead)
        error = self._lead - DELAY
        self._pace = min(max(self._pace + error / INTEGRAL_TIME * dt, 0.0), MAX_RATE)
        rate = min(max(self._pace + error / PROPORTIONAL_TIME, 0.0), MAX_RATE)
        times = np.array([t for t, _ in self._samples])
        points = np.array([q for _, q in self._samples])
        segment = max(int(np.searchsorted(times, self._play, side="right")) - 1, 0)
        if segment + 1 < len(times):
            t0, t1 = times[segment], times[segment + 1]
            joints = points[:, :self._braked]
            slope = (joints[segment + 1] - joints[segment]) / (t1 - t0)
            here = joints[segment] + slope * (self._play - t0)
            # Each joint's path to the newest sample, and the fastest it may go to stop there.
            remaining = (np.abs(joints[segment + 1] - here)
                         + np.abs(np.diff(joints[segment + 1:], axis=0)).sum(axis=0))
            moving = np.abs(slope) > 1e-9
            if moving.any():
                stop = np.sqrt(2.0 * BRAKING * remaining[moving]) / np.abs(slope[moving])
                rate = min(rate, float(stop.min()))
        self._play = min(self._play + rate * dt, times[-1])
        while len(self._samples) > 1 and self._samples[1][0] <= self._play:
            self._samples.popleft()
        t0, q0 = self._samples[0]
        if len(self._samples) == 1:
            return q0.copy(), np.zeros_like(q0)
        t1, q1 = self._samples[1]
        slope = (q1 - q0) / (t1 - t0)
        return q0 + slope * (self._play - t0), slope * rate
