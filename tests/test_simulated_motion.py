"""SimulatedMotion (the emulated arm's world): a step that leaves the world non-finite fails
at once, naming itself and the coordinates that went non-finite."""

import numpy as np
import pytest
from pydrake.math import RigidTransform

from physcap_drake.can.motion import MotionCommand
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.station.simulated_motion import simulated_motion


@pytest.fixture(scope="module")
def motion():
    return simulated_motion(load_scenario(stations_dir() / "identify_empty_can_piper_can.yaml"))


def test_a_step_that_leaves_a_non_finite_world_names_itself_and_the_coordinates(
        motion, monkeypatch):
    q0, _ = motion.initial_state()
    command = MotionCommand(q0, np.ones(6, bool), 0.05, 1.2, True)
    reading = motion.step(command, 0.005)
    assert np.isfinite(reading.q).all()
    # Physics that goes non-finite on one free body out of contact (as a flung can did; in
    # contact the solver would refuse it): a non-finite force on the tray's vertical velocity,
    # in a 5 ms step with one plant update (at 8 ms), so no geometry query sees the result.
    plant = motion.plant
    tray = plant.GetBodyByName("tray")  # in flight, out of contact (as a flung can)
    plant.SetFreeBodyPose(motion.plant_context, tray, RigidTransform([0.3, -0.3, 1.0]))
    index = plant.GetStateNames(False).index("tray_vz") - plant.num_positions()
    forces = np.zeros(plant.num_velocities())
    forces[index] = np.inf
    monkeypatch.setattr(motion, "_load_torque", lambda load: forces)
    with pytest.raises(RuntimeError, match=(
            r"world's state went non-finite \(tray_.*\) \[world step from "
            r"t = 0\.0050 s by 5 ms: .*gripper to 0\.0500 m at 15\.0 N\]")):
        motion.step(command, 0.005)
