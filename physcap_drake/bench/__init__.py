"""Benchmarks: commands that print figures (real-time factor, errors, success rates)."""
