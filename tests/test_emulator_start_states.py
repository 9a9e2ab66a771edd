"""The emulated PiPER's start states, read and driven through the vendor's SDK as a host
would: drag-teach (motion ignored until reset), a linkage's leader (no joint feedback,
control frames instead), stuck in standby (every mode frame dropped until reset), lossy
(the first mode frame lost); and the normal start on the other side of each."""

from __future__ import annotations

import time

import numpy as np
import pytest
from piper_sdk_peer import MDEG, enable, joints, sdk_with_emulator, settled, status, stream

from physcap_drake.can import codec
from physcap_drake.can.socket_bus import SocketBus, socket_pair
from physcap_drake.config_checks import ConfigChecker
from physcap_drake.piper_emulator.emulator import wait_until
from physcap_drake.piper_emulator.emulator_process import EmulatorProcess
from physcap_drake.piper_emulator.firmware import START_STATES, Firmware
from physcap_drake.piper_emulator.motion import KinematicMotion
from physcap_drake.scenario_errors import ScenarioError
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_operator import arm_report, operator_link
from physcap_drake.station.can_session import CanSession

pytestmark = [pytest.mark.emulated_hardware,
              pytest.mark.filterwarnings("ignore:The .bustype. argument is deprecated")]
READY = np.array([0.0, 1.2, -1.2, 0.0, 0.6, 0.0])
MOVED = READY + [0.2, 0.0, 0.0, 0.0, 0.0, 0.0]


def started(start: str):
    return sdk_with_emulator(motion=KinematicMotion(q0=READY), start=start)


def control_confirmed(sdk) -> bool:
    s = status(sdk)
    return s.ctrl_mode == 1 and s.mode_feed == 1


def test_an_unknown_start_state_is_refused_naming_the_states():
    with pytest.raises(ValueError, match="'drag'.*normal, teach, leader, standby, lossy"):
        Firmware(KinematicMotion(), start="drag")
    assert START_STATES == ("normal", "teach", "leader", "standby", "lossy")


def test_a_scenario_names_a_bad_start_state_by_its_field():
    PiperCan(interface="virtual", emulate=True, emulated_start="leader").check(
        ConfigChecker("s.yaml", "station"))
    with pytest.raises(ScenarioError, match="station.emulated_start") as error:
        PiperCan(interface="virtual", emulate=True, emulated_start="drag").check(
            ConfigChecker("s.yaml", "station"))
    assert "'teach'" in str(error.value) and "'drag'" in str(error.value)
    with pytest.raises(ScenarioError, match="station.emulated_start.*emulate: false"):
        PiperCan(interface="socketcan", emulated_start="teach").check(
            ConfigChecker("s.yaml", "station"))


def test_a_normal_arm_confirms_can_control_at_once_and_follows_targets():
    with started("normal") as (sdk, _):
        enable(sdk, speed=30)
        assert wait_until(lambda: control_confirmed(sdk))
        assert stream(sdk, MOVED, lambda: np.allclose(joints(sdk), MOVED, atol=1e-5))


def test_an_arm_in_drag_teach_ignores_can_motion_until_reset():
    with started("teach") as (sdk, _):
        assert wait_until(lambda: status(sdk).ctrl_mode == 2)  # teaching mode
        s = status(sdk)
        assert (s.arm_status, s.teach_status) == (0x0B, 1)  # recording, drag teaching
        enable(sdk, speed=30)
        stream(sdk, MOVED, lambda: False, timeout=0.3)
        assert settled(sdk)
        s = status(sdk)
        assert (s.ctrl_mode, s.arm_status, s.teach_status) == (2, 0x0B, 1)
        np.testing.assert_allclose(joints(sdk), READY, atol=1e-5)
        sdk.EmergencyStop(0x02)  # the reset: out of drag-teach, standby, motors off
        assert wait_until(lambda: status(sdk).ctrl_mode == 0 and status(sdk).teach_status == 0
                          and status(sdk).arm_status == 0)
        enable(sdk, speed=30)
        assert wait_until(lambda: control_confirmed(sdk))
        assert stream(sdk, MOVED, lambda: np.allclose(joints(sdk), MOVED, atol=1e-5))


