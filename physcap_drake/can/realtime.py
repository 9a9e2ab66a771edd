"""Real-time scheduling for the processes that stand between the host and the arm.

Design notes: docs/design/can.md.
"""

from __future__ import annotations

import logging
import os

log = logging.getLogger("physcap_drake.can")


def use_realtime(priority: int, who: str) -> bool:
    """Switches the calling thread to SCHED_RR at `priority` (1-99; 0 leaves the scheduling
    as it is). Returns whether it runs real-time now; logs a warning naming `who` if the
    system refused."""
    if priority <= 0:
        return False
    try:
        os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(priority))
    except (PermissionError, OSError, AttributeError) as error:
        log.warning("%s keeps normal scheduling: real-time priority %d was refused (%s); "
                    "on a busy machine its period can stretch (grant CAP_SYS_NICE, see "
                    "physcap_drake/can/realtime.py)", who, priority, error)
        return False
    return True
