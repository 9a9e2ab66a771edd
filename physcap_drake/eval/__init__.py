"""The evaluation harness: the grid of tasks × agent variants × trials, and its tables."""
