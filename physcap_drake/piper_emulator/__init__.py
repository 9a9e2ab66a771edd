"""A PiPER's firmware, emulated on a CAN bus: what the vendor's `piper_sdk` talks to when no
arm is there (see README.md here, and docs/piper_emulator.md).

`emulator` (the firmware loop on a bus), `firmware` and `firmware_settings` (the protocol's
answers and the arm's settings), `planner`, `paths`, `end_pose` (MOVE J/P/L/C), `arm_state`,
`motion` (the arm's world: kinematic, `arm_gravity`, or a simulated scene), `paced_world`,
`lateness`, and `emulator_process` (the emulator in a process of its own). It speaks the
protocol through `can.codec` and never imports the host's link.
"""
