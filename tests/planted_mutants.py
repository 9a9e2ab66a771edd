"""Issue 46's planted bugs: each applied alone to a copy of the tree, the tests of its area run.

`python tests/planted_mutants.py [NAME ...]` prints, per mutant, whether the area's tests
caught it. The tree itself is never changed: the sources are copied to a temporary directory.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COPIED = ("physcap_drake", "tests", "models", "stations", "agents", "pyproject.toml")

# The area's tests, the new ones first (pytest -x stops at the first failure).
CODEC = ["tests/test_codec_vendor_si.py", "tests/test_codec_enumerations.py",
         "tests/test_can_codec.py", "tests/test_can_codec_sdk.py"]
MASS = ["tests/test_mass_hand_worked.py", "tests/test_mass_estimator.py",
        "tests/test_torque_gain.py"]
PLACEMENT = ["tests/test_placement_boundaries.py", "tests/test_tasks.py"]
WATCHDOG = ["tests/test_watchdog_boundaries.py", "tests/test_feedback_listener_frames.py",
            "tests/test_can_faults.py"]
EXECUTOR = ["tests/test_executor_gripper_boundaries.py",
            "tests/test_executor_tracking_boundaries.py", "tests/test_skill_executor.py"]
SANDBOX = ["tests/test_sandbox_forbidden_names.py", "tests/test_sandbox_checks.py"]
STIFFNESS = ["tests/test_shipped_calibration.py", "tests/test_stiffness_estimator.py",
             "tests/test_calibration_heldout.py"]

#: name: (file, text, replacement, the area's tests). The first 10 are the issue's table.
MUTANTS = {
    "micrometre_10x": ("physcap_drake/can/codec/fields.py", "MICROMETRE = 1e-6",
                       "MICROMETRE = 1e-7", CODEC),
    "gravity_10pc_low": ("physcap_drake/physx/mass_estimator.py", "GRAVITY = 9.81",
                         "GRAVITY = 9.81 * 0.9", MASS),
    "upright_off": ("physcap_drake/tasks/placement.py", "if upright and tilt > UPRIGHT_TILT",
                    "if False and tilt > UPRIGHT_TILT", PLACEMENT),
    "wall_clearance_dropped": ("physcap_drake/tasks/placement.py",
                               "np.abs(offset[:2]) + radius > inner_half",
                               "np.abs(offset[:2]) > inner_half", PLACEMENT),
    "silence_timeout_doubled": ("physcap_drake/can/feedback.py", "if silence > self._timeout",
                                "if silence > 2 * self._timeout", WATCHDOG),
    "loss_7pc_low": ("physcap_drake/can/feedback.py",
                     "return sum(cycles) / (len(cycles) * len(self._others))",
                     "return 0.93 * sum(cycles) / (len(cycles) * len(self._others))", WATCHDOG),
    "gripper_grace_0": ("physcap_drake/control/skill_executor.py", "GRIPPER_MIN_TIME = 0.3",
                        "GRIPPER_MIN_TIME = 0.0", EXECUTOR),
    "settled_without_latency": ("physcap_drake/control/skill_executor.py",
                                ">= self._latency + GRIPPER_MIN_TIME", ">= GRIPPER_MIN_TIME",
                                EXECUTOR),
    "setattr_allowed": ("physcap_drake/agent/sandbox/policy.py",
                        '"locals", "memoryview", "open", "quit", "setattr", "vars",',
                        '"locals", "memoryview", "open", "quit", "vars",', SANDBOX),
    "stiffness_3_4_moved": ("models/calibration/stiffness_levels.yaml",
                            "[12.72, 5.60, 2.75, 1.41]", "[12.72, 5.60, 3.025, 1.41]",
                            STIFFNESS),
    # Seven more of the same kinds.
    "millidegree_10x": ("physcap_drake/can/codec/fields.py",
                        "MILLIDEGREE = math.pi / 180_000.0", "MILLIDEGREE = math.pi / 18_000.0",
                        CODEC),
    "upright_tilt_20deg": ("physcap_drake/tasks/placement.py",
                           "UPRIGHT_TILT = np.radians(10.0)", "UPRIGHT_TILT = np.radians(20.0)",
                           PLACEMENT),
    "floor_band_widened": ("physcap_drake/tasks/placement.py",
                           "-0.005 <= offset[2] - floor <= 0.01",
                           "-0.005 <= offset[2] - floor <= 0.03", PLACEMENT),
    "loss_limit_inclusive_off": ("physcap_drake/can/feedback.py", "if loss > self._max_loss",
                                 "if loss > 1.5 * self._max_loss", WATCHDOG),
    "gripper_tolerance_10x": ("physcap_drake/control/skill_executor.py",
                              "GRIPPER_TOLERANCE = 5e-4", "GRIPPER_TOLERANCE = 5e-3", EXECUTOR),
    "getattr_attribute_allowed": ("physcap_drake/agent/sandbox/policy.py",
                                  '"breakpoint", "compile", "delattr", "eval", "exec", "exit", '
                                  '"getattr", "globals",\n        "help"',
                                  '"breakpoint", "compile", "delattr", "eval", "exec", "exit", '
                                  '"globals",\n        "help"', SANDBOX),
    "max_grasp_offset_doubled": ("physcap_drake/physx/mass_estimator.py",
                                 "MAX_GRASP_OFFSET = 0.02", "MAX_GRASP_OFFSET = 0.04", MASS),
    # Five more, planted after issue 43 changed the executor and the sandbox.
    "tracking_ignores_latency": ("physcap_drake/control/skill_executor.py",
                                 "now - self._latency - self._planner.config.tracking_delay",
                                 "now - self._planner.config.tracking_delay", EXECUTOR),
    "func_prefix_allowed": ("physcap_drake/agent/sandbox/policy.py",
                            '"f_", "func_", "gi_",', '"f_", "gi_",', SANDBOX),
    "feedback_lower_limit_sign": ("physcap_drake/can/feedback.py",
                                  "np.append(JOINT_LOWER[:5] - ANGLE_MARGIN",
                                  "np.append(JOINT_LOWER[:5] + ANGLE_MARGIN", WATCHDOG),
    "tray_rotation_ignored": ("physcap_drake/tasks/placement.py",
                              "offset = X_tray.inverse().multiply(X_can.translation())",
                              "offset = X_can.translation() - X_tray.translation()", PLACEMENT),
    "joint_speed_unsigned": ("physcap_drake/can/codec/feedback.py",
                             'struct.unpack(">hhi", check(data, "driver high-speed"))',
                             'struct.unpack(">Hhi", check(data, "driver high-speed"))', CODEC),
}


def run(names: list[str]) -> int:
    with tempfile.TemporaryDirectory(prefix="planted46-") as scratch:
        tree = Path(scratch)
        for part in COPIED:
            source = ROOT / part
            (shutil.copytree if source.is_dir() else shutil.copy)(source, tree / part)
        env = dict(os.environ, PYTHONPATH=str(tree))
        survived = 0
        for name in names:
            path, old, new, tests = MUTANTS[name]
            target = tree / path
            original = target.read_text()
            if original.count(old) != 1:
                raise SystemExit(f"{name}: {old!r} is not once in {path}")
            target.write_text(original.replace(old, new))
            try:
                present = [t for t in tests if (tree / t).exists()]
                result = subprocess.run(
                    [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider",
                     *present], cwd=tree, env=env, capture_output=True, text=True)
            finally:
                target.write_text(original)
            caught = result.returncode != 0
            survived += not caught
            last = (result.stdout.strip().splitlines() or [""])[-1]
            print(f"{name:28s} {'caught ' if caught else 'SURVIVED'} {last}", flush=True)
        print(f"{len(names) - survived} of {len(names)} caught")
        return 1 if survived else 0


if __name__ == "__main__":
    sys.exit(run(sys.argv[1:] or list(MUTANTS)))
