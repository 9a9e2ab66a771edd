print("THOUGHT: $thought | ACTION: squeeze the $name")
position = get_object_pose("$name")
level = get_stiffness(position, "$name")
if level == 0:
    print("MEASURED: the stiffness of the $name could not be measured")
else:
    print(f"MEASURED: $name stiffness level = {level}")
home_pose()
breakpoint_code_block()
