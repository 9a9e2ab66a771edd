"""LinkProcess: a PiperLink streaming from a process of its own.

Design notes: docs/design/can.md.
"""

from __future__ import annotations

import dataclasses as dc
import gc
import logging
import socket
import sys
import time

import numpy as np

from physcap_drake.can import bring_up, codec
from physcap_drake.can.child_process import ChildError, ChildProcess, PassedFd
from physcap_drake.can.feedback import Health
from physcap_drake.can.link import LinkSettings, LinkStatus, StartupError
from physcap_drake.can.playback import TargetPlayback
from physcap_drake.can.shared_block import Layout, SharedBlock

log = logging.getLogger("physcap_drake.can")

TARGETS = Layout({"q": 6, "gripper": 2, "sim_time": 1, "written_at": 1})
FEEDBACK = Layout({"published_at": 1, "q": 6, "v": 6, "torque": 6, "gripper": 2,
                   "enabled": 6, "status": 7, "end_pose": 6, "stale": 1, "stale_since": 1,
                   "commands_sent": 1, "stale_count": 1, "driver_status": 6,
                   "gripper_status": 1, "figures": 3},
                  texts=("reason", "fault"))
#: How long the diagram's side waits for the streaming process to finish a publication, s.
FEEDBACK_PATIENCE = 0.002
#: How long the parent waits for the child's answer to a request (start-up has its own), s.
REQUEST_TIMEOUT = 5.0
#: The streaming process's GIL switch interval, s: its other threads (the bus reader) hand
#: the interpreter back to the streaming thread within this (Python's default is 5 ms).
SWITCH_INTERVAL = 0.0005


@dc.dataclass(frozen=True)
class LinkFeedback:
    """The child's latest publication: when (monotonic s), joint positions (rad), speeds
    (rad/s) and torques (N·m, firmware scaling applied), gripper opening (m) and effort
    (N·m), drivers enabled, arm status (None before the first), end pose (m, rad), the
    watchdog's verdict, since when the feedback is stale, commands sent, stale spells, the
    drivers' and gripper's status bits, and the link's figures."""

    published_at: float
    q: np.ndarray
    v: np.ndarray
    torque: np.ndarray
    gripper_opening: float
    gripper_effort: float
    enabled: np.ndarray
    status: codec.ArmStatus | None
    end_pose: np.ndarray
    health: Health
    stale_since: float | None
    commands_sent: int
    stale_count: int
    driver_status: np.ndarray = dc.field(default_factory=lambda: np.zeros(6, dtype=int))
    gripper_status: int = 0
    #: Feedback frames lost recently (fraction), how late the newest came (s), garbled ones.
    lost_fraction: float = 0.0
    late: float = 0.0
    garbled: int = 0


def open_bus(settings: LinkSettings):
    """The python-can bus `settings` names, a socketcan one checked first (`bring_up`);
    ConnectionError naming the fields and the fix if it fails."""
    return bring_up.open_bus(settings.interface, settings.channel, settings.bitrate)


