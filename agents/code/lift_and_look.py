print("THOUGHT: $thought | ACTION: $action_text")
grasp = get_object_pose("$name")
# Set down at a free spot of the destination, clear of what already stands there.
found = lift_and_look(grasp, "$name", "$destination")
print(f"FOUND under the $name: {', '.join(found) or 'nothing'}")
breakpoint_code_block()
