"""PhysCaP as a Drake systems diagram around an AgileX PiPER arm."""

__version__ = "0.1.0"
