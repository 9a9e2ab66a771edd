print("THOUGHT: $thought | ACTION: squeeze the $name")
position = get_object_pose("$name")
try:
    level = get_stiffness(position, "$name")
except SkillFailed as error:  # nothing there to squeeze (no contact)
    print(f"the $name was not found where expected: {error}")
    level = 0
if level == 0:
    print("MEASURED: the stiffness of the $name could not be measured")
else:
    print(f"MEASURED: $name stiffness level = {level}")
home_pose()
breakpoint_code_block()
