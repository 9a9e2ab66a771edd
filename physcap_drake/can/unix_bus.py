"""The rehearsal bus: one CAN-like bus on a Unix-domain socket, which any number of
processes of this machine join, for an emulated arm that several `physcap` commands share.

`UnixBusHub` serves the bus at a socket path (`physcap emulate-piper --interface unix`) and
relays like a CAN bus: every frame a member sends reaches all the other members, never
itself. `UnixSocketBus(path)` joins it as a python-can bus. Frames are `socket_bus`
packets; a member that stops reading loses frames (its socket is full), as a CAN node
whose receive queue overflows; nothing waits for it. See docs/piper_emulator.md.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import socket
import stat
import threading

import can

from physcap_drake.can.socket_bus import BUFFER_BYTES, MAX_PACKET_BYTES, SocketBus, socket_pair

#: How often the hub looks for members added from another thread, s.
HUB_POLL = 0.05
#: The most packets the hub relays from one member before it serves the others.
HUB_BATCH = 64


def _seqpacket() -> socket.socket:
    return socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)


class UnixSocketBus(SocketBus):
    """A member of the rehearsal bus served at `channel` (a socket path); raises
    CanInitializationError naming the command to run when nothing serves it."""

    def __init__(self, channel: str, **kwargs):
        sock = _seqpacket()
        try:
            sock.connect(channel)
        except OSError as error:
            sock.close()
            raise can.CanInitializationError(
                f"no emulated PiPER serves the unix socket {channel!r} ({error.strerror}): "
                f"start `physcap emulate-piper --interface unix --channel {channel}` "
                "first") from None
        super().__init__(sock, channel, **kwargs)
        self.channel_info = f"unix socket {channel}"


def _claim(path: str) -> None:
    """Removes a socket file nobody serves any more; OSError if `path` is served, or is
    not a socket."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return
    if not stat.S_ISSOCK(mode):
        raise OSError(errno.EEXIST, f"{path} exists and is not a socket")
    probe = _seqpacket()
    try:
        probe.connect(path)
    except ConnectionRefusedError:
        os.unlink(path)  # left by a server that is gone
        return
    finally:
        probe.close()
    raise OSError(errno.EADDRINUSE, f"another emulated PiPER already serves {path}")


class UnixBusHub:
    """Serves the rehearsal bus at `path` (see module docstring) from a thread of this
    process until `close()`; `member()` joins it from this process."""

    def __init__(self, path: str):
        _claim(path)
        self.path = path
        self._listener = _seqpacket()
        # Bound beside it and renamed once listening: a member that starts as soon as the
        # path exists must not find a socket that refuses it (bound, not yet listening).
        binding = f"{path}~"
        _claim(binding)  # left by a hub killed between the two
        self._listener.bind(binding)
        try:
            self._listener.listen(16)
            os.rename(binding, path)
        except OSError:
            self._listener.close()
            with contextlib.suppress(FileNotFoundError):
                os.unlink(binding)
            raise
        self._listener.setblocking(False)
        self._members: list[socket.socket] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="unix-bus-hub", daemon=True)
        self._thread.start()

    def member(self, name: str = "local") -> SocketBus:
        """A bus on the hub for this process (the emulated arm's)."""
        mine, hubs = socket_pair()
        self._add(hubs)
        return SocketBus(mine, name)

    @property
    def member_count(self) -> int:
        return len(self._members)

    def _add(self, sock: socket.socket) -> None:
        sock.setblocking(False)
        for option in (socket.SO_SNDBUF, socket.SO_RCVBUF):
            sock.setsockopt(socket.SOL_SOCKET, option, BUFFER_BYTES)
        self._members = [*self._members, sock]  # replaced, never changed: the loop reads it

    def _drop(self, sock: socket.socket) -> None:
        self._members = [m for m in self._members if m is not sock]
        sock.close()

    def _run(self) -> None:
        while not self._stop.is_set():
            members = self._members
            try:
                readable, _, _ = select.select([self._listener, *members], [], [], HUB_POLL)
            except (OSError, ValueError):  # a member closed meanwhile: look again
                continue
            for sock in readable:
                if sock is self._listener:
                    with contextlib.suppress(OSError):  # it gave up meanwhile, or no fds
                        self._add(self._listener.accept()[0])
                else:
                    self._relay(sock)

    def _relay(self, sender: socket.socket) -> None:
        packets = []
        for _ in range(HUB_BATCH):
            try:
                packet = sender.recv(MAX_PACKET_BYTES)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                packet = b""
            if not packet:  # it left the bus
                self._drop(sender)
                break
            packets.append(packet)
        for member in self._members:
            if member is sender:
                continue
            for packet in packets:
                try:
                    member.send(packet)
                except (BlockingIOError, InterruptedError):
                    continue  # its queue is full: this frame is lost for it
                except OSError:
                    self._drop(member)
                    break

    def close(self) -> None:
        """Stops serving, leaves every member, removes the socket file. Safe to call twice."""
        if self._stop.is_set():
            return
        self._stop.set()
        self._thread.join(timeout=2.0)
        for sock in self._members:
            sock.close()
        self._members = []
        self._listener.close()
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.path)
