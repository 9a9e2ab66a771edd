"""Showing a run to someone watching Meshcat: real-time pacing, and keeping the viewer open.

A simulation runs as fast as it can, often several times faster than life, and a command
ends (taking its Meshcat server with it) the moment its work is done. With `--meshcat` the
commands pace the simulator at real time (`pace_in_real_time`) and, at the end, keep the
server up (`hold_open`) until Enter is pressed, or for `--hold S` seconds.
"""

from __future__ import annotations

import sys
import time

from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator

from physcap_drake.commands.common import console


def pace_in_real_time(simulator: Simulator, rate: float = 1.0) -> None:
    """Makes `simulator` advance at most `rate` simulated seconds per wall-clock second
    (0: as fast as it can). Drake paces from the moment the statistics were last reset, so
    time spent outside AdvanceTo (a model answering) is caught up at full speed after."""
    simulator.set_target_realtime_rate(rate)
    simulator.ResetStatistics()


def hold_open(meshcat: Meshcat, hold_s: float | None) -> None:
    """Keeps the process, and so the Meshcat server, alive: `hold_s` seconds when given,
    else until Enter is pressed (when stdin is a terminal; a script is not held)."""
    url = meshcat.web_url()
    try:
        if hold_s is not None:
            console.print(f"Meshcat stays at {url} for {hold_s:g} s (Ctrl-C to quit)")
            time.sleep(hold_s)
        elif sys.stdin.isatty():
            console.input(f"Meshcat stays at {url} (replay it from its Animation panel); "
                          "press Enter to quit ")
        else:
            console.print("not holding Meshcat open: stdin is not a terminal (use --hold S)")
    except (KeyboardInterrupt, EOFError):
        pass
