"""The PiPER CAN interface: the protocol codec (more to come with the CAN station)."""
