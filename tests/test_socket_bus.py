"""The socket-pair bus between the emulated arm's and the host's processes: a cycle's frames
go as one packet (one wake-up of the reader) and come out one by one, in order, as sent."""

from __future__ import annotations

import contextlib
import threading
import time

import can
import pytest

from physcap_drake.can.socket_bus import SocketBus, socket_pair
from physcap_drake.can.unix_bus import UnixBusHub, UnixSocketBus
from physcap_drake.piper_emulator.emulator import wait_until

#: Bytes of a frame on the socket: id 4, flags 1, length 1, data 8, timestamp 8.
FRAME_BYTES = 22
#: The most frames a packet carries (docs/development.md, the fourth session's CPU cuts).
MAX_FRAMES = 64


def frames(count: int) -> list[can.Message]:
    """`count` frames of distinct ids, contents and lengths (0 to 8 bytes)."""
    return [can.Message(arbitration_id=0x100 + i, data=bytes(range(i % 9)),
                        is_extended_id=False) for i in range(count)]


def test_frames_sent_together_arrive_one_by_one_in_order():
    mine, theirs = socket_pair()
    sender, reader = SocketBus(mine, "sender"), SocketBus(theirs, "reader")
    try:
        sent = frames(MAX_FRAMES + 6)  # two packets
        sender.send_many(sent)
        sender.send(can.Message(arbitration_id=0x1FF, data=b"\x01", is_extended_id=False))
        got = [reader.recv(timeout=1.0) for _ in range(len(sent) + 1)]
        assert [(m.arbitration_id, bytes(m.data), m.dlc) for m in got] == [
            (m.arbitration_id, bytes(m.data), len(m.data)) for m in sent] + [(0x1FF, b"\x01", 1)]
        assert reader.recv(timeout=0.05) is None
    finally:
        sender.shutdown()
        reader.shutdown()


def test_a_cycle_is_one_packet_and_a_full_socket_drops_it_whole():
    mine, theirs = socket_pair()
    sender = SocketBus(mine, "sender")
    try:
        sender.send_many(frames(15))
        sender.send_many(frames(MAX_FRAMES + 1))
        sizes = [len(theirs.recv(MAX_FRAMES * FRAME_BYTES)) for _ in range(3)]
        assert sizes == [15 * FRAME_BYTES, MAX_FRAMES * FRAME_BYTES, FRAME_BYTES]
        with pytest.raises(can.CanOperationError, match="not reading"):
            for _ in range(1_000_000):  # the reader stopped: its socket fills up
                sender.send_many(frames(15))
        theirs.setblocking(False)
        while True:  # what did get through are whole cycles
            try:
                assert len(theirs.recv(MAX_FRAMES * FRAME_BYTES)) == 15 * FRAME_BYTES
            except BlockingIOError:
                break
    finally:
        sender.shutdown()
        theirs.close()


def test_a_member_of_the_hub_gets_a_packet_of_frames_whole(tmp_path):
    """The rehearsal hub relays a packet of many frames to the other members intact."""
    hub = UnixBusHub(str(tmp_path / "bus.sock"))
    local = hub.member()
    member = UnixSocketBus(str(tmp_path / "bus.sock"))
    try:
        assert wait_until(lambda: hub.member_count == 2)
        sent = frames(MAX_FRAMES)
        local.send_many(sent)
        got = [member.recv(timeout=2.0) for _ in sent]
        assert [(m.arbitration_id, bytes(m.data)) for m in got if m is not None] == [
            (m.arbitration_id, bytes(m.data)) for m in sent]
    finally:
        member.shutdown()
        local.shutdown()
        hub.close()


def test_a_reader_blocked_on_a_bus_whose_peer_has_gone_does_not_spin():
    """piper_sdk reads with recv() and no timeout; once the peer (the emulator) has closed
    its end, each read finds nothing at once and python-can asks again. Each must wait, or
    the reader's thread takes a whole core for as long as the bus stays open."""
    mine, theirs = socket_pair()
    bus = SocketBus(mine)
    theirs.close()
    reads, inner = [], bus._recv_internal

    def counted(timeout):
        reads.append(timeout)
        return inner(timeout)

    def read() -> None:
        with contextlib.suppress(can.CanError):
            bus.recv()

    bus._recv_internal = counted
    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    assert wait_until(lambda: reads, timeout=10.0)
    first, started = len(reads), time.monotonic()
    time.sleep(0.3)
    seen, took = len(reads) - first, time.monotonic() - started
    bus.shutdown()  # the blocked recv() raises now and the thread ends
    reader.join(timeout=5.0)
    # At least 5 ms between reads keeps an idle reader under 1 % of a core; spinning, it
    # read 365,405 times in 0.3 s.
    assert seen <= took / 0.005 + 2
