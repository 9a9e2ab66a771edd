"""`physcap emulate-piper` of the kinematic arm runs without the rest of the command line
(a rehearsal starts one per terminal): what it loads, and that it answers as the whole
command line does."""

from __future__ import annotations

import os
import subprocess
import sys

from physcap_drake.commands.emulate import alone

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: Runs `physcap ARGS` as the console command does and, at exit, prints which of the whole
#: command line's modules it loaded.
PROBE = """
import atexit, sys
heavy = ("physcap_drake.cli", "physcap_drake.commands.common", "physcap_drake.scenario")
atexit.register(lambda: print("loaded:", [m for m in heavy if m in sys.modules]))
sys.argv = ["physcap", *sys.argv[1:]]
from physcap_drake.launch import main
main()
"""


def _physcap(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": ROOT, "PHYSCAP_ALLOCATOR": "system"}
    return subprocess.run([sys.executable, "-c", PROBE, *args], env=env, capture_output=True,
                          text=True, timeout=60)


def test_only_the_kinematic_arm_without_help_runs_alone():
    assert alone(["emulate-piper", "--channel", "vcan0", "--start", "teach"])
    assert not alone(["emulate-piper", "--channel", "vcan0", "--scenario", "rig.yaml"])
    assert not alone(["emulate-piper", "--channel", "vcan0", "--scenario-text=a: 1"])
    assert not alone(["emulate-piper", "--help"])
    assert not alone(["emulate-piper", "-h"])
    assert not alone(["arm", "status", "--channel", "vcan0"])


def test_the_kinematic_arm_serves_without_scenarios_or_the_other_commands():
    served = _physcap("emulate-piper", "--interface", "virtual", "--channel", "alone",
                      "--seconds", "0.2")
    assert served.returncode == 0, served.stderr
    assert "emulating a PiPER (firmware S-V1.8-2, start state normal)" in served.stdout
    assert "loaded: []" in served.stdout
    # Bad input is one line naming the option and exit 2, as from the whole command line.
    refused = _physcap("emulate-piper", "--interface", "virtual", "--channel", "alone",
                       "--start", "asleep")
    assert refused.returncode == 2
    assert refused.stderr.strip() == (
        "error: Invalid value: --start must be one of normal, teach, leader, standby, lossy, "
        "not 'asleep' (see 'physcap emulate-piper --help')")
    # With a scenario the whole command line runs (it loads the scenario with Drake).
    missing = _physcap("emulate-piper", "--interface", "virtual", "--channel", "alone",
                       "--scenario", "/nonexistent/rig.yaml")
    assert missing.returncode == 2 and "rig.yaml" in missing.stderr
    assert "physcap_drake.cli" in missing.stdout
