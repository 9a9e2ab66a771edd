"""The PiPER's 11-bit CAN identifiers (piper_sdk 0.6.2 `CanIDPiper`, reference/piper.md §2).

Arm -> host: periodic feedback 0x2A1-0x2A8, driver feedback 0x251-0x256 / 0x261-0x266,
replies 0x473, 0x476, 0x478, 0x47B, 0x47C, 0x47E, 0x4AF, and (once enabled with 0x477)
joint end velocity/acceleration 0x481-0x486. Host -> arm: motion 0x150-0x15F, settings
and queries 0x470-0x47D, the firmware request 0x4AF and the leader-arm home request 0x191.
"""

from __future__ import annotations

# Arm -> host -------------------------------------------------------------------------------
ARM_STATUS = 0x2A1
END_POSE_FEEDBACK = (0x2A2, 0x2A3, 0x2A4)  # X/Y, Z/RX, RY/RZ
JOINT_FEEDBACK = (0x2A5, 0x2A6, 0x2A7)  # J1/J2, J3/J4, J5/J6
GRIPPER_FEEDBACK = 0x2A8
HIGH_SPEED = tuple(range(0x251, 0x257))  # J1..J6 driver speed, current, position
LOW_SPEED = tuple(range(0x261, 0x267))  # J1..J6 driver voltage, temperatures, status
LIMITS_REPLY = 0x473
INSTRUCTION_ACK = 0x476
END_LIMITS_REPLY = 0x478
CRASH_PROTECTION_REPLY = 0x47B
ACCELERATION_REPLY = 0x47C
GRIPPER_PARAMETERS_REPLY = 0x47E
JOINT_END_MOTION = tuple(range(0x481, 0x487))  # J1..J6 end velocity / acceleration
FIRMWARE = 0x4AF  # the request (host) and the reply (arm) share it

# Host -> arm -------------------------------------------------------------------------------
MOTION_CONTROL = 0x150
MODE_CONTROL = 0x151
END_POSE_COMMAND = (0x152, 0x153, 0x154)
JOINT_COMMAND = (0x155, 0x156, 0x157)
MOVE_C_POINT = 0x158
GRIPPER_COMMAND = 0x159
MIT_COMMAND = tuple(range(0x15A, 0x160))  # J1..J6
LEADER_HOME = 0x191
LINKAGE_CONFIG = 0x470
MOTOR_ENABLE = 0x471
LIMIT_QUERY = 0x472
LIMIT_SETTING = 0x474
JOINT_CONFIG = 0x475
PARAMETER_REQUEST = 0x477
END_LIMITS_SETTING = 0x479
CRASH_PROTECTION_SETTING = 0x47A
GRIPPER_PARAMETERS = 0x47D

#: Frames the arm sends every feedback cycle (the host's heartbeat).
PERIODIC_FEEDBACK = (ARM_STATUS, *END_POSE_FEEDBACK, *JOINT_FEEDBACK, GRIPPER_FEEDBACK,
                     *HIGH_SPEED)
#: Frames the linkage offsets of 0x470 move: feedback 0x2A1-0x2A8 (to 0x2B1-0x2B8 or
#: 0x2C1-0x2C8) and commands 0x150-0x159 (to 0x160-0x169 or 0x170-0x179).
OFFSET_FEEDBACK = (ARM_STATUS, *END_POSE_FEEDBACK, *JOINT_FEEDBACK, GRIPPER_FEEDBACK)
OFFSET_COMMANDS = (MOTION_CONTROL, MODE_CONTROL, *END_POSE_COMMAND, *JOINT_COMMAND,
                   MOVE_C_POINT, GRIPPER_COMMAND)
#: The offsets 0x470 may set (none, +0x10, +0x20).
ID_OFFSETS = (0x00, 0x10, 0x20)
