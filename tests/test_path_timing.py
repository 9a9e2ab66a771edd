"""The closed-form TOPP-RA (`control/path_timing.py`) against Drake's `Toppra`, and the
trajectories `time_parameterize` builds from it."""

import numpy as np
import pytest
from pydrake.multibody.optimization import CalcGridPointsOptions, Toppra
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import RevoluteJoint, SpatialInertia

from physcap_drake.control.path_timing import time_optimal_timing
from physcap_drake.control.trajectories import joint_path, peak_rates, time_parameterize

SPEED, ACCELERATION = 3.0, 5.0   # the PiPER's limits, rad/s and rad/s²


def six_joint_chain() -> MultibodyPlant:
    """Drake's Toppra wants a plant with as many positions as the path has rows."""
    plant = MultibodyPlant(time_step=0.0)
    parent = plant.world_body()
    for i in range(6):
        body = plant.AddRigidBody(f"link{i}", SpatialInertia.SolidBoxWithMass(1.0, 0.1, 0.1, 0.1))
        plant.AddJoint(RevoluteJoint(f"joint{i}", parent.body_frame(), body.body_frame(),
                                     [0.0, 0.0, 1.0]))
        parent = body
    plant.Finalize()
    return plant


def random_paths(count: int, seed: int):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        waypoints = np.cumsum(rng.normal(0.0, 0.6, (6, int(rng.integers(2, 8)))), axis=1)
        yield joint_path(waypoints)


def test_the_timing_equals_drakes_toppra_on_random_paths():
    plant = six_joint_chain()
    for path in random_paths(12, seed=3):
        grid = Toppra.CalcGridPoints(path, CalcGridPointsOptions())
        toppra = Toppra(path, plant, grid)
        toppra.AddJointVelocityLimit(np.full(6, -SPEED), np.full(6, SPEED))
        toppra.AddJointAccelerationLimit(np.full(6, -ACCELERATION), np.full(6, ACCELERATION))
        reference = toppra.SolvePathParameterization()
        ours = time_optimal_timing(path, grid, max_velocity=SPEED,
                                   max_acceleration=ACCELERATION)
        np.testing.assert_allclose(ours.get_segment_times(), reference.get_segment_times(),
                                   rtol=0, atol=1e-9)
        times = np.linspace(0.0, reference.end_time(), 300)
        np.testing.assert_allclose(ours.vector_values(times), reference.vector_values(times),
                                   rtol=0, atol=1e-9)


def test_a_long_straight_move_accelerates_cruises_and_brakes():
    """2 rad on one joint: 0.6 s to reach 3 rad/s, 0.067 s at speed, 0.6 s to stop
    (1.267 s); the grid enforces the limits at its knots only, so a little slower."""
    path = joint_path(np.array([[0.0, 2.0]] + [[0.0, 0.0]] * 5))
    timing = time_optimal_timing(path, Toppra.CalcGridPoints(path, CalcGridPointsOptions()),
                                 max_velocity=SPEED, max_acceleration=ACCELERATION)
    assert 2.0 / SPEED + SPEED / ACCELERATION <= timing.end_time() < 1.267 * 1.01
    speed = 2.0 * timing.MakeDerivative(1).vector_values(
        np.linspace(0, timing.end_time(), 400))
    assert speed.max() == pytest.approx(SPEED, rel=1e-3)


def test_time_parameterize_starts_and_ends_at_rest_within_the_limits():
    for path in random_paths(8, seed=11):
        waypoints = path.vector_values(path.get_segment_times())
        trajectory = time_parameterize(waypoints, max_velocity=SPEED,
                                       max_acceleration=ACCELERATION)
        velocity, acceleration = peak_rates(trajectory)
        assert velocity <= SPEED and acceleration <= ACCELERATION
        np.testing.assert_allclose(trajectory.value(trajectory.start_time()).ravel(),
                                   waypoints[:, 0], atol=1e-9)
        np.testing.assert_allclose(trajectory.value(trajectory.end_time()).ravel(),
                                   waypoints[:, -1], atol=1e-9)
        for t in (trajectory.start_time(), trajectory.end_time()):
            assert np.abs(trajectory.EvalDerivative(t, 1)).max() < 1e-6


def test_gridpoints_must_span_the_path_and_increase():
    path = joint_path(np.array([[0.0, 1.0]] * 6))
    with pytest.raises(ValueError, match=r"span the path \[0.0, 1.0\], got \[0.0, 0.5\]"):
        time_optimal_timing(path, np.array([0.0, 0.5]), max_velocity=SPEED,
                            max_acceleration=ACCELERATION)
    with pytest.raises(ValueError, match="strictly increasing"):
        time_optimal_timing(path, np.array([0.0, 0.6, 0.6, 1.0]), max_velocity=SPEED,
                            max_acceleration=ACCELERATION)
