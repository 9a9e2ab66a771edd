"""Docstrings stay short and say what a reader looks for: no module docstring is over 25
lines (rationale, history and measurements go to docs/design/), and every LeafSystem's
class docstring names each port the class declares (a port block as in pydrake)."""

from __future__ import annotations

import ast
import importlib
import re
from pathlib import Path

import pytest

import physcap_drake

PACKAGE = Path(physcap_drake.__file__).parent
MAX_MODULE_DOCSTRING_LINES = 25
#: Where a docstring's port block starts: "Input ports:", "Output port:", "No input ports."
PORT_BLOCK = re.compile(r"^\s*(Input|Output|No input) ports?\b", re.M)
DECLARE_PORT = {"DeclareVectorInputPort", "DeclareAbstractInputPort", "DeclareInputPort",
                "DeclareVectorOutputPort", "DeclareAbstractOutputPort",
                "DeclareStateOutputPort"}


def modules() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def leaf_systems(trees: dict[Path, ast.Module]) -> list[tuple[Path, ast.ClassDef]]:
    """Every class of the package deriving from LeafSystem, directly or through classes of
    the package (by name)."""
    classes = {node.name: [ast.unparse(base).rsplit(".", 1)[-1] for base in node.bases]
               for tree in trees.values() for node in ast.walk(tree)
               if isinstance(node, ast.ClassDef)}

    def derives(name: str, seen: frozenset[str] = frozenset()) -> bool:
        return any(base == "LeafSystem" or (base in classes and base not in seen
                                            and derives(base, seen | {name}))
                   for base in classes.get(name, ()))

    return [(path, node) for path, tree in trees.items() for node in ast.walk(tree)
            if isinstance(node, ast.ClassDef) and derives(node.name)]


def _binding_loop(name: str, call: ast.AST, parents: dict[ast.AST, ast.AST]):
    """The for loop or comprehension around `call` whose target binds `name`, with where
    `name` sits in the target (a path of tuple indices)."""
    node = call
    while node in parents:
        node = parents[node]
        generators = (node.generators if isinstance(node, (ast.ListComp, ast.SetComp,
                                                           ast.DictComp, ast.GeneratorExp))
                      else [node] if isinstance(node, ast.For) else [])
        for loop in generators:
            path = _position(name, loop.target)
            if path is not None:
                return loop.iter, path
    return None


def _position(name: str, target: ast.AST) -> tuple[int, ...] | None:
    if isinstance(target, ast.Name):
        return () if target.id == name else None
    if isinstance(target, ast.Tuple):
        for index, element in enumerate(target.elts):
            inner = _position(name, element)
            if inner is not None:
                return (index, *inner)
    return None


def undocumented_ports(doc: str, names: set[str]) -> list[str]:
    """The names that the docstring's port block (from its first "Input ports" or
    "Output ports" line to its end or an "Args:" line) does not mention; all of them when
    it has no port block."""
    start = PORT_BLOCK.search(doc)
    block = doc[start.start():] if start else ""
    block = block[:end.start()] if (end := re.search(r"^\s*Args:", block, re.M)) else block
    return sorted(name for name in names if name not in block)


def port_names(path: Path, tree: ast.Module, cls: ast.ClassDef) -> tuple[set[str], int]:
    """(the names of the ports the class declares that can be known without building it,
    how many declarations name their port at run time only). A name is a string literal, a
    constant of the module's namespace, or a loop variable over a constant sequence."""
    namespace = vars(importlib.import_module(module_name(path)))
    parents = {child: parent for parent in ast.walk(cls) for child in ast.iter_child_nodes(parent)}
    names, unknown = set(), 0
    for call in ast.walk(cls):
        if not (isinstance(call, ast.Call) and isinstance(call.func, ast.Attribute)
                and call.func.attr in DECLARE_PORT and call.args):
            continue
        argument = call.args[0]
        values = _constant(argument, path, namespace)
        if values is not None:
            values = [values]
        elif isinstance(argument, ast.Name) and (loop := _binding_loop(argument.id, call,
                                                                       parents)):
            items = _constant(loop[0], path, namespace)
            values = [_item(item, loop[1]) for item in items] if items is not None else None
        if values and all(isinstance(v, str) for v in values):
            names.update(values)
        else:
            unknown += 1
    return names, unknown


#: What evaluating a port name's expression raises when it names something only the
#: running constructor has (its arguments, self, a loop over them).
_NOT_CONSTANT = (NameError, AttributeError, TypeError, KeyError, IndexError)