def test_a_leader_arm_sends_control_frames_and_no_joint_feedback():
    with started("leader") as (sdk, emulator):
        # It sends its joints as targets for its followers (0x155-0x157) and their mode.
        assert wait_until(lambda: sdk.GetArmJointCtrl().time_stamp > 0)
        target = sdk.GetArmJointCtrl().joint_ctrl
        np.testing.assert_allclose(np.array([target.joint_1, target.joint_2, target.joint_3,
                                             target.joint_4, target.joint_5, target.joint_6])
                                   / MDEG, READY, atol=1e-3)
        assert wait_until(lambda: sdk.GetArmModeCtrl().time_stamp > 0)
        assert wait_until(lambda: status(sdk).ctrl_mode == 6)  # linkage teaching input
        enable(sdk, speed=30)
        stream(sdk, MOVED, lambda: False, timeout=0.3)
        assert settled(sdk)
        assert status(sdk).ctrl_mode == 6
        assert sdk.GetArmJointMsgs().time_stamp == 0  # never a joint feedback frame
        assert sdk.GetArmEndPoseMsgs().time_stamp == 0
        np.testing.assert_allclose(emulator.snapshot().q, READY, atol=1e-9)  # it held still
        sdk.EmergencyStop(0x02)  # a reset does not change its role
        assert settled(sdk)
        assert status(sdk).ctrl_mode == 6
    with started("normal") as (sdk, _):  # the other side: a normal arm sends its joints
        assert wait_until(lambda: sdk.GetArmJointMsgs().time_stamp > 0)
        assert settled(sdk)
        assert sdk.GetArmJointCtrl().time_stamp == 0


def test_a_standby_arm_drops_every_mode_frame_until_it_is_reset():
    with started("standby") as (sdk, _):
        enable(sdk, speed=30)
        for _ in range(5):  # a host resending the mode frame, as start-up does
            sdk.MotionCtrl_2(0x01, 0x01, 30, 0x00)
            time.sleep(0.02)
        stream(sdk, MOVED, lambda: False, timeout=0.3)
        assert settled(sdk)
        assert (status(sdk).ctrl_mode, status(sdk).mode_feed) == (0, 0)  # still standby
        np.testing.assert_allclose(joints(sdk), READY, atol=1e-5)
        sdk.MotionCtrl_1(0x02, 0, 0)  # the vendor's reset (piper_ctrl_reset.py)
        assert wait_until(lambda: not any(sdk.GetArmEnableStatus()))  # motors off
        enable(sdk, speed=30)
        assert wait_until(lambda: control_confirmed(sdk))
        assert stream(sdk, MOVED, lambda: np.allclose(joints(sdk), MOVED, atol=1e-5))


def test_a_lossy_arm_loses_the_first_mode_frame_and_takes_the_second():
    with started("lossy") as (sdk, _):
        enable(sdk, speed=30)  # its mode frame is lost
        assert settled(sdk)
        assert status(sdk).ctrl_mode == 0  # still standby
        sdk.MotionCtrl_2(0x01, 0x01, 30, 0x00)  # sent again, as a host confirming control
        assert wait_until(lambda: control_confirmed(sdk))
        assert stream(sdk, MOVED, lambda: np.allclose(joints(sdk), MOVED, atol=1e-5))


def test_the_emulator_process_starts_in_the_state_asked_for():
    emulator_end, host_end = socket_pair()
    with pytest.raises(ValueError, match="'drag'"):
        EmulatorProcess(emulator_end, start="drag")
    host_end.close()
    emulator_end, host_end = socket_pair()
    emulator = EmulatorProcess(emulator_end, start="leader").wait_ready()
    host = SocketBus(host_end, "host")
    try:
        seen = {}  # identifier: data of every frame in a second of its feedback
        deadline = time.monotonic() + 1.0
        while time.monotonic() < deadline:
            message = host.recv(timeout=0.1)
            if message is not None:
                seen[message.arbitration_id] = bytes(message.data)
        assert codec.decode_arm_status(seen[codec.ARM_STATUS]).ctrl_mode == 6
        assert not set(codec.JOINT_FEEDBACK) & set(seen)
        assert set(codec.JOINT_COMMAND) <= set(seen)
    finally:
        host.shutdown()
        emulator.close()


def test_an_emulated_station_starts_its_arm_in_the_scenarios_state(table_scenario):
    table_scenario.station = PiperCan(interface="virtual", emulate=True,
                                      emulated_start="teach")
    session = CanSession(table_scenario).wait_ready()  # the emulated arm runs, unconnected
    try:
        arm = session.emulator.snapshot()
        assert (arm.ctrl_mode, arm.arm_status, arm.teach_status) == (2, 0x0B, 1)
    finally:
        session.close()


def test_the_operators_emulated_arm_starts_in_the_scenarios_state(table_scenario):
    table_scenario.station = PiperCan(interface="virtual", channel="operator_leader",
                                      emulate=True, emulated_start="leader")
    with operator_link(table_scenario) as link:
        assert arm_report(link).status.ctrl_mode == 6
