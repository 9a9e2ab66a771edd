"""Robot skills: IK, limit-respecting trajectories, the gripper, a safety envelope, and the
SkillExecutor system that drives the station's inputs."""
