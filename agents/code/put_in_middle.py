import numpy as np

print("THOUGHT: $thought | ACTION: $action_text")
grasp = get_object_pose("$name")
destination = get_object_pose("$destination")
open_gripper()
goto_pose(grasp, z_approach=0.12)
close_gripper()
goto_pose(grasp + np.array([0.0, 0.0, 0.15]))
# Into the middle of the (empty) destination, at its own grasp height above the floor
# (about 15 mm up): free_spot's spot by the wall leaves the open fingers no room in a basket.
place = np.array([destination[0], destination[1], grasp[2] + 0.015])
goto_pose(place, z_approach=0.12)
open_gripper()
goto_pose(place + np.array([0.0, 0.0, 0.12]))
home_pose()
breakpoint_code_block()
