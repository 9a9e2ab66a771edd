"""CanSession: what a CAN station holds outside Drake, started only when asked.

Design notes: docs/design/station.md.
"""

from __future__ import annotations

import atexit
import dataclasses as dc
from typing import TYPE_CHECKING

from pydrake.common.yaml import yaml_dump_typed

from physcap_drake.can.faults import FaultSettings
from physcap_drake.can.link import LinkSettings
from physcap_drake.can.link_process import LinkProcess
from physcap_drake.can.socket_bus import socket_pair
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_gate import confirm_enabling

if TYPE_CHECKING:
    import numpy as np

    from physcap_drake.can.link import LinkStatus
    from physcap_drake.piper_emulator.emulator import EmulatorTiming
    from physcap_drake.piper_emulator.emulator_process import EmulatorProcess

#: What builds the emulated arm's world in the emulator's process, by name: it is built from
#: the scenario, a layer above the station (see `physcap_drake.emulated_world`).
EMULATED_WORLD_BUILDER = "physcap_drake.emulated_world:build_world"
#: The firmware version the emulated arm reports unless `station.firmware` says another.
EMULATED_FIRMWARE = "S-V1.8-2"
#: How far apart (s) a watchdog trip and the emulated arm's stall may be and still be the
#: same event: the streaming and the feedback cycles tick apart, a few periods.
TRIP_MARGIN = 0.02


class CanSession:
    """See the design notes. `world_size`: positions + velocities of the emulated world's
    plant (the scene's copy of it), 0 without an emulator."""

    def __init__(self, scenario, world_size: int = 0):
        config: PiperCan = scenario.station
        self.config = config
        self._scenario_yaml = (yaml_dump_typed(dc.replace(scenario, station=config.emulated))
                               if config.emulate else None)
        #: The emulated plant's positions + velocities (the shared world block's size).
        self.world_size = world_size
        self.link: LinkProcess | None = None
        self.emulator: EmulatorProcess | None = None
        #: The emulated world as it was when the session closed ((time s, state) or None):
        #: success checks read it after the episode released the station.
        self.last_world: tuple[float, np.ndarray] | None = None
        #: The streaming process's last status (LinkStatus) and stale reasons when it closed.
        self.last_status: LinkStatus | None = None
        self.last_stale_reasons: list[str] = []
        #: When (monotonic s) and why the feedback went stale, as of closing.
        self.last_stale_events: list[tuple[float, str]] = []
        #: How the emulated arm kept its pace (`piper_emulator.emulator.EmulatorTiming`) when
        #: it closed.
        self.last_emulator_timing: EmulatorTiming | None = None
        atexit.register(self.close)  # processes must not outlive the interpreter

    def unexplained_trips(self) -> list[str]:
        """The watchdog trips of the closed session that no stall of the emulated arm's own
        firmware loop explains (each as "reason at t s"): the feedback went silent while
        the emulated arm itself was not running (a starved machine) is the emulator's
        doing; any other trip (silence, loss, garbling, lateness on the link) is not.
        Without an emulator's figures every trip is unexplained."""
        timing = self.last_emulator_timing
        window = self.config.feedback_timeout + TRIP_MARGIN
        unexplained = []
        for since, reason in self.last_stale_events:
            silent = reason.startswith("no feedback for")
            if not (silent and timing is not None
                    and timing.firmware.covering(since - window, since, TRIP_MARGIN)):
                unexplained.append(f"{reason} at {since:.3f} s")
        return unexplained

    @property
    def started(self) -> bool:
        return self.link is not None and self.link.started

    def prepare(self) -> CanSession:
        """Starts the processes without connecting: they import (and the emulated arm builds
        its world) in the background, so `start()` has only the arm's start-up left."""
        if self.link is not None:
            return self
        config = self.config
        if not config.emulate:
            self.link = LinkProcess(LinkSettings.of(config))
            return self
        # The one place a CAN station imports the emulator: `emulate: true`.
        from physcap_drake.piper_emulator.emulator_process import EmulatorProcess

        emulator_end, link_end = socket_pair()
        f = config.faults
        self.link = LinkProcess(LinkSettings.of(config), link_end,
                                FaultSettings(f.loss, f.delay, f.garble), seed=f.seed)
        self.emulator = EmulatorProcess(
            emulator_end, self._scenario_yaml, world_builder=EMULATED_WORLD_BUILDER,
            gripper_max_effort=config.gripper_max_effort,
            state_size=self.world_size, firmware=config.firmware or EMULATED_FIRMWARE,
            realtime_priority=max(config.realtime_priority - 1, 0),
            pace_world=config.pace_world, start=config.emulated_start)
        return self

    def wait_ready(self) -> CanSession:
        """Waits until the processes `prepare` started are ready to connect (the emulated
        arm's world is built). Raises RuntimeError naming what failed."""
        link = self.prepare().link
        assert link is not None  # prepare() starts it
        try:
            if self.emulator is not None:
                self.emulator.wait_ready()
            link.wait_ready()
        except BaseException:
            self.close()
            raise
        return self

    def start(self) -> CanSession:
        """Connects (see the design notes); does nothing if already started. Raises
        ConnectionError / StartupError naming the bus and what failed (nothing is left
        running then)."""
        if self.started:
            return self
        link = self.wait_ready().link
        assert link is not None  # prepare() starts it
        try:
            link.start(confirm=lambda: confirm_enabling(self.config))
        except BaseException:
            self.close()
            raise
        return self

    def close(self) -> None:
        """Stops streaming (the arm holds), then the emulated arm. Safe to call twice."""
        link, emulator = self.link, self.emulator
        self.link = self.emulator = None
        if link is not None:
            if link.started:
                self.last_status = link.status()
                self.last_stale_reasons = link.stale_reasons()
                self.last_stale_events = link.stale_events()
            link.close()
        if emulator is not None:
            if link is not None and link.started:
                self.last_world = emulator.world()
                try:
                    self.last_emulator_timing = emulator.timing()
                except RuntimeError:  # the emulated arm is gone: no figures to keep
                    self.last_emulator_timing = None
            emulator.close()
