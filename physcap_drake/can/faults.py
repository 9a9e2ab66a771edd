"""FaultyBus: a python-can bus wrapper that damages what the host receives (fault drills).

It sits between the bus and the host's reader (the Notifier), so every fault it injects is a
fault of the feedback path: frames lost, delayed, garbled (wrong length, or a joint angle far
out of range), or the whole link silent. Commands the host sends pass through untouched.
Settings can change while it runs (`set`); draws come from a seeded generator.
"""

from __future__ import annotations

import collections
import dataclasses as dc
import struct
import threading
import time

import can
import numpy as np

from physcap_drake.can import codec


@dc.dataclass(frozen=True)
class FaultSettings:
    """loss, garble: probability per frame (0..1); delay: s added to every frame's delivery;
    silent: no frame gets through."""

    loss: float = 0.0
    delay: float = 0.0
    garble: float = 0.0
    silent: bool = False


def garbled(message: can.Message, kind: int) -> can.Message:
    """A damaged copy of `message`: kind 0 cuts it to 5 bytes; kind 1 puts an out-of-range
    value in it (a joint angle of about 2·10⁶ degrees, or all bytes 0xFF elsewhere)."""
    data = bytes(message.data)
    if kind == 0:
        data = data[:5]
    elif message.arbitration_id in codec.JOINT_FEEDBACK:
        data = struct.pack(">ii", 2_000_000_000, 2_000_000_000)
    else:
        data = b"\xff" * 8
    return can.Message(arbitration_id=message.arbitration_id, data=data,
                       is_extended_id=message.is_extended_id, timestamp=message.timestamp,
                       dlc=len(data))


class FaultyBus(can.BusABC):
    """Wraps `inner` (see module docstring). Closing it closes `inner`."""

    def __init__(self, inner: can.BusABC, settings: FaultSettings | None = None, seed: int = 0):
        self._inner = inner
        self._settings = settings or FaultSettings()
        self._rng = np.random.default_rng(seed)
        self._pending: collections.deque[can.Message] = collections.deque()
        self._lock = threading.Lock()
        self.counts = collections.Counter()  # frames "lost", "garbled", "silenced", "passed"
        #: Every frame sent through it (the host's commands), in order, for tests and drills.
        self.sent: collections.deque[can.Message] = collections.deque(maxlen=100_000)
        super().__init__(channel=getattr(inner, "channel_info", "faulty"))
        self.channel_info = f"faulty({getattr(inner, 'channel_info', '?')})"

    def set(self, **changes) -> None:
        """Changes the fault settings (fields of FaultSettings) from now on."""
        with self._lock:
            self._settings = dc.replace(self._settings, **changes)

    @property
    def settings(self) -> FaultSettings:
        with self._lock:
            return self._settings

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.sent.append(msg)
        self._inner.send(msg, timeout)

    def send_many(self, messages) -> None:
        """Sends `messages` in order: in one packet where the inner bus can (SocketBus)."""
        self.sent.extend(messages)
        inner_many = getattr(self._inner, "send_many", None)
        if inner_many is not None:
            inner_many(messages)
            return
        for message in messages:
            self._inner.send(message)

    def _damage(self, message: can.Message, settings: FaultSettings) -> can.Message | None:
        if settings.silent:
            self.counts["silenced"] += 1
            return None
        if settings.loss and self._rng.random() < settings.loss:
            self.counts["lost"] += 1
            return None
        if settings.garble and self._rng.random() < settings.garble:
            self.counts["garbled"] += 1
            return garbled(message, int(self._rng.integers(2)))
        self.counts["passed"] += 1
        return message

    def _recv_internal(self, timeout: float | None):
        deadline = None if timeout is None else time.time() + timeout
        while True:
            delay = self._settings.delay  # `set` replaces them whole: one read is consistent
            now = time.time()
            if self._pending and self._pending[0].timestamp + delay <= now:
                return self._pending.popleft(), False
            wait = 0.01 if deadline is None else deadline - now
            if self._pending:
                wait = min(wait, self._pending[0].timestamp + delay - now)
            if deadline is not None and now >= deadline:
                return None, False
            message = self._inner.recv(timeout=max(0.0, min(wait, 0.01)))
            settings = self._settings  # as they are when the frame came
            if message is None or (message := self._damage(message, settings)) is None:
                continue
            if not self._pending and message.timestamp + settings.delay <= time.time():
                return message, False  # due already: no need to queue it
            self._pending.append(message)

    def shutdown(self) -> None:
        super().shutdown()
        self._inner.shutdown()
