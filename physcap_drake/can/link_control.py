"""The steps of taking control of a PiPER that wait for the arm to show they took effect.

`ControlSteps` is a part of PiperLink (it uses the link's listener, `_send` and
`_wait_for`): `check_ready()` refuses an arm that is silent, in drag-teach, a leader, or
sends no joint feedback; `take_control()` sends the mode frame (0x151: CAN control, MOVE J,
the station's speed) until the arm's status (0x2A1) reports both (one that stays in standby
is to be reset); `set_collision_level` and `set_gripper_stroke` write a setting only when
the arm's differs, and read it back;
`enable()` / `disable()` switch the motors until every driver reports it. Each failure is
a StartupError whose one line names the state and what to do.
"""

from __future__ import annotations

import time

import numpy as np

from physcap_drake.can import codec

#: ctrl_mode and move mode of streaming joint targets (0x151, 0x2A1).
CAN_CONTROL, MOVE_J = 1, 1
#: ctrl_mode of an arm in standby, and of one in drag-teach.
STANDBY, TEACH_MODE = 0, 2
#: Interval between enable (or disable) commands until the drivers report it, s.
ENABLE_RETRY = 0.05
#: How to leave drag-teach, and to make a leader arm a follower again.
LEAVE_TEACH = ("press the teach button on the arm's base to end drag-teach (or `physcap arm "
               "resume --yes` with the arm supported), then try again")
#: How owners get an arm out of standby (docs/real_rig.md).
RESET_STANDBY = ("support the arm and reset it (`physcap arm resume --yes`, 0x150 = 2 as the "
                 "vendor's piper_ctrl_reset.py: the motors lose power), then try again; "
                 "power-cycle it if it stays in standby")
MAKE_FOLLOWER = ("make it a follower (piper_sdk: MasterSlaveConfig(0xFC, 0, 0, 0)), "
                 "power-cycle it, then try again")


class StartupError(RuntimeError):
    """The arm did not answer, or did not do what it was asked, in time."""


