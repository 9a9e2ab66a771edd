"""The package's layers: each subpackage (or top-level module) of physcap_drake imports only
from its own layer or the layers below it, no two packages and no two modules import each
other (directly or round a cycle), no module imports another module's private names, and
the host imports the PiPER emulator only where it starts one.

Every import counts, also those inside functions: a deferred import is still a dependency.
A new package must be given a layer here; that is where its place in the design is decided.
"""

from __future__ import annotations

import ast
import functools
import os
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import physcap_drake

ROOT = Path(physcap_drake.__file__).parent

#: From the bottom up. Within a layer, packages may import each other, but not round a cycle.
LAYERS = (
    # Plain helpers with no robot in them.
    ("scenario_errors", "scenario_layers", "config_checks", "resources", "immutable_state",
     "weak_method", "kinematics", "clock", "allocator", "blas_threads", "fork_server"),
    # The arm's bus, the host's side: protocol, link, buses.
    ("can",),
    # The PiPER's emulated firmware, on the protocol (never the host's link).
    ("piper_emulator",),
    # The station (simulated or over CAN) and its ports.
    ("station",),
    # Skills on the arm, then the physical probes on the skills.
    ("control",),
    ("physx",),
    # A scenario file puts the configurations of the layers above together.
    ("scenario",),
    # The robot stack (station, skills, probes on one request path), perception, the API.
    ("robot_stack", "perception", "emulated_world"),
    ("knowledge", "free_spot", "robot_calls", "robot_api"),
    # What runs on the API: the tasks and the agent; then what records an agent.
    ("tasks", "agent"),
    ("recording",),
    # Composition: episodes, episode folders, replays, calibration runs, demos.
    ("app",),
    # Programs: evaluation grids, benchmarks, the command line.
    ("eval", "bench", "station_commands"),
    ("commands",),
    ("cli", "__init__"),
    # The console command: limits NumPy's BLAS threads, picks the memory allocator, then
    # runs the command line.
    ("launch", "__main__"),
)
LAYER_OF = {name: index for index, names in enumerate(LAYERS) for name in names}


def unit_of(path: Path) -> str:
    """The package (or top-level module) of physcap_drake a source file belongs to."""
    parts = path.relative_to(ROOT).with_suffix("").parts
    return parts[0]


def module_of(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


@functools.cache
def parsed(path: Path) -> ast.Module:
    """The file's syntax tree, parsed once for all the tests of this module (read only)."""
    return ast.parse(path.read_text(), str(path))


@functools.cache
def imported_modules(path: Path) -> tuple[tuple[int, str, tuple[str, ...]], ...]:
    """(line, absolute module, names imported from it) of every import in the file."""
    module = module_of(path)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = []
    for node in ast.walk(parsed(path)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name, ()) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            found.append((node.lineno, target, tuple(a.name for a in node.names)))
    return tuple(found)


def package_edges() -> dict[str, dict[str, list[str]]]:
    """unit -> imported unit -> where ("file:line")."""
    edges: dict[str, dict[str, list[str]]] = defaultdict(lambda: defaultdict(list))
    for path in sorted(ROOT.rglob("*.py")):
        source = unit_of(path)
        for line, target, _ in imported_modules(path):
            parts = target.split(".")
            if parts[0] != "physcap_drake" or len(parts) < 2:
                continue
            if parts[1] != source:
                edges[source][parts[1]].append(f"{path.relative_to(ROOT)}:{line}")
    return edges


#: The modules outside piper_emulator that import it, and when. The host imports the emulator
#: only where it starts one: the CLI's `emulate-piper`, or a station with `emulate: true`
#: (deferred: those imports run only then, so a real arm's run loads no emulator).
EMULATOR_STARTERS = {
    "commands/emulate.py": "`physcap emulate-piper` starts an emulator",
    "station/simulated_motion.py": "the emulated arm's world (a simulated scene), built only "
                                   "for an emulator",
}
EMULATOR_STARTERS_DEFERRED = {
    "station/can_session.py": "`emulate: true`: starts the emulator's process",
    "station/can_operator.py": "`emulate: true`: `physcap arm` on an emulated arm",
    "station/can_scene.py": "`emulate: true`: the emulated scene reads the emulated world",
    "station/can_config.py": "`emulate: true`: checks `emulated_start`",
}
#: What the emulator uses of the host's package `can`: the protocol, the joint profile both
#: follow, and the plumbing between processes; never the link (`link`, `link_process`,
#: `feedback`, ...), so the emulator can be reused without the host.
EMULATOR_USES_OF_CAN = {"codec", "joint_profile", "socket_bus", "child_process",
                        "shared_block", "realtime"}
EMULATOR = "physcap_drake.piper_emulator"


def typing_only_lines(path: Path) -> set[int]:
    """The lines of `path`'s `if TYPE_CHECKING:` blocks (imports there never run)."""
    tree = parsed(path)
    return {node.lineno for block in tree.body if isinstance(block, ast.If)
            and ast.unparse(block.test) == "TYPE_CHECKING"
            for node in ast.walk(block) if hasattr(node, "lineno")}


def emulator_imports(path: Path) -> tuple[list[int], list[int]]:
    """(all lines, module-level lines) at which `path` imports the emulator package;
    `if TYPE_CHECKING:` imports are left out."""
    tree = parsed(path)
    top_level = {node.lineno for node in tree.body}
    typing_only = typing_only_lines(path)
    lines, module_level = [], []
    for line, target, names in imported_modules(path):
        modules = [target] + [f"{target}.{name}" for name in names]
        if line not in typing_only and any(
                m == EMULATOR or m.startswith(EMULATOR + ".") for m in modules):
            lines.append(line)
            if line in top_level:
                module_level.append(line)
    return lines, module_level


def test_only_the_emulator_starters_import_the_emulator():
    found, eager = {}, []
    for path in sorted(ROOT.rglob("*.py")):
        name = str(path.relative_to(ROOT))
        if unit_of(path) == "piper_emulator":
            continue
        lines, module_level = emulator_imports(path)
        if lines:
            found[name] = lines
        if module_level and name in EMULATOR_STARTERS_DEFERRED:
            eager.append(f"{name}:{module_level} (import it where emulate is true)")
    assert sorted(found) == sorted(EMULATOR_STARTERS | EMULATOR_STARTERS_DEFERRED), found
    assert eager == []


def test_the_emulator_uses_the_protocol_not_the_hosts_link():
    used = {}
    for path in sorted((ROOT / "piper_emulator").rglob("*.py")):
        for line, target, names in imported_modules(path):
            parts = target.split(".")
            if parts[:2] != ["physcap_drake", "can"]:
                continue
            for module in ([parts[2]] if len(parts) > 2 else list(names)):
                used.setdefault(module, []).append(f"{path.relative_to(ROOT)}:{line}")
    assert set(used) - EMULATOR_USES_OF_CAN == set(), used


def test_a_real_arm_loads_no_emulator():
    """Importing what drives a real arm (its station, session, operator commands, recorder)
    loads none of the emulator."""
    program = ("import sys\n"
               "import physcap_drake.station.can_station, physcap_drake.station.can_interface\n"
               "import physcap_drake.commands.arm, physcap_drake.recording.can_topics\n"
               f"print([m for m in sys.modules if m.startswith({EMULATOR!r})])")
    result = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True,
                            check=True, env={**os.environ, "PYTHONPATH": str(ROOT.parent)})
    assert result.stdout.strip() == "[]", result.stdout


