"""The PiPER over CAN, the host's side: the protocol (`codec`), the host's link (`link`,
`link_control`, `feedback`, `playback`, and the streaming process `link_process`), bringing a
bus up (`bring_up`), the buses (`socket_bus`, `unix_bus`), what joins processes
(`shared_block`, `child_process`, `realtime`), the joint profile both the link and the
emulated firmware follow (`joint_profile`), and the fault drills (`faults`). The emulated arm
is a package of its own, `physcap_drake.piper_emulator`."""
