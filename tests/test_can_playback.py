"""TargetPlayback: the diagram's targets, replayed at a steady pace whatever their bursts."""

import numpy as np
import pytest

from physcap_drake.can.joint_profile import step_towards
from physcap_drake.can.playback import TargetPlayback

PERIOD = 0.005  # the streaming cycle and the diagram's control period, s


def ramp_to(goal: float, speed: float, acceleration: float) -> tuple[np.ndarray, np.ndarray]:
    """A trajectory of J2 from 0 to `goal` rad within the given limits, one sample a period."""
    q, v, samples = np.zeros(6), np.zeros(6), [np.zeros(6)]
    target = np.zeros(6)
    target[1] = goal
    while len(samples) < 2 or np.any(q != samples[-2]):
        q, v = step_towards(q, v, target, np.zeros(6), np.full(6, speed),
                            np.full(6, acceleration), PERIOD)
        samples.append(q.copy())
    return PERIOD * np.arange(len(samples)), np.array(samples)


def stream(times, samples, delivered_by, cycles: int):
    """Plays `samples` as the streaming process does, the diagram having produced those up to
    `delivered_by(wall time)` of simulated time; then streams the played targets within
    the firmware's limits. Returns the played and the streamed J2 positions, and the
    furthest J2 sample delivered by then, rad."""
    playback = TargetPlayback()
    q, v, k = samples[0].copy(), np.zeros(6), 0
    played, streamed, furthest = [], [], []
    for cycle in range(cycles):
        while k < len(times) and times[k] <= delivered_by(cycle * PERIOD) + 1e-9:
            playback.add(samples[k], times[k])
            k += 1
        target, speed = playback.next(PERIOD)
        q, v = step_towards(q, v, target, speed, np.full(6, 3.0), np.full(6, 5.0), PERIOD)
        played.append(target[1])
        streamed.append(q[1])
        furthest.append(samples[:k, 1].max())
    return np.array(played), np.array(streamed), np.array(furthest)


def test_a_steady_stream_is_played_a_delay_later_at_its_own_speed():
    times, samples = ramp_to(0.5, 0.4, 2.0)
    played, streamed, _ = stream(times, samples, lambda wall: wall, len(times) + 60)

    def error(lag: int) -> float:  # from the trajectory delayed by `lag` cycles, rad
        expected = samples[np.minimum(np.arange(len(played) - lag), len(times) - 1), 1]
        return float(np.max(np.abs(played[lag:] - expected)))

    delay = round(0.08 / PERIOD)  # about 80 ms behind (docs/real_rig.md)
    assert min(error(lag) for lag in range(delay - 2, delay + 3)) < 1e-4
    assert streamed[-1] == pytest.approx(0.5, abs=1e-6)


@pytest.mark.parametrize("gap", [0.02, 0.05, 0.1, 0.2])
def test_bursts_of_samples_neither_overshoot_nor_stop_short(gap):
    """The diagram delivers its samples every `gap` s; a fast move still ends on its goal
    without running past it, and the played target never passes the newest sample."""
    times, samples = ramp_to(1.0, 2.5, 4.8)
    played, streamed, furthest = stream(times, samples,
                                        lambda wall: np.floor(wall / gap) * gap,
                                        len(times) + 200)
    assert np.all(played <= furthest + 1e-9)
    assert streamed.max() < 1.0 + 0.005
    assert streamed[-1] == pytest.approx(1.0, abs=1e-6)


def test_a_diagram_behind_wall_time_is_followed_at_its_pace():
    times, samples = ramp_to(0.6, 0.3, 2.0)
    played, _, furthest = stream(times, samples, lambda wall: 0.7 * wall,
                                 round(times[-1] / 0.7 / PERIOD) + 100)
    settled = slice(len(played) // 3, 2 * len(played) // 3)
    # Steady: the playback neither runs dry (stopping the arm) nor falls further behind.
    assert np.all(np.diff(played[settled]) > 0.0)
    assert np.all(played[settled] < furthest[settled])
    assert played[-1] == pytest.approx(0.6)


def test_an_earlier_sample_starts_the_playback_over():
    playback = TargetPlayback()
    for k in range(40):
        playback.add(np.full(6, 0.01 * k), 5.0 + k * PERIOD)
        playback.next(PERIOD)
    playback.add(np.zeros(6), 0.0)
    target, speed = playback.next(PERIOD)
    assert np.all(target == 0.0) and np.all(speed == 0.0)


@pytest.mark.parametrize("lag", [0.0, 0.02, 0.1])
def test_a_reference_behind_a_braking_target_stops_on_it_without_overrunning(lag):
    """The streamed target cruises at 2 rad/s and brakes at the acceleration limit onto
    1.0 rad; the reference starts `lag` rad behind it (a burst, a stall) yet never passes
    the target's end by more than 2 mrad (the braking is sampled, the target's speed a
    finite difference; without the stopping-point bound it ran 0.28 rad past), and stops
    on it."""
    times, samples = ramp_to(1.0, 2.0, 5.0)
    velocity = np.gradient(samples[:, 1], PERIOD)
    q, v = samples[0].copy(), np.zeros(6)
    q[1] -= lag
    path = []
    for k in range(len(times) + 100):
        i = min(k, len(times) - 1)
        q, v = step_towards(q, v, samples[i], np.array([0, velocity[i] if k < len(times)
                                                        else 0.0, 0, 0, 0, 0]),
                            np.full(6, 3.0), np.full(6, 5.0), PERIOD)
        path.append(q[1])
    assert max(path) <= 1.0 + 0.002
    assert path[-1] == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("speed", [3.0, 0.3])
def test_a_joint_sent_to_a_standing_target_never_passes_it(speed):
    """From rest towards a target that stands still, at the emulated arm's acceleration
    limit (5 rad/s²): the reference only ever moves towards the target and comes to rest on
    it. Before, a last exact step taken at up to 0.12 rad/s overran it and the joint swung
    about it for 15 periods, showing the arm 'arrived' while it still moved."""
    for goal in np.geomspace(1e-3, 2.0, 80):
        _, samples = ramp_to(goal, speed, 5.0)
        path = samples[:, 1]
        assert np.all(np.diff(path) >= 0.0), f"{goal} rad: the reference turned back"
        assert path.max() <= goal, f"{goal} rad: passed by {path.max() - goal} rad"
        assert path[-1] == goal
