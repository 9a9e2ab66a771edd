"""Meshcat on a CAN station: the robot is drawn where the arm says its joints are."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.geometry import Meshcat
from pydrake.multibody.plant import MultibodyPlant

from physcap_drake.clock import Clock
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.station.can_station import close_can_station
from physcap_drake.station.robot_model import add_directives
from physcap_drake.station_commands import build_commanded_station

pytestmark = pytest.mark.emulated_hardware


def test_the_drawn_robot_stands_where_the_emulated_world_has_it():
    scenario = load_scenario(stations_dir() / "identify_empty_can_piper_can.yaml")
    meshcat = Meshcat()
    target = np.array([0.5, 0.8, -0.6, 0.0, 0.3, 0.0])
    diagram, station = build_commanded_station(scenario, meshcat=meshcat,
                                               arm_position=target)
    try:
        clock = Clock(diagram, scenario.simulator_config)
        clock.run_for(3.0)
        context = station.GetMyContextFromRoot(clock.context)
        measured = station.GetOutputPort("piper.position_measured").Eval(context)
        np.testing.assert_allclose(measured, target, atol=1e-3)
        # Where the view's scene graph puts link6, against the emulated world's own plant.
        view = station.GetSubsystemByName("view_scene_graph")
        query = view.get_query_output_port().Eval(view.GetMyContextFromRoot(clock.context))
        inspector = query.inspector()
        frame = next(f for f in inspector.GetAllFrameIds()
                     if inspector.GetName(f) == "piper::link6")
        drawn = query.GetPoseInWorld(frame).translation()
        poses = station.GetOutputPort("body_poses").Eval(context)
        plant = MultibodyPlant(time_step=0.0)
        add_directives(plant, scenario.directives)  # the emulated world's bodies, in order
        plant.Finalize()
        link6 = plant.GetBodyByName("link6", plant.GetModelInstanceByName("piper"))
        np.testing.assert_allclose(drawn, poses[int(link6.index())].translation(), atol=2e-3)
        assert np.linalg.norm(drawn - poses[0].translation()) > 0.1  # not at the origin
        assert meshcat.HasPath("/drake/visualizer/piper")
    finally:
        close_can_station(station)