def test_every_package_has_a_layer():
    units = {unit_of(path) for path in ROOT.rglob("*.py")}
    assert units - set(LAYER_OF) == set(), "give these a layer in tests/test_layers.py"


def test_imports_go_down_the_layers():
    upward = [f"{source} (layer {LAYER_OF[source]}) imports {target} (layer "
              f"{LAYER_OF[target]}) at {', '.join(where)}"
              for source, targets in package_edges().items()
              for target, where in targets.items()
              if LAYER_OF.get(target, -1) > LAYER_OF.get(source, -1)]
    assert upward == []


def test_no_package_import_cycles():
    edges = {source: set(targets) for source, targets in package_edges().items()}
    cycles = [component for component in strongly_connected(edges) if len(component) > 1]
    assert cycles == []


def test_no_private_names_imported_across_modules():
    """A private module or name (leading underscore) is used only inside the package that
    holds it (e.g. agent/llm/_common.py by agent/llm's modules)."""
    leaks = []
    for path in sorted(ROOT.rglob("*.py")):
        importer = module_of(path) if path.name == "__init__.py" else (
            module_of(path).rpartition(".")[0])
        for line, target, names in imported_modules(path):
            if not target.startswith("physcap_drake"):
                continue
            for name in names or ("",):
                parts = f"{target}.{name}".strip(".").split(".")
                for i, part in enumerate(parts):
                    holder = ".".join(parts[:i])
                    if part.startswith("_") and not part.startswith("__") and not (
                            importer == holder or importer.startswith(holder + ".")):
                        leaks.append(f"{path.relative_to(ROOT)}:{line} imports "
                                     f"{'.'.join(parts)}")
    assert leaks == []


def strongly_connected(edges: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components of a directed graph."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for other in edges.get(node, ()):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            component = []
            while True:
                other = stack.pop()
                on_stack.discard(other)
                component.append(other)
                if other == node:
                    break
            components.append(sorted(component))

    for node in sorted(edges):
        if node not in index:
            visit(node)
    return components


def module_edges() -> dict[str, set[str]]:
    """module -> the physcap_drake modules it imports (every import, also inside functions:
    a deferred import is still a dependency; `if TYPE_CHECKING:` imports are left out, as
    they never run). `from package import name` counts as importing `package.name` when
    that is a module, else the package."""
    paths = {module_of(path): path for path in ROOT.rglob("*.py")}
    edges: dict[str, set[str]] = {}
    for module, path in paths.items():
        typing_only = typing_only_lines(path)
        targets = set()
        for line, target, names in imported_modules(path):
            if line in typing_only or not target.startswith("physcap_drake"):
                continue
            submodules = {f"{target}.{name}" for name in names} & set(paths)
            targets |= submodules or {target}
            if len(submodules) < len(names):  # names defined in the package itself
                targets.add(target)
        edges[module] = targets & set(paths) - {module}
    return edges


def test_no_import_cycles_between_modules():
    """No two modules import each other, directly or round a cycle (see `module_edges`)."""
    cycles = [component for component in strongly_connected(module_edges())
              if len(component) > 1]
    assert cycles == []


def test_the_cycle_finder_finds_a_cycle():
    """The check above can fail: a graph with a cycle is caught."""
    assert ["a", "b"] in strongly_connected({"a": {"b"}, "b": {"a", "c"}, "c": set()})


def test_the_emulated_world_is_named_where_the_emulator_can_import_it():
    """The CAN session names the emulated world's builder instead of importing it (it sits
    above the station); the name must lead to it."""
    from physcap_drake.can.child_process import named_function
    from physcap_drake.emulated_world import build_world
    from physcap_drake.station.can_session import EMULATED_WORLD_BUILDER

    assert named_function(EMULATED_WORLD_BUILDER) is build_world
