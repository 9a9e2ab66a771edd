"""Perception: from a referring expression to a pixel (a pointer), and from a pixel and the
depth image to a 3D point and a grasp point (camera geometry)."""
