"""The port contract of MakeStation: exactly these names and sizes."""

from __future__ import annotations

import pytest
from conftest import unique_channel
from pydrake.systems.framework import PortDataType

from physcap_drake.station import MakeStation, close_station, ports
from physcap_drake.station.can_config import PiperCan

EXPECTED_INPUTS = {"piper.position": 6, "gripper.position": 1, "gripper.force_limit": 1}
EXPECTED_VECTOR_OUTPUTS = {
    "piper.position_measured": 6,
    "piper.velocity_estimated": 6,
    "piper.torque_measured": 6,
    "gripper.position_measured": 1,
    "gripper.effort_measured": 1,
}
EXPECTED_ABSTRACT_OUTPUTS = {"camera.rgb", "camera.depth", "camera.label", "body_poses",
                             "piper.fault"}


@pytest.fixture(params=["sim", pytest.param("can", marks=[
    pytest.mark.emulated_hardware, pytest.mark.xdist_group("realtime")])])
def any_station(request, table_scenario):
    """The sim station, and the CAN station over an emulator of the same scene."""
    if request.param == "can":
        table_scenario.station = PiperCan(interface="virtual", channel=unique_channel(),
                                          emulate=True)
    station = MakeStation(table_scenario)
    yield station
    close_station(station)


def test_ports_are_exactly_the_contract(any_station):
    station = any_station
    inputs = {station.get_input_port(i).get_name(): station.get_input_port(i)
              for i in range(station.num_input_ports())}
    outputs = {station.get_output_port(i).get_name(): station.get_output_port(i)
               for i in range(station.num_output_ports())}
    assert {name: port.size() for name, port in inputs.items()} == EXPECTED_INPUTS
    assert all(p.get_data_type() == PortDataType.kVectorValued for p in inputs.values())
    assert set(outputs) == set(EXPECTED_VECTOR_OUTPUTS) | EXPECTED_ABSTRACT_OUTPUTS
    for name, size in EXPECTED_VECTOR_OUTPUTS.items():
        assert outputs[name].get_data_type() == PortDataType.kVectorValued
        assert outputs[name].size() == size
    for name in EXPECTED_ABSTRACT_OUTPUTS:
        assert outputs[name].get_data_type() == PortDataType.kAbstractValued
    # The fault: a text, "" while there is none (before any event has run, on both).
    fault = outputs["piper.fault"]
    assert fault.Allocate().get_value() == ""
    assert fault.Eval(station.CreateDefaultContext()) == ""


def test_contract_constants_match_the_expected_names():
    assert ports.VECTOR_INPUTS == EXPECTED_INPUTS
    assert ports.VECTOR_OUTPUTS == EXPECTED_VECTOR_OUTPUTS
    assert set(ports.IMAGE_OUTPUTS) | {ports.BODY_POSES, ports.ARM_FAULT} == (
        EXPECTED_ABSTRACT_OUTPUTS)


def test_the_70mm_gripper_is_selectable(table_scenario):
    for directive in table_scenario.directives:
        if directive.add_directives is not None:
            directive.add_directives.file = directive.add_directives.file.replace("100mm", "70mm")
    station = MakeStation(table_scenario)
    plant = station.GetSubsystemByName("plant")
    finger = plant.GetJointByName("left_finger_joint")
    assert finger.position_upper_limits()[0] == 0.035
