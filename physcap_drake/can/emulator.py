"""PiperEmulator: a virtual PiPER on a python-can bus, answering like the arm.

It runs the emulated firmware (`firmware.Firmware`) in its own thread: every 1/rate s it
applies the frames that arrived (answering queries and settings at once), runs one
firmware cycle and sends the arm's feedback: status (0x2A1), end pose (0x2A2-0x2A4),
joints (0x2A5-0x2A7), gripper (0x2A8), driver high-speed feedback (0x251-0x256) and, every
fifth cycle, low-speed feedback (0x261-0x266).

How the arm moves is up to its motion backend: `motion.KinematicMotion` puts the joints on
their reference and takes holding torques from an optional `gravity_torque(q)` model;
`simulated_motion.SimulatedMotion` runs the simulated station (a MultibodyPlant scene with
the task's objects), so joint torques and gripper effort come from its physics. Torques go
on the bus as motor currents with the firmware's scaling.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import can
import numpy as np

from physcap_drake.can.arm_state import EmulatedArm
from physcap_drake.can.firmware import Firmware
from physcap_drake.can.motion import KinematicMotion


class PiperEmulator:
    """Speaks the PiPER protocol on `bus` (see module docstring). `on_cycle()`, if given, is
    called after every cycle while the lock is held (to publish the emulated world)."""

    def __init__(self, bus: can.BusABC, *, firmware: str = "S-V1.8-2", rate: float = 200.0,
                 gravity_torque: Callable[[np.ndarray], np.ndarray] | None = None,
                 motion=None, on_cycle: Callable[[], None] | None = None):
        """`motion`: the motion backend (default: KinematicMotion(gravity_torque))."""
        if motion is not None and gravity_torque is not None:
            raise ValueError("gravity_torque applies to the kinematic motion only; the "
                             "given motion backend computes its own torques")
        self._bus = bus
        self._period = 1.0 / rate
        self.motion = motion or KinematicMotion(gravity_torque)
        self.firmware = Firmware(self.motion, firmware)
        self._on_cycle = on_cycle
        #: Held while the arm (and the motion backend's world) changes; hold it to read both.
        self.lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

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

    def __enter__(self) -> PiperEmulator:
        return self.start()

    def __exit__(self, *_) -> None:
        self.stop()

    def snapshot(self) -> EmulatedArm:
        """A copy of the firmware's state (for tests and tools)."""
        with self.lock:
            return self.firmware.arm.copy()

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
            if next_time < time.monotonic():  # fell behind (a stall): start afresh
                next_time = time.monotonic()
            self._stop.wait(max(0.0, next_time - time.monotonic()))

    def _send_all(self, frames) -> None:
        for identifier, data in frames:
            try:
                self._bus.send(can.Message(arbitration_id=identifier, data=data,
                                           is_extended_id=False))
            except can.CanError:
                pass  # like the arm: a frame that cannot be sent is simply lost


def wait_until(predicate: Callable[[], bool], timeout: float = 2.0) -> bool:
    """Polls `predicate` until it holds or `timeout` s pass (a helper for bus peers)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.005)
    return predicate()
