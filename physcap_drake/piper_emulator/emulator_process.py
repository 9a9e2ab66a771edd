"""EmulatorProcess: the emulated arm in a process of its own, like the real arm is a device
of its own.

Design notes: docs/design/can.md.
"""

from __future__ import annotations

import gc
import logging
import socket
import sys
import time

import numpy as np

from physcap_drake.can.child_process import ChildError, ChildProcess, PassedFd, named_function
from physcap_drake.can.shared_block import Layout, SharedBlock

#: How long the parent waits for the child to build its world and start, s.
START_TIMEOUT = 120.0
#: How long a reader of the world waits for the emulator to finish a publication, s.
WORLD_PATIENCE = 0.005
REQUEST_TIMEOUT = 10.0
#: The emulator process's GIL switch interval, s (Python's default is 5 ms).
SWITCH_INTERVAL = 0.0005
#: The emulated firmware's cycle rate in the emulator's process, Hz (the PiPER's feedback
#: rate): the world is stepped, and published, once per cycle.
FIRMWARE_RATE = 200.0


def world_layout(size: int) -> Layout:
    """Simulation time (s) and the plant's positions and velocities (`size` values)."""
    return Layout({"time": 1, "state": size})


class EmulatorProcess:
    """The parent's handle. `bus_socket`: the emulator's end of a socket pair; `scenario_yaml`:
    a scenario with a `SimPiper` station (as YAML text) whose simulated station backs the
    arm, or None for the kinematic arm; `world_builder`: with a scenario, the function that
    builds the world from it in the child, as "package.module:function" called with
    (scenario_yaml, gripper_max_effort) and returning a motion backend (named, not imported:
    the world is built from layers above this package, see `physcap_drake.emulated_world`;
    it sets the scenario's hidden `body_masses` before the world runs);
    `gripper_max_effort`: N·m at the simulated gripper's full force (see SimulatedMotion);
    `state_size`: the plant's positions + velocities (the world block's size, 0 without a
    scenario); `firmware`: the version it reports; `realtime_priority`: its scheduling (see
    `can.realtime`, 0: normal); `pace_world`: step the world in a thread of its own
    (`paced_world`, see `serve`); `start`: the state the arm powers up in
    (`firmware.START_STATES`); `joints`: without a scenario, where the kinematic arm (which
    weighs like the PiPER model, `arm_gravity`) powers up, rad (default all 0, the rest
    pose; within the mechanical stops). The process starts at once and builds its world in the
    background; `wait_ready()` waits for it."""

    def __init__(self, bus_socket: socket.socket, scenario_yaml: str | None = None, *,
                 world_builder: str | None = None, gripper_max_effort: float = 2.0,
                 state_size: int = 0, firmware: str = "S-V1.8-2", realtime_priority: int = 0,
                 pace_world: bool = False, start: str = "normal", joints=None):
        from physcap_drake.piper_emulator.firmware import START_STATES

        if start not in START_STATES:
            bus_socket.close()
            raise ValueError(f"emulated start state {start!r}: one of "
                             f"{', '.join(START_STATES)}")
        if scenario_yaml is not None and world_builder is None:
            bus_socket.close()
            raise ValueError("an emulated world from a scenario needs its world_builder "
                             "(\"package.module:function\")")
        self._world = SharedBlock(world_layout(state_size)) if state_size else None
        self._last_world: tuple[float, np.ndarray] | None = None
        world_fd = None if self._world is None else PassedFd(self._world.fd)
        try:
            self._child = ChildProcess(
                "physcap_drake.piper_emulator.emulator_process:serve",
                (PassedFd(bus_socket.fileno()), scenario_yaml, world_builder,
                 gripper_max_effort, firmware, world_fd, state_size, realtime_priority,
                 pace_world, start, None if joints is None else [float(a) for a in joints]),
                name="piper-emulator", forked=True)
        finally:
            bus_socket.close()  # the child has its own copy
        self._ready = False

    def wait_ready(self) -> EmulatorProcess:
        """Waits until the emulated arm runs (its world built, its first cycle published);
        RuntimeError with the child's words if it cannot start (it is closed then)."""
        if self._ready:
            return self
        try:
            self._request(("ready",), timeout=START_TIMEOUT)
            deadline = time.monotonic() + REQUEST_TIMEOUT
            while self._world is not None and self.world() is None:  # its first cycle
                if time.monotonic() > deadline:
                    raise RuntimeError("the PiPER emulator process never published its world")
                time.sleep(0.002)
        except BaseException:
            self.close()
            raise
        self._ready = True
        return self

    def _request(self, request: tuple, timeout: float = REQUEST_TIMEOUT):
        try:
            return self._child.request(request, timeout)
        except ChildError as error:
            raise RuntimeError(f"PiPER emulator process: {error}") from None

    def world(self) -> tuple[float, np.ndarray] | None:
        """(simulation time s, plant positions and velocities) as last published (None
        before the first publication)."""
        reading = None if self._world is None else self._world.read(patience=WORLD_PATIENCE)
        if reading is not None and not np.isnan(reading["time"][0]):
            self._last_world = float(reading["time"][0]), reading["state"]
        return self._last_world

    def snapshot(self):
        """A copy of the emulated firmware's state (`arm_state.EmulatedArm`)."""
        return self._request(("snapshot",))

    def timing(self):
        """How the emulated arm kept its pace so far (`emulator.EmulatorTiming`)."""
        return self._request(("timing",))

    def set_error(self, arm_status: int = 0, err_code: int = 0) -> None:
        """The arm reports this error state from now on (see PiperEmulator.set_error)."""
        self._request(("set_error", arm_status, err_code))

    def set_world(self, state: np.ndarray) -> None:
        """Moves things in the simulated world while it runs, as something outside the arm
        would (an operator placing an object): the plant's positions and velocities become
        `state`; returns once applied. The world's hidden masses are its plant's model data,
        from the scenario's `body_masses`, and never change while it runs."""
        self._request(("set_world", state))

    def close(self) -> None:
        """Stops the emulator (the emulated arm stops answering). Safe to call twice."""
        # Not ready yet, it may still be building its world: no need to wait for it.
        self._child.close(5.0 if self._ready else 0.2, polite=self._ready)
        if self._world is not None:
            self._world.close()
            self._world = None


