"""Perception: the objects in view from the camera (RGB-D perception from colour and depth,
or the simulator's label segmenter as an ablation), phrases resolved against them, their
grasp points, a judge of the final view, and camera calibration with a ChArUco board."""