def _constant(expression: ast.expr, path: Path, namespace: dict):
    """The expression's value in the module's namespace, or None if it is not a constant
    there."""
    try:
        return eval(compile(ast.Expression(expression), str(path), "eval"), dict(namespace))
    except _NOT_CONSTANT:
        return None


def _item(item, at: tuple[int, ...]):
    for index in at:
        item = item[index]
    return item


@pytest.fixture(scope="module")
def trees() -> dict[Path, ast.Module]:
    return {path: ast.parse(path.read_text(), str(path)) for path in modules()}


def long_module_docstrings(trees: dict[Path, ast.Module]) -> dict[str, int]:
    """The modules whose docstring has more than 25 lines, with its line count."""
    return {path.name if not path.is_relative_to(PACKAGE) else
            str(path.relative_to(PACKAGE)): len(doc.strip().splitlines())
            for path, tree in trees.items()
            if (doc := ast.get_docstring(tree)) is not None
            and len(doc.strip().splitlines()) > MAX_MODULE_DOCSTRING_LINES}


def test_no_module_docstring_is_over_25_lines(trees):
    assert long_module_docstrings(trees) == {}, \
        "module docstrings over 25 lines (move the rest to docs/design/)"


def test_a_docstring_of_26_lines_is_long_and_one_of_25_is_not():
    def module(lines: int) -> ast.Module:
        return ast.parse('"""' + "\n".join(f"line {i}" for i in range(lines)) + '"""\n')
    found = long_module_docstrings({Path("a.py"): module(25), Path("b.py"): module(26),
                                    Path("c.py"): ast.parse("x = 1\n")})
    assert found == {"b.py": 26}


def test_every_leaf_systems_docstring_names_its_ports(trees):
    systems = leaf_systems(trees)
    assert len(systems) >= 20, "the LeafSystem finder lost the package's systems"
    missing = {}
    for path, cls in systems:
        names, _ = port_names(path, trees[path], cls)
        absent = undocumented_ports(ast.get_docstring(cls) or "", names)
        if absent:
            missing[f"{path.relative_to(PACKAGE)}:{cls.name}"] = absent
    assert missing == {}, "LeafSystem docstrings that do not name these ports"


def test_the_port_finder_reads_literals_constants_and_loops(trees):
    """Names written as literals, module constants and loop variables over constant tuples
    are all found; the skill executor's and the CAN interface's are known port names."""
    systems = {cls.name: (path, cls) for path, cls in leaf_systems(trees)}
    names, unknown = port_names(*_with_tree(trees, systems["SkillExecutor"]))
    assert names == {"request", "status", "piper.position_measured", "piper.velocity_estimated",
                     "gripper.position_measured", "piper.position", "gripper.position",
                     "gripper.force_limit"} and unknown == 0
    names, _ = port_names(*_with_tree(trees, systems["PiperCanInterface"]))
    assert {"piper.torque_measured", "gripper.effort_measured"} <= names
    names, _ = port_names(*_with_tree(trees, systems["JointFriction"]))
    assert names == {"arm_velocity", "generalized_force"}


def test_a_port_missing_from_a_docstring_is_found():
    source = ('from pydrake.systems.framework import LeafSystem\n'
              'class Probe(LeafSystem):\n'
              '    """Input port: request."""\n'
              '    def __init__(self):\n'
              '        self.DeclareAbstractInputPort("request", None)\n'
              '        for name in ("a.out", "b.out"):\n'
              '            self.DeclareVectorOutputPort(name, 1, None)\n')
    tree = ast.parse(source)
    path = PACKAGE / "clock.py"  # any module: its namespace resolves nothing here
    [(_, cls)] = leaf_systems({path: tree})
    names, unknown = port_names(path, tree, cls)
    assert names == {"request", "a.out", "b.out"} and unknown == 0
    assert undocumented_ports(ast.get_docstring(cls), names) == ["a.out", "b.out"]
    assert undocumented_ports("Reads `request` and writes a.out, b.out.", names) == sorted(names)
    assert undocumented_ports("Does it.\n\nInput port: request.\nOutput ports: a.out, b.out.",
                              names) == []
    assert undocumented_ports("Input port: request.\n\nArgs:\n    a.out, b.out: files.",
                              names) == ["a.out", "b.out"]


def _with_tree(trees, found):
    path, cls = found
    return path, trees[path], cls