def serve(conn, bus_fd: int, scenario_yaml: str | None, world_builder: str | None,
          gripper_max_effort: float, firmware: str, world_fd: int | None, state_size: int,
          realtime_priority: int, pace_world: bool = False, start: str = "normal",
          joints: list[float] | None = None) -> None:
    """The emulated arm's process: runs until the parent says close or goes away."""
    from physcap_drake.can.realtime import use_realtime
    from physcap_drake.can.socket_bus import SocketBus
    from physcap_drake.piper_emulator.arm_gravity import ArmGravity
    from physcap_drake.piper_emulator.emulator import PiperEmulator
    from physcap_drake.piper_emulator.motion import KinematicMotion
    from physcap_drake.piper_emulator.paced_world import PacedWorld

    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    # The firmware thread gets the interpreter back from the world thread within this.
    sys.setswitchinterval(SWITCH_INTERVAL)
    world = None if world_fd is None else SharedBlock(world_layout(state_size), fd=world_fd)
    try:
        if scenario_yaml is None:
            motion = KinematicMotion(ArmGravity(), q0=joints)
        else:
            # The builder's world has the scenario's hidden masses as model data.
            motion = named_function(world_builder)(scenario_yaml, gripper_max_effort)
    except (RuntimeError, ValueError, OSError) as error:  # say why there is no world; end
        conn.recv()
        conn.send(("error", f"{type(error).__name__}: {error}"))
        return

    def publish() -> None:
        plant = motion.plant
        world.write({"time": [motion.context.get_time()],
                     "state": plant.GetPositionsAndVelocities(motion.plant_context)})

    if scenario_yaml is not None and pace_world:
        # The world's physics never makes the firmware cycle wait (a world behind the wall
        # clock is counted instead). It is not the arm's controller, so its thread runs one
        # real-time priority below the firmware's: ahead of the machine's ordinary work (at
        # normal scheduling a busy machine would starve it), never ahead of the firmware's
        # cycle (at the same priority it would hold the CPU, and the interpreter, for a
        # whole round-robin slice: stalls of 50 ms). It rests between steps
        # (PacedWorld.REST), so it never makes the kernel throttle the real-time threads.
        setup = (lambda: use_realtime(max(realtime_priority - 1, 1),
                                      "the emulated PiPER's world")) \
            if realtime_priority > 1 else None
        motion = PacedWorld(motion, 1.0 / FIRMWARE_RATE, world_thread_setup=setup,
                            on_step=publish if world is not None else None)

    use_realtime(realtime_priority, "the emulated PiPER")  # its firmware thread inherits it
    # What start-up allocated (the world's Drake systems, the modules) is never collected
    # again: a full collection over all of it stalls the firmware loop for about 40 ms,
    # which the host's watchdog sees as lost feedback.
    gc.freeze()
    bus = SocketBus(socket.socket(fileno=bus_fd), "emulator")
    # A world stepped in the firmware's cycle is published after every cycle.
    on_cycle = publish if world is not None and not pace_world else None
    emulator = PiperEmulator(bus, firmware=firmware, motion=motion, rate=FIRMWARE_RATE,
                             on_cycle=on_cycle, start=start).start()
    try:
        while True:
            try:
                kind, *args = conn.recv()
            except (EOFError, OSError):
                break
            if kind == "close":
                conn.send(("ok", None))
                break
            conn.send(_answer(emulator, kind, args))
    finally:
        emulator.stop()
        bus.shutdown()
        if world is not None:
            world.close()


def _answer(emulator, kind: str, args) -> tuple[str, object]:
    if kind == "ready":
        return "ok", None
    if kind == "snapshot":
        return "ok", emulator.snapshot()
    if kind == "timing":
        return "ok", emulator.timing()
    if kind == "set_error":
        emulator.set_error(*args)
        return "ok", None
    if kind == "set_world":
        (state,) = args
        motion = emulator.motion
        if not hasattr(motion, "set_world"):
            return "error", "the kinematic emulated arm has no simulated world to set"
        with getattr(motion, "lock", emulator.lock):
            motion.set_world(state)
        return "ok", None
    return "error", f"unknown request {kind!r}"
