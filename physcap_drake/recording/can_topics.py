"""The messages of a CAN station's own topics (/piper/arm_status, /piper/link; see
`topics`) from the streaming link's latest publication (`can.link_process.LinkFeedback`)."""

from __future__ import annotations

from physcap_drake.can import codec
from physcap_drake.can.feedback import GRIPPER_FAULTS


def arm_status_message(feedback) -> dict:
    """physcap.ArmStatus: the arm as it reports itself (unknown fields before its first
    status frame)."""
    s = feedback.status
    message = {"enabled": [bool(on) for on in feedback.enabled],
               "driver_status": [int(b) for b in feedback.driver_status],
               "gripper_status": int(feedback.gripper_status),
               "gripper_errors": [what for bit, what in GRIPPER_FAULTS.items()
                                  if feedback.gripper_status & bit]}
    if s is None:
        return {"ctrl_mode": "unknown", "move_mode": "unknown", "arm_status": "unknown",
                "error_code": 0, **message}
    return {"ctrl_mode": codec.CTRL_MODE_NAMES.get(s.ctrl_mode, str(s.ctrl_mode)),
            "move_mode": codec.MOVE_MODE_NAMES.get(s.mode_feed, str(s.mode_feed)),
            "arm_status": s.state, "error_code": int(s.err_code), "errors": s.error,
            "teach_status": int(s.teach_status), "motion_status": int(s.motion_status),
            **message}


def link_message(feedback) -> dict:
    """physcap.LinkHealth: the watchdog's verdict and the link's figures."""
    health = feedback.health
    return {"stale": bool(health.stale), "reason": health.reason, "fault": health.fault,
            "watchdog_trips": int(feedback.stale_count),
            "commands_sent": int(feedback.commands_sent),
            "lost_fraction": float(feedback.lost_fraction), "late_s": float(feedback.late),
            "garbled_frames": int(feedback.garbled)}


def arm_feedback_of(station):
    """For a CAN station (its interface `piper_can`), a callable giving the link's latest
    publication once connected (None before); None for any other station."""
    if not station.HasSubsystemNamed("piper_can"):
        return None
    session = station.GetSubsystemByName("piper_can").session

    def latest():
        return session.link.feedback() if session.started else None

    return latest
