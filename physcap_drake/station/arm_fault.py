"""The error a station raises when the arm itself stops."""


class ArmFault(RuntimeError):
    """The arm reported an error state (emergency stop, joint communication error, collision,
    limit) or its feedback was lost for too long. Motion commands have stopped and the arm
    holds; the episode ends. Not a skill error: no retry can fix it from software."""