class LinkProcess:
    """The parent's handle (see module docstring); the process starts at once (it imports
    while the caller does other things), the arm's start-up waits for `start()`.
    `settings`: the link's; `bus_socket`: one end of a `socket_bus.socket_pair` to talk on
    (an emulator holds the other), else the child opens the bus `settings` names; `faults`:
    a `faults.FaultSettings` to damage what the link receives (emulated buses only; drills
    change it with `set_faults`), drawn from a generator seeded with `seed`."""

    def __init__(self, settings: LinkSettings, bus_socket: socket.socket | None = None,
                 faults=None, seed: int = 0):
        self.settings = settings
        self._targets = SharedBlock(TARGETS)
        self._feedback = SharedBlock(FEEDBACK)
        bus_fd = None if bus_socket is None else PassedFd(bus_socket.fileno())
        self._child = ChildProcess(
            "physcap_drake.can.link_process:serve",
            (settings, faults, seed, PassedFd(self._targets.fd), PassedFd(self._feedback.fd),
             bus_fd), name="piper-can-link")
        if bus_socket is not None:
            bus_socket.close()  # the child has its own copy
        self._started = False
        self._last: LinkFeedback | None = None
        self.firmware = ""
        self.torque_scale = (1.0,) * 6
        #: Whether the streaming process got real-time scheduling (see `can.realtime`).
        self.realtime = False

    @property
    def started(self) -> bool:
        return self._started

    def wait_ready(self) -> LinkProcess:
        """Waits until the process has imported what it needs and answers (it has not
        opened the bus: `start()` does)."""
        self._request(("ready",), timeout=REQUEST_TIMEOUT * 6, close_on_error=True)
        return self

    def start(self, confirm=None) -> LinkProcess:
        """Runs the arm's start-up sequence in the streaming process and waits for its
        first publication; `confirm()`, if given, runs before the motors are enabled (it
        raises to refuse). Raises StartupError or ConnectionError with the child's words
        (the process is closed then)."""
        timeout = self.settings.startup_timeout * 8 + 30.0
        reply = self._request(("connect",), timeout=timeout, close_on_error=True)
        self.firmware, self.torque_scale, self.realtime = reply
        if confirm is not None:
            try:
                confirm()
            except BaseException:
                self.close()
                raise
        self._request(("enable",), timeout=timeout, close_on_error=True)
        deadline = time.monotonic() + REQUEST_TIMEOUT
        while self.feedback() is None:  # the first cycle publishes right after start-up
            if time.monotonic() > deadline:
                self.close()
                raise StartupError("the CAN link process started but never published")
            time.sleep(0.001)
        self._started = True
        return self

    def _request(self, request: tuple, timeout: float = REQUEST_TIMEOUT, *,
                 close_on_error: bool = False):
        try:
            return self._child.request(request, timeout)
        except ChildError as error:
            if close_on_error:
                self.close()
            if error.kind == "ConnectionError":
                raise ConnectionError(str(error)) from None
            raise StartupError(str(error)) from None

    # Streaming ---------------------------------------------------------------------------

    def command(self, q, opening: float, effort: float, sim_time: float = np.nan) -> None:
        """The targets streamed from the next cycle on (rad; m; N·m), as PiperLink.command;
        `sim_time`: the simulated time they are for (s), when they sample a trajectory: the
        streaming process then plays the samples back at a steady pace
        (`playback.TargetPlayback`) instead of sending each as it comes."""
        self._targets.write({"q": np.asarray(q, dtype=float), "gripper": [opening, effort],
                             "sim_time": [sim_time], "written_at": [time.monotonic()]})

    def feedback(self) -> LinkFeedback | None:
        """The latest consistent publication (the previous one if the child is mid-write;
        None before the first)."""
        reading = self._feedback.read(patience=FEEDBACK_PATIENCE)
        if reading is not None and not np.isnan(reading["published_at"][0]):
            self._last = _feedback_of(reading)
        return self._last

    def status(self) -> LinkStatus:
        feedback = self.feedback()
        if feedback is None:
            return LinkStatus(Health(True, "no feedback yet", ""), None, 0, 0)
        return LinkStatus(feedback.health, feedback.stale_since, feedback.commands_sent,
                          feedback.stale_count)

    # Requests ----------------------------------------------------------------------------

    def set_faults(self, **changes) -> None:
        """Changes the fault drill on the received frames (fields of FaultSettings)."""
        self._request(("faults", changes))

    def cycle_starts(self) -> list[float]:
        """Start times of the last streaming cycles (monotonic s)."""
        return self._request(("cycle_starts",))

    def stale_reasons(self) -> list[str]:
        return self._request(("stale_reasons",))

    def stale_events(self) -> list[tuple[float, str]]:
        """When (monotonic s, the machine's clock) and why the feedback went stale."""
        return self._request(("stale_events",))

    def close(self) -> None:
        """Stops streaming (the arm holds its last target) and ends the process. Safe to
        call twice."""
        self._child.close(5.0 if self._started else 0.5)
        self._targets.close()
        self._feedback.close()


def _feedback_of(r) -> LinkFeedback:
    status = None if np.isnan(r["status"][0]) else codec.ArmStatus(
        *(int(v) for v in r["status"]))
    since = float(r["stale_since"][0])
    return LinkFeedback(
        float(r["published_at"][0]), r["q"], r["v"], r["torque"], float(r["gripper"][0]),
        float(r["gripper"][1]), r["enabled"] > 0.5, status, r["end_pose"],
        Health(bool(r["stale"][0] > 0.5), r["reason"], r["fault"]),
        None if np.isnan(since) else since, int(r["commands_sent"][0]),
        int(r["stale_count"][0]), r["driver_status"].astype(int), int(r["gripper_status"][0]),
        float(r["figures"][0]), float(r["figures"][1]), int(r["figures"][2]))


# The child -------------------------------------------------------------------------------

