"""Errors of the robot skills. Their messages are shown to users and to generated code."""


class SkillError(RuntimeError):
    """A skill did not do what was asked."""


class SkillRefused(SkillError):
    """The request was rejected before any motion: invalid input, an unsafe or unreachable
    target, or limits that cannot be met. The robot did not move."""


class SkillFailed(SkillError):
    """The skill started but did not complete (timed out, blocked, or the station reported an
    error). The arm was stopped and holds where it is."""

