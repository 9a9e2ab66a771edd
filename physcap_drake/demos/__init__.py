"""Scripted demonstrations of the robot skills (no agent involved)."""
