"""A CAN station's recording: the arm's status and the link's health, with their schemas."""

from __future__ import annotations

import time

import jsonschema
import pytest
from conftest import unique_channel

from physcap_drake.recording import topics
from physcap_drake.recording.json_schemas import agent_schemas
from physcap_drake.recording.mcap_recorder import make_mcap_recorder
from physcap_drake.recording.mcap_sink import McapSink
from physcap_drake.recording.reading import read_recording
from physcap_drake.robot_stack import build_robot_stack
from physcap_drake.scenario import load_scenario_text
from physcap_drake.station import close_station
from physcap_drake.station.can_station import can_session

pytestmark = pytest.mark.emulated_hardware

SCENE = """directives:
- add_directives: {file: package://physcap_models/piper/piper_100mm.dmd.yaml}
- add_model: {name: table, file: package://physcap_models/scene/table.sdf}
- add_weld: {parent: world, child: table::table_top}
simulator_config: {target_realtime_rate: 1.0}
cameras: [{name: camera, width: 64, height: 36, rgb: true, depth: true, label: true}]
"""


def test_arm_status_and_link_health_are_recorded_with_a_watchdog_trip(tmp_path):
    scenario = load_scenario_text(SCENE + "station: !PiperCan {interface: virtual, channel: "
                                  f"{unique_channel()}, emulate: true}}\n")
    sink = McapSink(tmp_path / "can.mcap")
    robot = build_robot_stack(scenario, make_recorder=lambda station: make_mcap_recorder(
        sink, station, scenario, image_period=0.0))
    try:
        clock = robot.make_clock()
        clock.run_for(0.5)
        link = can_session(robot.station).link
        # The feedback stops for a moment (between two runs): one watchdog trip.
        link.set_faults(silent=True)
        time.sleep(0.15)
        link.set_faults(silent=False)
        clock.run_for(0.5)
    finally:
        close_station(robot.station)
        sink.close()
    recorded = read_recording(tmp_path / "can.mcap")
    assert recorded.topics()[topics.ARM_STATUS] == "physcap.ArmStatus"
    assert recorded.topics()[topics.LINK] == "physcap.LinkHealth"
    schemas = agent_schemas()
    status = recorded.on(topics.ARM_STATUS)
    health = recorded.on(topics.LINK)
    assert len(status) > 10 and len(health) > 10
    for message in (*status, *health):
        jsonschema.validate(message.value, schemas[message.topic][1])
    last = status[-1].value
    assert (last["ctrl_mode"], last["move_mode"], last["arm_status"]) == (
        "CAN control", "MOVE J", "normal")
    assert last["enabled"] == [True] * 6 and last["error_code"] == 0
    trips = [m.value["watchdog_trips"] for m in health]
    assert trips[0] == 0 and trips[-1] >= 1
    assert not health[-1].value["stale"] and health[-1].value["lost_fraction"] <= 0.05
    sent = [m.value["commands_sent"] for m in health]
    assert sent[-1] > sent[0]
