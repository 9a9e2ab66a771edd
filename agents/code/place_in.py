print("THOUGHT: $thought | ACTION: $action_text")
# Grasped from above, set down at a free spot of the destination, clear of its walls.
place_in("$destination", "$name")
breakpoint_code_block()
