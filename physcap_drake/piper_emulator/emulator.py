"""PiperEmulator: a virtual PiPER on a python-can bus, answering like the arm.

Design notes: docs/design/can.md.
"""

from __future__ import annotations

import dataclasses as dc
import threading
import time
from collections.abc import Callable

import can
import numpy as np

from physcap_drake.piper_emulator.arm_state import EmulatedArm
from physcap_drake.piper_emulator.firmware import Firmware
from physcap_drake.piper_emulator.lateness import LagTracker, Lateness
from physcap_drake.piper_emulator.motion import KinematicMotion
from physcap_drake.piper_emulator.paced_world import WorldTiming

#: The firmware's cycle rate, Hz (the PiPER's feedback rate).
DEFAULT_RATE = 200.0


@dc.dataclass(frozen=True)
class EmulatorTiming:
    """How the emulated arm kept its pace: its firmware loop's lateness, and its paced
    world's figures (None when the world is stepped in the cycle itself)."""

    firmware: Lateness
    world: WorldTiming | None


class PiperEmulator:
    """Speaks the PiPER protocol on `bus` (see module docstring). `on_cycle()`, if given, is
    called after every cycle while the lock is held (to publish the emulated world)."""

    def __init__(self, bus: can.BusABC, *, firmware: str = "S-V1.8-2", rate: float = DEFAULT_RATE,
                 gravity_torque: Callable[[np.ndarray], np.ndarray] | None = None,
                 motion=None, on_cycle: Callable[[], None] | None = None,
                 start: str = "normal"):
        """`motion`: the motion backend (default: KinematicMotion(gravity_torque)); `start`:
        the state the arm powers up in (`firmware.START_STATES`)."""
        if motion is not None and gravity_torque is not None:
            raise ValueError("gravity_torque applies to the kinematic motion only; the "
                             "given motion backend computes its own torques")
        self._bus = bus
        self._period = 1.0 / rate
        self.motion = motion or KinematicMotion(gravity_torque)
        self.firmware = Firmware(self.motion, firmware, start)
        self._on_cycle = on_cycle
        #: Held while the arm (and the motion backend's world) changes; hold it to read both.
        self.lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._lag = LagTracker(self._period)

    @property
    def bus(self) -> can.BusABC:
        """The bus it answers on (the caller that opened it shuts it down)."""
        return self._bus

    @property
    def period(self) -> float:
        """Feedback period, s."""
        return self._period

    @property
    def arm(self) -> EmulatedArm:
        """The live firmware state (change it only holding `lock`)."""
        return self.firmware.arm

    def start(self) -> PiperEmulator:
        self._thread = threading.Thread(target=self._run, name="piper-emulator", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        stop_world = getattr(self.motion, "stop", None)
        if stop_world is not None:
            stop_world()

    def __enter__(self) -> PiperEmulator:
        return self.start()

    def __exit__(self, *_) -> None:
        self.stop()

    def snapshot(self) -> EmulatedArm:
        """A copy of the firmware's state (for tests and tools)."""
        with self.lock:
            return self.firmware.arm.copy()

    def timing(self) -> EmulatorTiming:
        """The loop's lateness so far (see EmulatorTiming)."""
        world = getattr(self.motion, "timing", None)
        return EmulatorTiming(self._lag.lateness(), None if world is None else world())

    def set_error(self, arm_status: int = 0, err_code: int = 0) -> None:
        """Makes the arm report an error state from now on (a fault drill): `arm_status` as in
        0x2A1 (1 e-stop, 5 joint communication error, 7 collision, ...), `err_code` bits
        0-5 communication error of J1-J6, 8-13 angle limit. The arm holds where it is."""
        with self.lock:
            self.firmware.set_error(arm_status, err_code)

    # The firmware loop ---------------------------------------------------------------------

    def _run(self) -> None:
        next_time = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            late = now - next_time
            self._lag.note(now, max(late, 0.0))
            if late > self._period / 2:  # fell behind (a stall): start afresh, no burst
                next_time = now
            while (message := self._bus.recv(timeout=0.0)) is not None:
                with self.lock:
                    replies = self.firmware.handle(message.arbitration_id, bytes(message.data),
                                                   message.timestamp or None)
                self._send_all(replies)
            with self.lock:
                frames = self.firmware.cycle(self._period)
                if self._on_cycle is not None:
                    self._on_cycle()
            self._send_all(frames)
            next_time += self._period
            self._stop.wait(max(0.0, next_time - time.monotonic()))

    def _send_all(self, frames) -> None:
        """Sends `frames` ((id, data)); on a SocketBus as one packet (one wake-up of the
        reader). Like the arm, a frame that cannot be sent is simply lost."""
        if not frames:
            return
        messages = [can.Message(arbitration_id=identifier, data=data, is_extended_id=False)
                    for identifier, data in frames]
        if hasattr(self._bus, "send_many"):
            batches, send = [messages], self._bus.send_many
        else:
            batches, send = messages, self._bus.send
        for batch in batches:
            try:
                send(batch)
            except can.CanError:
                pass


def wait_until(predicate: Callable[[], bool], timeout: float = 2.0) -> bool:
    """Polls `predicate` until it holds or `timeout` s pass (a helper for bus peers)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.005)
    return predicate()
