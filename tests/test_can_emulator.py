"""The PiPER emulator on a python-can virtual bus, driven by the vendor's own SDK
(piper-sdk, a dev dependency) and by a raw python-can peer."""

from __future__ import annotations

import itertools
import time

import can
import numpy as np
import pytest

from physcap_drake.can import codec
from physcap_drake.can.emulator import PiperEmulator, wait_until

piper_sdk = pytest.importorskip("piper_sdk")
_names = itertools.count()


@pytest.fixture
def channel():
    return f"piper_test_{next(_names)}"  # the SDK keeps one interface per channel name


@pytest.fixture
def emulator(channel):
    bus = can.Bus(interface="virtual", channel=channel)
    emulator = PiperEmulator(bus, gravity_torque=lambda q: np.array(
        [0.0, 2.73, -4.65, 0.0, -0.86, 0.0])).start()
    yield emulator
    emulator.stop()
    bus.shutdown()


def connect_sdk(channel: str):
    piper = piper_sdk.C_PiperInterface_V2(can_name=channel, judge_flag=False,
                                          can_auto_init=False)
    piper.CreateCanBus(channel, bustype="virtual", judge_flag=False)
    piper.ConnectPort(piper_init=False)
    return piper


def test_the_vendor_sdk_enables_commands_and_reads_back(emulator, channel):
    piper = connect_sdk(channel)
    try:
        assert wait_until(lambda: (piper.EnableArm(7), all(piper.GetArmEnableStatus()))[1],
                          timeout=3.0)
        piper.GripperTeachingPendantParamConfig(100, 100, 1)  # a new gripper: stroke 100 mm
        piper.MotionCtrl_2(0x01, 0x01, 100, 0x00)  # CAN control, joint mode, 100 % speed
        target = [20000, 30000, -25000, 10000, 15000, -5000]  # 0.001°
        deadline = time.monotonic() + 1.5
        while time.monotonic() < deadline:
            piper.JointCtrl(*target)
            time.sleep(0.005)
        piper.GripperCtrl(50000, 1000, 0x01, 0)  # 50 mm, 1 N·m, enable
        joints = piper.GetArmJointMsgs().joint_state
        assert wait_until(lambda: piper.GetArmGripperMsgs().gripper_state.grippers_angle
                          == 50000, timeout=2.0)
        assert [joints.joint_1, joints.joint_2, joints.joint_3, joints.joint_4, joints.joint_5,
                joints.joint_6] == target
        gripper = piper.GetArmGripperMsgs().gripper_state
        assert gripper.grippers_effort == 1000 and gripper.foc_status.driver_enable_status
        status = piper.GetArmStatus().arm_status
        assert status.ctrl_mode == 1 and status.arm_status == 0 and status.mode_feed == 1
        np.testing.assert_allclose(emulator.snapshot().q, np.radians(np.array(target) / 1000.0),
                                   atol=1e-6)
        # Holding torques arrive as motor currents, scaled for firmware S-V1.8-2 (×4 on J1-J3).
        j2 = piper.GetArmHighSpdInfoMsgs().motor_2
        assert j2.current / 1000.0 * 1.18125 * 4 == pytest.approx(2.73, abs=0.01)
    finally:
        piper.DisconnectPort()


def test_a_raw_peer_reads_firmware_limits_and_the_emergency_stop(emulator, channel):
    bus = can.Bus(interface="virtual", channel=channel)
    try:
        def send(frame):
            bus.send(can.Message(arbitration_id=frame[0], data=frame[1], is_extended_id=False))

        def collect(identifier, count=1, timeout=1.0):
            found, deadline = [], time.monotonic() + timeout
            while len(found) < count and time.monotonic() < deadline:
                message = bus.recv(timeout=0.05)
                if message is not None and message.arbitration_id == identifier:
                    found.append(bytes(message.data))
            return found

        send(codec.encode_firmware_request())
        assert codec.decode_firmware(collect(codec.FIRMWARE, 2)) == "S-V1.8-2"
        send(codec.encode_limit_query(2))
        limits = codec.decode_joint_limits(collect(codec.LIMITS_REPLY)[0])
        assert limits.motor == 2 and limits.max_angle == pytest.approx(np.pi, abs=1e-3)
        send(codec.encode_motion_control(emergency=1))
        assert wait_until(lambda: emulator.snapshot().arm_status == 1)
        statuses = [codec.decode_arm_status(d) for d in collect(codec.ARM_STATUS, 50)]
        assert statuses[-1].error == "emergency stop"  # the arm now reports it
    finally:
        bus.shutdown()
