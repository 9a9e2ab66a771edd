"""SocketBus: a python-can bus between two processes of this machine, for the emulator.

python-can's virtual bus only connects buses of one interpreter; the emulated arm and the
host's streaming process are separate processes, like the real arm and its host. They talk
over a Unix socket pair (datagrams: one packet carries one frame, or the frames `send_many`
sends together, such as one feedback cycle's). A packet that cannot be sent at once (the
peer stopped reading and the socket is full) is dropped and the sender gets a
CanOperationError, as a real bus's full transmit queue does; nothing ever waits.
"""

from __future__ import annotations

import collections
import select
import socket
import struct
import time

import can

#: Socket buffer size asked for, bytes (about 0.2-1 s of the arm's feedback, as the kernel
#: allows).
BUFFER_BYTES = 4 << 20
#: arbitration id, flags (1 extended, 2 remote), length, 8 data bytes, timestamp.
_FRAME = struct.Struct(">IBB8sd")
#: Bytes of one frame on the socket.
PACKET_BYTES = _FRAME.size
#: The most frames one packet carries (`send_many` splits longer lists).
MAX_FRAMES = 64
#: Bytes of the largest packet.
MAX_PACKET_BYTES = MAX_FRAMES * PACKET_BYTES
#: How long a read waits once the peer has closed its end, s (nothing will come).
CLOSED_PEER_WAIT = 0.01


def socket_pair() -> tuple[socket.socket, socket.socket]:
    """Two connected ends; give one to each process (multiprocessing can pass them)."""
    return socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)


class SocketBus(can.BusABC):
    """One end of a `socket_pair` as a python-can bus (see module docstring)."""

    def __init__(self, sock: socket.socket, channel: str = "socket", **kwargs):
        super().__init__(channel=channel, **kwargs)
        self._socket = sock
        self._socket.setblocking(False)
        for option in (socket.SO_SNDBUF, socket.SO_RCVBUF):  # the kernel caps the size
            self._socket.setsockopt(socket.SOL_SOCKET, option, BUFFER_BYTES)
        self.channel_info = f"socket pair {channel}"
        self._received: collections.deque[can.Message] = collections.deque()
        self._drain()

    def _drain(self) -> None:
        """Drops what the peer sent before this end was opened, as a freshly opened CAN
        socket only sees frames from then on."""
        try:
            while self._socket.recv(MAX_PACKET_BYTES):
                pass
        except (BlockingIOError, InterruptedError):
            pass

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.send_many((msg,))

    def send_many(self, messages) -> None:
        """Sends `messages` in order, MAX_FRAMES to a packet (one wake-up of the reader for
        them all, not one each); CanOperationError if a packet is dropped (all its frames)."""
        stamp = time.time()
        for first in range(0, len(messages), MAX_FRAMES):
            packet = b"".join(_FRAME.pack(
                msg.arbitration_id, (1 if msg.is_extended_id else 0)
                | (2 if msg.is_remote_frame else 0), len(msg.data),
                bytes(msg.data).ljust(8, b"\0"), stamp)
                for msg in messages[first:first + MAX_FRAMES])
            try:
                self._socket.send(packet)
            except (BlockingIOError, InterruptedError) as error:
                raise can.CanOperationError("socket bus: the peer is not reading, frames "
                                            "dropped") from error
            except OSError as error:
                raise can.CanOperationError(f"socket bus: {error}") from error

    def _recv_internal(self, timeout: float | None):
        if self._received:  # the rest of the last packet
            return self._received.popleft(), False
        try:
            packet = self._socket.recv(MAX_PACKET_BYTES)
        except BlockingIOError:
            ready, _, _ = select.select([self._socket], [], [], timeout)
            if not ready:
                return None, False
            try:
                packet = self._socket.recv(MAX_PACKET_BYTES)
            except (BlockingIOError, InterruptedError):
                return None, False
            except ConnectionError:
                packet = b""
        except ConnectionError:
            packet = b""
        except OSError as error:
            raise can.CanOperationError(f"socket bus: {error}") from error
        if not packet:  # the peer closed its end: nothing will come any more
            # Waits a little even without a timeout: python-can's recv() then calls again at
            # once, and a reader blocked in recv() (piper_sdk's) would spin a core.
            time.sleep(CLOSED_PEER_WAIT if timeout is None else min(timeout, CLOSED_PEER_WAIT))
            return None, False
        channel = self.channel_info
        self._received.extend(
            can.Message(arbitration_id=identifier, is_extended_id=bool(flags & 1),
                        is_remote_frame=bool(flags & 2), dlc=length, data=data[:length],
                        timestamp=stamp, channel=channel)
            for identifier, flags, length, data, stamp
            in _FRAME.iter_unpack(packet[:len(packet) - len(packet) % PACKET_BYTES]))
        if not self._received:
            return None, False
        return self._received.popleft(), False

    def shutdown(self) -> None:
        super().shutdown()
        self._socket.close()
