"""What an operator does with the arm outside an episode: read its state, stop it, resume it,
clear its errors (`physcap arm ...`).

`operator_link(scenario)` opens a PiperLink on the bus the scenario's `station: !PiperCan`
names, listening but not streaming (nothing is enabled, no target is sent). With
`emulate: true` it starts an emulated arm in this process, backed by the scenario's scene,
on the same virtual channel. `ArmReport` is what `physcap arm status` prints.
"""

from __future__ import annotations

import dataclasses as dc
import time
from contextlib import contextmanager

import can
import numpy as np

from physcap_drake.can import codec
from physcap_drake.can.feedback import ArmParameters
from physcap_drake.can.link import LinkSettings, PiperLink, StartupError
from physcap_drake.can.link_process import open_bus
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_session import EMULATED_FIRMWARE

#: Driver status bits (0x261-0x266 byte 5) that are faults, in words.
DRIVER_FAULTS = {codec.LOW_VOLTAGE: "low voltage", codec.MOTOR_OVERHEAT: "motor over-temperature",
                 codec.OVER_CURRENT: "over-current", codec.DRIVER_OVERHEAT:
                 "driver over-temperature", codec.COLLISION_TRIPPED: "collision protection",
                 codec.DRIVER_ERROR: "driver error", codec.STALL_TRIPPED: "stall protection"}


@contextmanager
def operator_link(scenario):
    """Yields an open (listening, not streaming) PiperLink to the scenario's arm; closes it
    (and an emulated arm) afterwards. Raises ValueError for a scenario without a PiperCan
    station, ConnectionError if the bus cannot be opened."""
    config = scenario.station
    if not isinstance(config, PiperCan):
        raise ValueError(f"station is !{type(config).__name__}; the arm commands need a "
                         "!PiperCan station (the real arm, or its emulator)")
    settings = LinkSettings.of(config)
    emulator = None
    if config.emulate:  # the one place `physcap arm` imports the emulator
        from physcap_drake.piper_emulator.emulator import PiperEmulator
        from physcap_drake.station.simulated_motion import simulated_motion

        emulator_bus = can.Bus(interface="virtual", channel=config.channel)
        emulator = PiperEmulator(emulator_bus, firmware=config.firmware or EMULATED_FIRMWARE,
                                 motion=simulated_motion(scenario),
                                 start=config.emulated_start).start()
    link = PiperLink(open_bus(settings), settings).open()
    try:
        yield link
    finally:
        link.close()
        if emulator is not None:
            emulator.stop()
            emulator.bus.shutdown()


@dc.dataclass(frozen=True)
class ArmReport:
    """The arm as it reports itself: firmware, status (0x2A1), which motors are enabled,
    joint positions (rad), its parameters, and what is wrong ("" if nothing)."""

    firmware: str
    status: codec.ArmStatus
    enabled: np.ndarray
    gripper_enabled: bool
    q: np.ndarray
    gripper_opening: float
    parameters: ArmParameters
    errors: str

    @property
    def summary(self) -> str:
        s = self.status
        return (f"{codec.CTRL_MODE_NAMES.get(s.ctrl_mode, s.ctrl_mode)}, "
                f"{codec.MOVE_MODE_NAMES.get(s.mode_feed, s.mode_feed)}, {s.state}")


def arm_report(link: PiperLink) -> ArmReport:
    """Asks the arm for everything it reports (StartupError if something does not come)."""
    firmware = link.read_firmware()
    parameters = link.read_parameters()
    link.read_status()
    link.read_drivers()  # the enable bits: a status read before them shows every motor off
    feedback = link.listener.snapshot()
    assert feedback.status is not None  # read_status waited for one
    problems = [feedback.status.error] if feedback.status.error else []
    for joint, bits in enumerate(feedback.driver_status):
        problems += [f"J{joint + 1} {what}" for bit, what in DRIVER_FAULTS.items() if bits & bit]
    return ArmReport(firmware, feedback.status, feedback.enabled,
                     bool(feedback.gripper_status & codec.ENABLED), feedback.q,
                     feedback.gripper_opening, parameters, "; ".join(problems))


#: `steady_joint_angles`: the two readings it compares are this far apart (s), and differ by
#: at most this much on every joint for the arm to count as still (rad, about 0.06°).
STEADY_INTERVAL = 0.2
STEADY_TOLERANCE = 1e-3


def steady_joint_angles(link: PiperLink) -> np.ndarray:
    """The joint angles J1..J6 (rad) the arm reports, read twice STEADY_INTERVAL apart;
    raises ValueError naming the joint if the arm moved in between (a view taken while the
    operator still moves the arm would pair an image with the wrong pose)."""
    first = link.read_joint_angles()
    time.sleep(STEADY_INTERVAL)
    second = link.read_joint_angles()
    moved = np.abs(second - first)
    if moved.max() > STEADY_TOLERANCE:
        joint = int(np.argmax(moved))
        raise ValueError(f"the arm moved while the view was taken (J{joint + 1} by "
                         f"{np.degrees(moved[joint]):.2f}°): hold it still and try again")
    return second


__all__ = ["ArmReport", "StartupError", "arm_report", "operator_link", "steady_joint_angles"]
