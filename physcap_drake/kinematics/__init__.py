"""Kinematics that needs no Drake: the vendor's DH forward kinematics and joint constants
(see `piper_dh`)."""
