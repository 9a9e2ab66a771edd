"""An McapSink written from two threads at once (the diagram's recorder, and the agent's
model-call thread on the CAN station) goes on writing: neither waits for the other forever.

Without the sink's own lock this deadlocked within a second: one thread held foxglove-sdk's
writer lock while its flush waited for the interpreter, and the other held the interpreter
while it waited for that lock. The run is a child process so that a deadlock fails the test
(by its timeout) instead of hanging the suite.
"""

from __future__ import annotations

import subprocess
import sys

from physcap_drake.recording import topics
from physcap_drake.recording.reading import read_recording

SAMPLES = 20000
WRITERS = f"""
import sys, threading
import numpy as np
from physcap_drake.recording.mcap_sink import McapSink

sink = McapSink(sys.argv[1])
names = [f"joint{{i}}" for i in range(6)]
done = threading.Event()
entries = []

def agent_thread():
    while not done.is_set():
        k = len(entries)
        sink.transcript_entry(0.001 * k, {{"kind": "note", "step": 0, "robot_time_s": 0.0,
                                          "text": "thinking " * 20, "data": {{}}}})
        entries.append(k)

thread = threading.Thread(target=agent_thread, daemon=True)
thread.start()
for i in range({SAMPLES}):
    sink.joint_states(0.001 * i, names, np.zeros(6), np.zeros(6), np.zeros(6))
done.set()
thread.join()
sink.close()
print(len(entries))
"""


def test_two_threads_write_one_sink_without_waiting_for_each_other(tmp_path):
    path = tmp_path / "two_threads.mcap"
    child = subprocess.run([sys.executable, "-c", WRITERS, str(path)], capture_output=True,
                           text=True, timeout=180)
    assert child.returncode == 0, child.stderr
    entries = int(child.stdout.strip())
    assert entries >= 1
    recording = read_recording(path)
    assert len(recording.on(topics.JOINT_STATES)) == SAMPLES
    assert len(recording.on(topics.AGENT_LOG)) == entries
