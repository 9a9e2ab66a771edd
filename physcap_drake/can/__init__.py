"""The PiPER over CAN: the protocol (`codec`), the host's link (`link`, `feedback`, and the
streaming process `link_process`), and the emulated arm (`emulator`, `firmware`,
`firmware_settings`, `planner`, `end_pose`, `paths`, `motion`, `paced_world`, and its
process `emulator_process`; the simulated world behind it is `station.simulated_motion`,
built by `emulated_world`), with what joins them across processes (`socket_bus`,
`shared_block`, `child_process`, `realtime`) and the fault drills (`faults`)."""
