"""Composition: what builds and runs whole programs out of the systems below (an agent
episode, episode folders, replays, calibration runs, the sim runner, the demos). Nothing
below this package imports it (tests/test_layers.py)."""
