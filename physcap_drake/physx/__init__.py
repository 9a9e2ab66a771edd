"""PhysX: physical property extraction from the arm's own sensing (mass from joint torques,
stiffness from gripper effort versus finger travel)."""
