"""Mutation testing (mutmut) of the modules that decide safety and results: `./run mutate
[MODULE ...]` (default: the five of the acceptance list; `--list` shows all). `./run mutate
MODULE --mutants NAME ...` runs only the named mutants (fnmatch patterns), e.g. the survivors
of a full run once new tests are written; the score is then over those.

Each module runs alone, in a copy of the tree under the temporary directory, against its own
tests only, two mutants at a time (one per core of a 2-core machine; `./run` nices it).
mutmut mutates function and method bodies; the module-level constants are covered by
tests/planted_mutants.py. Prints the score per module and every surviving mutant's diff
(docs/mutation_testing.md).
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COPIED = ("physcap_drake", "tests", "models", "stations", "agents", "pyproject.toml")

#: module: (files mutated, relative to physcap_drake/; the tests that judge them)
MODULES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "can/codec": (("can/codec/*.py",),
                  ("test_can_codec.py", "test_can_codec_sdk.py", "test_codec_vendor_si.py",
                   "test_codec_enumerations.py")),
    "can/feedback.py": (("can/feedback.py",), ("test_watchdog_boundaries.py",
                                               "test_feedback_listener_frames.py",
                                               "test_feedback_listener_status.py")),
    "tasks/placement.py": (("tasks/placement.py",),
                           ("test_placement_boundaries.py",)),
    "agent/sandbox/policy.py": (("agent/sandbox/policy.py",),
                                ("test_sandbox_forbidden_names.py", "test_sandbox_checks.py")),
    "control/skill_executor.py": (("control/skill_executor.py",),
                                  ("test_skill_executor.py",
                                   "test_executor_gripper_boundaries.py",
                                   "test_executor_tracking_boundaries.py",
                                   "test_executor_taking_requests.py")),
    # Further modules of issue 46's list (run on demand; slower tests).
    "physx/mass_estimator.py": (("physx/mass_estimator.py",),
                                ("test_mass_hand_worked.py", "test_mass_estimator.py",
                                 "test_torque_gain.py")),
    "physx/stiffness_levels.py": (("physx/stiffness_levels.py",),
                                  ("test_stiffness_estimator.py",
                                   "test_shipped_calibration.py")),
    "eval/statistics.py": (("eval/statistics.py",), ("test_eval_statistics.py",)),
}
SHOW = """
import sys
from mutmut.mutation.diff_apply import get_diff_for_mutant
for state, _, name in (argument.partition(":") for argument in sys.argv[1:]):
    module = name.split(".x")[0] if ".x" in name else name.rsplit(".", 1)[0]
    print(f"--- {state}: {name}")
    print(get_diff_for_mutant(name, path=module.replace(".", "/") + ".py"), flush=True)
"""
DEFAULT = ("can/codec", "can/feedback.py", "tasks/placement.py", "agent/sandbox/policy.py",
           "control/skill_executor.py")


def setup_cfg(files: tuple[str, ...], tests: tuple[str, ...]) -> str:
    lines = ["[mutmut]", "source_paths = physcap_drake", "only_mutate ="]
    lines += [f"    physcap_drake/{pattern}" for pattern in files]
    lines += ["also_copy =", *(f"    {part}" for part in COPIED if part != "physcap_drake")]
    lines += ["pytest_add_cli_args = -p no:cacheprovider -p no:randomly -q",
              "pytest_add_cli_args_test_selection ="]
    lines += [f"    tests/{test}" for test in tests]
    return "\n".join(lines) + "\n"


def mutate(module: str, names: tuple[str, ...] = ()) -> tuple[int, int, list[str]]:
    """(killed, total, surviving mutant names) of one module, or of its mutants `names`;
    prints the survivors' diffs."""
    files, tests = MODULES[module]
    with tempfile.TemporaryDirectory(prefix="physcap-mutate-") as scratch:
        tree = Path(scratch)
        for part in COPIED:
            source = ROOT / part
            (shutil.copytree if source.is_dir() else shutil.copy)(source, tree / part)
        (tree / "setup.cfg").write_text(setup_cfg(files, tests))
        mutmut = [str(Path(sys.executable).with_name("mutmut"))]
        log = Path(tempfile.gettempdir()) / f"physcap-mutate-{module.replace('/', '_')}.log"
        print(f"{module}: mutmut running, its progress in {log}", flush=True)
        with log.open("w") as output:
            subprocess.run([*mutmut, "run", "--max-children", "2", *names], cwd=tree, check=False,
                           stdout=output, stderr=subprocess.STDOUT)
        results = subprocess.run([*mutmut, "results", "--all", "true"], cwd=tree,
                                 capture_output=True, text=True, check=True).stdout
        states = {name: state for name, state in re.findall(r"^\s*(\S+): (.+)$", results,
                                                             flags=re.M)
                  if state != "not checked" or not names}
        killed = sum(state in ("killed", "timeout", "segfault") for state in states.values())
        survivors = [name for name, state in states.items()
                     if state not in ("killed", "timeout", "segfault")]
        if survivors:  # their diffs, in one process (`mutmut show` starts one per mutant)
            subprocess.run([sys.executable, "-c", SHOW, *(f"{states[name]}:{name}"
                                                          for name in survivors)],
                           cwd=tree, check=False)
    return killed, len(states), survivors


def main(arguments: list[str]) -> int:
    if arguments == ["--list"]:
        print("\n".join(f"{name}{' (default)' if name in DEFAULT else ''}" for name in MODULES))
        return 0
    names: tuple[str, ...] = ()
    if "--mutants" in arguments:
        at = arguments.index("--mutants")
        arguments, names = arguments[:at], tuple(arguments[at + 1:])
        if len(arguments) != 1 or not names:
            print("--mutants needs one MODULE before it and mutant names after it",
                  file=sys.stderr)
            return 2
    unknown = [name for name in arguments if name not in MODULES]
    if unknown:
        print(f"unknown module(s) {', '.join(unknown)}; known: {', '.join(MODULES)}",
              file=sys.stderr)
        return 2
    scores = {module: mutate(module, names) for module in (arguments or DEFAULT)}
    print("\nmodule | killed / mutants | score | survivors")
    for module, (killed, total, survivors) in scores.items():
        score = 100.0 * killed / total if total else float("nan")
        print(f"{module} | {killed} / {total} | {score:.1f} % | {len(survivors)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