def serve(conn, settings: LinkSettings, faults, seed: int, targets_fd: int,
          feedback_fd: int, bus_fd: int | None) -> None:
    """The streaming process: serves the parent's requests until it says close or dies."""
    from physcap_drake.can.faults import FaultyBus
    from physcap_drake.can.link import PiperLink
    from physcap_drake.can.realtime import use_realtime
    from physcap_drake.can.socket_bus import SocketBus

    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    sys.setswitchinterval(SWITCH_INTERVAL)
    # Before any thread starts: the bus reader and the streaming thread inherit it.
    realtime = use_realtime(settings.realtime_priority, "the CAN streaming process")
    targets = SharedBlock(TARGETS, fd=targets_fd)
    feedback = SharedBlock(FEEDBACK, fd=feedback_fd)
    faulty = None
    playback = TargetPlayback()
    last_cycle, written = time.monotonic(), np.nan

    def open_link() -> PiperLink:
        """The bus is opened when the parent asks to start, not before."""
        nonlocal faulty
        if bus_fd is None:
            bus = open_bus(settings)
        else:
            bus = faulty = FaultyBus(SocketBus(socket.socket(fileno=bus_fd), settings.channel),
                                     faults, seed=seed)

        def on_cycle() -> None:
            nonlocal last_cycle, written
            now = time.monotonic()
            elapsed, last_cycle = now - last_cycle, now
            wanted = targets.read()
            if (wanted is not None and not np.isnan(wanted["q"]).any()
                    and wanted["written_at"][0] != written):
                written = wanted["written_at"][0]
                sim_time = wanted["sim_time"][0]
                if np.isnan(sim_time):  # a target standing still, not a trajectory's
                    playback.reset()
                    link.command(wanted["q"], *wanted["gripper"])
                else:  # the gripper's targets are played back in step with the joints'
                    playback.add(np.concatenate([wanted["q"], wanted["gripper"]]), sim_time)
            if not playback.empty:
                target, velocity = playback.next(elapsed)
                link.command(target[:6], target[6], target[7], velocity[:6])
            _publish(link, feedback)

        link = PiperLink(bus, settings, on_cycle=on_cycle)
        return link

    link: PiperLink | None = None
    try:
        while True:
            try:
                if not conn.poll(0.5):
                    continue
                kind, *args = conn.recv()
            except (EOFError, OSError):
                break  # the parent is gone: stop streaming, the arm holds
            if kind == "close":
                conn.send(("ok", None))
                break
            if kind == "connect":
                try:
                    link = link or open_link()
                except ConnectionError as error:
                    conn.send(("ConnectionError", str(error)))
                    continue
            conn.send(_answer(link, faulty, kind, args, realtime))
    finally:
        if link is not None:
            link.close()
        targets.close()
        feedback.close()


def _answer(link, faulty, kind: str, args, realtime: bool) -> tuple[str, object]:
    if kind == "ready":
        return "ok", None
    if link is None:
        return "StartupError", f"{kind!r} before the link started"
    try:
        if kind == "connect":
            link.connect()
            return "ok", (link.firmware, link.torque_scale, realtime)
        if kind == "enable":
            link.enable_motors().start_streaming()
            gc.freeze()  # what start-up allocated is never collected again: shorter pauses
            return "ok", None
        if kind == "faults":
            if faulty is None:
                return "StartupError", "fault drills need the emulated bus (emulate: true)"
            faulty.set(**args[0])
            return "ok", None
        if kind == "cycle_starts":
            return "ok", list(link.cycle_starts)
        if kind == "stale_reasons":
            return "ok", list(link.stale_reasons)
        if kind == "stale_events":
            return "ok", list(link.stale_events)
        return "StartupError", f"unknown request {kind!r}"
    except ConnectionError as error:
        return "ConnectionError", str(error)
    except StartupError as error:
        return "StartupError", str(error)


def _publish(link, block: SharedBlock) -> None:
    f = link.listener.snapshot()
    status = link.status()
    s = f.status
    block.write({
        "published_at": [time.monotonic()], "q": f.q, "v": f.v,
        "torque": link.torques(f.current), "gripper": [f.gripper_opening, f.gripper_effort],
        "enabled": f.enabled.astype(float),
        "status": [np.nan] * 7 if s is None else dc.astuple(s), "end_pose": f.end_pose,
        "stale": [float(status.health.stale)],
        "stale_since": [np.nan if status.stale_since is None else status.stale_since],
        "commands_sent": [status.commands_sent], "stale_count": [status.stale_count],
        "driver_status": f.driver_status, "gripper_status": [f.gripper_status],
        "figures": list(link.listener.link_figures()),
    }, {"reason": status.health.reason, "fault": status.health.fault})
