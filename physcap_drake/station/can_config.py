"""Configuration of the real PiPER over CAN (`station: !PiperCan` in a scenario file).

The scenario schema accepts it so that scenario files for the real arm can be written and
checked today; `MakeStation` refuses it with a clear error until the CAN station exists.
"""

# No `from __future__ import annotations`: yaml_load_typed reads the field types at run time.
import dataclasses as dc

from physcap_drake.config_checks import ConfigChecker


@dc.dataclass
class PiperCan:
    """The real PiPER arm on a CAN bus (1 Mbit/s classic CAN, see `reference/piper.md` §2)."""

    # python-can interface: "socketcan" for the arm's USB adapter, "virtual" for the emulator.
    interface: str = "socketcan"
    # python-can channel, e.g. "can0".
    channel: str = "can0"
    # Rate at which joint targets are streamed in joint mode, Hz.
    control_rate: float = 200.0
    # Firmware version string such as "S-V1.8-2"; empty: read it from the arm (0x4AF).
    firmware: str = ""
    # Gripper stroke set on start-up with 0x47D, mm: 70 (V1 gripper) or 100 (V2 gripper).
    gripper_stroke_mm: int = 100

    def check(self, at: ConfigChecker) -> None:
        at.choice("interface", self.interface, ["socketcan", "virtual", "slcan", "gs_usb"])
        if not self.channel:
            at.fail("channel", "a CAN channel name such as 'can0'", "got an empty string")
        at.number("control_rate", self.control_rate, minimum=0.0, maximum=500.0,
                  open_minimum=True)
        at.choice("gripper_stroke_mm", self.gripper_stroke_mm, [70, 100])