class ControlSteps:
    """See module docstring (a mixin of PiperLink)."""

    def check_ready(self) -> None:
        """Refuses (StartupError) an arm that sends nothing, is in drag-teach or is a leader
        arm, or sends no joint feedback, within station.startup_timeout."""
        timeout = self.config.startup_timeout
        deadline = time.monotonic() + timeout
        while not self.listener.heard() and time.monotonic() < deadline:
            time.sleep(0.005)
        if not self.listener.heard():
            self.close()
            raise StartupError(f"no frames from the arm on {self.where} within "
                               f"station.startup_timeout = {timeout} s: power the arm on "
                               "(the switch on its base), check the CAN cable and that the "
                               f"bus runs at {self.config.bitrate} bit/s")
        while not self.listener.complete() and time.monotonic() < deadline:
            self._refuse_teach_or_leader()
            time.sleep(0.005)
        self._refuse_teach_or_leader()
        if not self.listener.complete():
            self.close()
            raise StartupError(f"the arm on {self.where} sends no joint feedback (0x2A5-0x2A8) "
                               f"within station.startup_timeout = {timeout} s: power-cycle "
                               "it; if it stays so, it may be set up as a leader arm: "
                               + MAKE_FOLLOWER)

    def _refuse_teach_or_leader(self) -> None:
        status = self.listener.snapshot().status
        if status is not None and (status.ctrl_mode == TEACH_MODE
                                   or status.arm_status in codec.TEACH_STATES):
            self.close()
            raise StartupError(f"the arm on {self.where} is in drag-teach ({status.state}): "
                               + LEAVE_TEACH)
        if self.listener.role() == "leader":
            self.close()
            raise StartupError(f"the arm on {self.where} is a leader (teach-input) arm: it "
                               "sends targets for a follower and takes no commands: "
                               + MAKE_FOLLOWER)

    def take_control(self) -> None:
        """Sends the mode frame until the arm reports CAN control and MOVE J."""
        def confirmed():
            status = self.listener.snapshot().status
            if status is not None and (status.ctrl_mode == TEACH_MODE
                                       or status.arm_status in codec.TEACH_STATES):
                self._refuse_teach_or_leader()
            ok = (status is not None and status.ctrl_mode == CAN_CONTROL
                  and status.mode_feed == MOVE_J)
            return True if ok else None

        try:
            self._wait_for(confirmed, "CAN control in MOVE J (0x2A1 after 0x151)",
                           ask=lambda: self._send(*self.mode_frame()))
        except StartupError:
            # The arm in drag-teach or leading (seen only now, under load): named as such.
            self._refuse_teach_or_leader()
            status = self.listener.snapshot().status
            if status is not None and status.ctrl_mode == STANDBY:
                raise StartupError(f"the arm on {self.where} stays in standby: it took no "
                                   "mode frame (0x151, CAN control) within "
                                   f"station.startup_timeout = {self.config.startup_timeout} "
                                   "s, as after drag-teach or MIT mode: " + RESET_STANDBY
                                   ) from None
            said = ("no status" if status is None else
                    f"{codec.CTRL_MODE_NAMES.get(status.ctrl_mode, status.ctrl_mode)}, "
                    f"{codec.MOVE_MODE_NAMES.get(status.mode_feed, status.mode_feed)}, "
                    f"{status.state}")
            raise StartupError(f"the arm on {self.where} never confirmed CAN control in MOVE "
                               f"J within station.startup_timeout = "
                               f"{self.config.startup_timeout} s (it reports {said}): check "
                               "that nothing else (a teach pendant, another program) controls "
                               "it; power-cycle it if it stays so") from None

    def _ask_parameter(self, query: int, field: str, what: str):
        """The reply to a fresh 0x477 `query`, kept in ArmParameters.`field`."""
        parameters = self.listener.parameters
        setattr(parameters, field, None)
        request = codec.encode_parameter_request(codec.ParameterRequest(query=query))
        return self._wait_for(lambda: getattr(parameters, field), what,
                              ask=lambda: self._send(*request))

    def collision_levels(self) -> tuple[int, ...]:
        """The arm's collision protection levels J1..J6 (0x477 -> 0x47B), asked now."""
        return self._ask_parameter(codec.QUERY_CRASH, "crash_levels",
                                   "the collision levels (0x47B)")

    def set_collision_level(self, level: int) -> None:
        """Sets every joint's collision protection level (0x47A) and reads it back."""
        if self.collision_levels() == (level,) * 6:
            return
        self._send(*codec.encode_crash_protection(codec.CRASH_PROTECTION_SETTING, [level] * 6))
        time.sleep(0.02)
        levels = self.collision_levels()
        if levels != (level,) * 6:
            self.close()
            raise StartupError(f"the arm on {self.where} reports collision levels {levels} "
                               f"after station.collision_level = {level} was set: set it with "
                               "the vendor's tool, or leave collision_level out")

    def gripper_parameters(self) -> codec.GripperParameters:
        """The arm's stored gripper parameters (0x477 -> 0x47E), asked now."""
        return self._ask_parameter(codec.QUERY_GRIPPER, "gripper",
                                   "the gripper parameters (0x47E)")

    def set_gripper_stroke(self, stroke_mm: int) -> bool:
        """Writes the gripper stroke (0x47D) only if the arm's stored one differs, with the
        gripper disabled first; returns whether it wrote."""
        stored = self.gripper_parameters()
        if stored.stroke_mm == stroke_mm:
            return False
        self._send(*codec.encode_gripper_command(codec.GripperCommand(
            0.0, 0.0, codec.GRIPPER_DISABLE), stroke=stroke_mm / 1000.0))
        self._send(*codec.encode_gripper_parameters(stroke_mm, stored.teach_range,
                                                    stored.friction))
        time.sleep(0.02)
        if self.gripper_parameters().stroke_mm != stroke_mm:
            self.close()
            raise StartupError(f"the arm on {self.where} kept its gripper stroke "
                               f"{stored.stroke_mm} mm after {stroke_mm} mm was written "
                               "(0x47D): check station.gripper_stroke_mm")
        return True

    def enable(self) -> None:
        """Enables the motors until every driver says so in a frame sent after the request."""
        self._switch_motors(True)

    def disable(self) -> None:
        """Disables the motors (the arm goes limp: support it, or park it first) until every
        driver reports it."""
        self._switch_motors(False)

    def _switch_motors(self, on: bool) -> None:
        since = time.monotonic()
        deadline = since + self.config.startup_timeout
        while True:
            reported = self.listener.reported_since(since)
            done = reported & (self.listener.snapshot().enabled == on)
            if done.all():
                return
            if time.monotonic() > deadline:
                missing = [f"J{j + 1}" for j in np.flatnonzero(~done)]
                self.close()
                raise StartupError(f"{self.where}: the motors of {', '.join(missing)} did "
                                   f"not report {'enabled' if on else 'disabled'} "
                                   f"(0x261-0x266 bit 6) within station.startup_timeout = "
                                   f"{self.config.startup_timeout} s")
            self._send(*codec.encode_motor_enable(on))
            time.sleep(ENABLE_RETRY)

    def send_gripper(self, opening: float, effort: float, code: int = codec.GRIPPER_ENABLE,
                     set_zero: bool = False) -> None:
        """One gripper command (0x159): opening (m), effort limit (N·m), enable code,
        set-zero (the current opening becomes the zero)."""
        self._send(*codec.encode_gripper_command(codec.GripperCommand(
            opening, effort, code, set_zero), stroke=self.config.gripper_stroke_mm / 1000.0))
