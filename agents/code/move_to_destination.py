import numpy as np

print("THOUGHT: $thought | ACTION: $action_text")
grasp = get_object_pose("$name") + np.array([0.0, 0.0, $raise_by])
destination = get_object_pose("$destination")
open_gripper()
goto_pose(grasp, z_approach=0.12)
close_gripper()
goto_pose(grasp + np.array([0.0, 0.0, 0.15]))
# Set it down at its own grasp height above the destination's floor (about 15 mm up).
place = np.array([destination[0]$dx, destination[1]$dy, grasp[2] + 0.015])
goto_pose(place, z_approach=0.12)
open_gripper()
goto_pose(place + np.array([0.0, 0.0, 0.12]))
home_pose()
breakpoint_code_block()
