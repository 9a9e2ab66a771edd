"""Ctrl-C while the MCAP writer is inside a file write: the recording is not lost.

The interrupt is sent from inside the file's `write` (where a real one lands when it comes
during a flush): it must come out as KeyboardInterrupt once the writer's call returned, and
the recording must still close into a complete file holding every message logged."""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest

from physcap_drake.recording import topics
from physcap_drake.recording.crash_safe_file import CrashSafeFile
from physcap_drake.recording.mcap_sink import McapSink
from physcap_drake.recording.reading import read_recording

NAMES = [f"joint{i}" for i in range(6)]


@pytest.fixture
def default_ctrl_c():
    """Python's own SIGINT handler, as in a command started from a terminal."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


def interrupt_inside_writes(monkeypatch, times: int) -> None:
    """The next `times` file writes each get a Ctrl-C while they run."""
    original, left = CrashSafeFile.write, [times]

    def write(self, data):
        if left[0] > 0:
            left[0] -= 1
            os.kill(os.getpid(), signal.SIGINT)
        return original(self, data)

    monkeypatch.setattr(CrashSafeFile, "write", write)


def test_ctrl_c_during_a_flush_comes_after_it_and_the_file_closes_whole(
        tmp_path, monkeypatch, default_ctrl_c):
    sink = McapSink(tmp_path / "episode.mcap")
    for k in range(50):
        sink.joint_states(0.01 * k, NAMES, np.full(6, k), np.zeros(6), np.zeros(6))
    interrupt_inside_writes(monkeypatch, times=1)
    with pytest.raises(KeyboardInterrupt):
        sink.flush()
    sink.joint_states(0.5, NAMES, np.full(6, 50), np.zeros(6), np.zeros(6))
    sink.close()
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # handed back
    positions = [m.value.joints[0].position
                 for m in read_recording(tmp_path / "episode.mcap").on(topics.JOINT_STATES)]
    assert positions == list(range(51))


def test_ctrl_c_during_the_close_still_finishes_the_file(tmp_path, monkeypatch,
                                                          default_ctrl_c):
    sink = McapSink(tmp_path / "episode.mcap")
    sink.joint_states(0.0, NAMES, np.zeros(6), np.zeros(6), np.zeros(6))
    interrupt_inside_writes(monkeypatch, times=3)
    with pytest.raises(KeyboardInterrupt):
        sink.close()
    assert len(read_recording(tmp_path / "episode.mcap").on(topics.JOINT_STATES)) == 1


def test_ctrl_c_outside_the_writer_is_raised_at_once(tmp_path, default_ctrl_c):
    sink = McapSink(tmp_path / "episode.mcap")
    try:
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):  # the handler runs between two bytecodes of this loop
                pass
    finally:
        sink.close()
