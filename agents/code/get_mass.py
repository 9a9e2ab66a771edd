import math

print("THOUGHT: $thought | ACTION: weigh the $name")
position = get_object_pose("$name")
try:
    mass = get_mass(position, "$name")
except SkillFailed as error:  # nothing there to weigh (no contact)
    print(f"the $name was not found where expected: {error}")
    mass = math.nan
if math.isnan(mass):
    print("MEASURED: the mass of the $name could not be measured")
else:
    print(f"MEASURED: $name mass = {mass:.3f} kg")
home_pose()
breakpoint_code_block()
