"""The rehearsal bus on a Unix-domain socket: CAN's broadcast between any number of members,
clear errors without a server, a stale socket reclaimed; and one emulated arm served by
`physcap emulate-piper --interface unix`, driven from two processes through piper_sdk."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
import time

import can
import numpy as np
import pytest
from piper_sdk_peer import enable, joints, sdk_on_unix_bus, status

from physcap_drake.can import unix_bus
from physcap_drake.can.unix_bus import UnixBusHub, UnixSocketBus
from physcap_drake.piper_emulator.emulator import wait_until

pytestmark = [pytest.mark.emulated_hardware,
              pytest.mark.filterwarnings("ignore:The .bustype. argument is deprecated")]


@pytest.fixture
def path(tmp_path):
    return str(tmp_path / "piper.sock")


def frame(identifier: int, first: int = 0) -> can.Message:
    return can.Message(arbitration_id=identifier, data=[first, 1, 2, 3, 4, 5, 6, 7],
                       is_extended_id=False)


def received(bus, within: float = 2.0) -> list[tuple[int, bytes]]:
    """Every frame that reaches `bus` until it has been quiet for 0.2 s (or `within` s)."""
    frames, deadline = [], time.monotonic() + within
    while time.monotonic() < deadline:
        message = bus.recv(timeout=0.2)
        if message is None:
            break
        frames.append((message.arbitration_id, bytes(message.data)))
    return frames


def test_every_frame_reaches_every_other_member_and_never_its_sender(path):
    hub = UnixBusHub(path)
    local = hub.member()
    a, b = UnixSocketBus(path), UnixSocketBus(path)
    try:
        assert wait_until(lambda: hub.member_count == 3)
        a.send(frame(0x151, 1))
        local.send(frame(0x2A1, 2))
        assert sorted(received(b)) == [(0x151, bytes([1, 1, 2, 3, 4, 5, 6, 7])),
                                       (0x2A1, bytes([2, 1, 2, 3, 4, 5, 6, 7]))]
        assert received(a) == [(0x2A1, bytes([2, 1, 2, 3, 4, 5, 6, 7]))]
        assert received(local) == [(0x151, bytes([1, 1, 2, 3, 4, 5, 6, 7]))]
        b.shutdown()  # a member that leaves is dropped; the others go on
        assert wait_until(lambda: hub.member_count == 2)
        a.send(frame(0x471))
        assert [i for i, _ in received(local)] == [0x471]
    finally:
        for bus in (a, b, local):
            bus.shutdown()
        hub.close()
    assert not os.path.exists(path)  # the socket file goes with the hub


def test_without_a_server_the_error_names_the_command_to_run(path):
    with pytest.raises(can.CanInitializationError,
                       match=f"emulate-piper --interface unix --channel {path}"):
        UnixSocketBus(path)


def test_a_stale_socket_is_reclaimed_and_a_served_one_is_refused(path):
    first = UnixBusHub(path)
    try:
        with pytest.raises(OSError, match="already serves"):
            UnixBusHub(path)
    finally:
        first.close()
    dead = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    dead.bind(path)  # what a killed server leaves: a socket file nobody listens on
    dead.close()
    assert os.path.exists(path)
    UnixBusHub(path).close()  # the stale file is no obstacle
    with open(path, "w") as plain:
        plain.write("not a socket")
    with pytest.raises(OSError, match="not a socket"):
        UnixBusHub(path)


CLIENT = """
import sys, time
import can
from piper_sdk_peer import sdk_on_unix_bus
class Patch:
    def setitem(self, d, k, v): d[k] = v
    def setattr(self, o, k, v): setattr(o, k, v)
sdk = sdk_on_unix_bus(sys.argv[1], Patch())
deadline = time.monotonic() + 10
while time.monotonic() < deadline and not all(sdk.GetArmEnableStatus()):
    sdk.EnableArm(7)
    time.sleep(0.05)
print(all(sdk.GetArmEnableStatus()))
sdk.DisconnectPort()
"""


def test_one_emulated_arm_is_shared_by_separate_processes(path, monkeypatch, tmp_path):
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([root, os.path.join(root, "tests")])}
    server = subprocess.Popen([sys.executable, "-m", "physcap_drake", "emulate-piper",
                               "--interface", "unix", "--channel", path, "--seconds", "120"],
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              text=True)
    try:
        assert wait_until(lambda: os.path.exists(path) or server.poll() is not None,
                          timeout=60.0), "the emulator never served its socket"
        assert server.poll() is None, server.stdout.read()
        sdk = sdk_on_unix_bus(path, monkeypatch)
        # The socket is served before the emulator's first cycle; on a loaded machine its
        # feedback may take seconds to reach the SDK's reader (the wait ends as it does).
        assert wait_until(lambda: sdk.GetArmJointMsgs().time_stamp > 0, timeout=30.0)
        assert wait_until(lambda: sdk.GetArmLowSpdInfoMsgs().time_stamp > 0, timeout=30.0)
        assert not any(sdk.GetArmEnableStatus())  # motors off at power-up
        # Another process enables the arm; this one sees it, and moves it.
        client = subprocess.run([sys.executable, "-c", CLIENT, path], env=env,
                                capture_output=True, text=True, timeout=60)
        assert client.stdout.strip() == "True", client.stderr
        assert wait_until(lambda: all(sdk.GetArmEnableStatus()))
        enable(sdk, speed=50)
        target = joints(sdk) + [0.2, 0.0, 0.0, 0.0, 0.0, 0.0]
        counts = [round(a * 1000 * 180 / np.pi) for a in target]
        assert wait_until(lambda: (sdk.JointCtrl(*counts),
                                   np.allclose(joints(sdk), target, atol=1e-4))[1],
                          timeout=10.0)
        assert status(sdk).ctrl_mode == 1
        sdk.DisconnectPort()
    finally:
        server.terminate()  # SIGTERM ends it as Ctrl-C does: socket removed
        output = server.communicate(timeout=10)[0]
    assert server.returncode == 0, output
    assert "Traceback" not in output
    assert not os.path.exists(path)


def test_the_socket_path_appears_only_once_the_hub_accepts_members(path, monkeypatch):
    """A member that connects as soon as the path exists (a second terminal's command, a
    script waiting for the file) is accepted: the path does not exist while the hub's
    socket is bound but not yet listening (piper_sdk, refused twice, then read nothing)."""
    listening, release = threading.Event(), threading.Event()

    class SlowToListen(socket.socket):
        def listen(self, backlog):
            listening.set()
            release.wait(10.0)
            super().listen(backlog)

    monkeypatch.setattr(unix_bus, "_seqpacket",
                        lambda: SlowToListen(socket.AF_UNIX, socket.SOCK_SEQPACKET))
    hubs = []
    starting = threading.Thread(target=lambda: hubs.append(UnixBusHub(path)))
    starting.start()
    try:
        assert listening.wait(10.0)
        assert not os.path.exists(path)  # bound, not listening: nothing to find yet
    finally:
        release.set()
        starting.join()
    member = UnixSocketBus(path)
    try:
        assert wait_until(lambda: hubs[0].member_count == 1)
    finally:
        member.shutdown()
        hubs[0].close()
    assert not os.path.exists(path) and not os.path.exists(path + "~")
