"""Every name and attribute the sandbox forbids, from lists written out here (not read from
the policy's own tables): rejected by the static check in every role, missing from the
child's builtins and refused by its module views; and the plain builtins next to them
still allowed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from physcap_drake.agent.sandbox import CodeRejected, check_code
from physcap_drake.agent.sandbox.restricted import make_builtins, wrap_module

#: Builtins that run code, reach objects by name, touch the interpreter or build classes.
FORBIDDEN_NAMES = (
    "__import__", "breakpoint", "compile", "delattr", "eval", "exec", "exit", "getattr",
    "globals", "help", "input", "locals", "memoryview", "open", "quit", "setattr", "vars",
    "classmethod", "object", "property", "staticmethod", "super", "type", "format",
)
#: Attributes that reach files, native code, the interpreter or names at run time.
FORBIDDEN_ATTRIBUTES = (
    "DataSource", "dump", "dumps", "fromfile", "fromregex", "genfromtxt", "load",
    "load_library", "loads", "loadtxt", "memmap", "open_memmap", "save", "savetxt", "savez",
    "savez_compressed", "tofile", "ctypes", "ctypeslib", "distutils", "f2py", "lib",
    "show_config", "show_runtime", "testing", "format", "format_map", "mro", "builtins", "gc",
    "importlib", "inspect", "io", "marshal", "mmap", "multiprocessing", "os", "pathlib",
    "pickle", "posix", "pty", "resource", "shutil", "signal", "socket", "subprocess", "sys",
    "tempfile", "threading", "types", "warnings", "breakpoint", "compile", "delattr", "eval",
    "exec", "exit", "getattr", "globals", "help", "input", "locals", "open", "quit", "setattr",
    "vars", "__class__", "__dict__", "_private", "f_globals", "gi_frame", "co_code",
    "tb_frame", "cr_frame", "ag_frame",
)
#: Plain builtins generated code uses.
ALLOWED_NAMES = ("abs", "len", "max", "min", "range", "round", "sorted", "sum", "zip",
                 "isinstance", "float", "int", "list", "dict", "print", "_")


def rejected(source: str) -> str:
    with pytest.raises(CodeRejected) as error:
        check_code(source)
    return str(error.value)


@pytest.mark.parametrize("name", FORBIDDEN_NAMES)
def test_a_forbidden_name_is_rejected_in_every_role(name):
    for source in (f"{name}(1)", f"x = {name}", f"{name} = 1", f"def f({name}):\n    pass",
                   f"def {name}():\n    pass", f"for {name} in []:\n    pass",
                   f"import numpy as {name}",
                   f"try:\n    pass\nexcept Exception as {name}:\n    pass"):
        assert repr(name) in rejected(source), source


@pytest.mark.parametrize("name", FORBIDDEN_NAMES)
def test_a_forbidden_name_is_not_among_the_childs_builtins(name):
    assert name == "__import__" or name not in make_builtins(print)


@pytest.mark.parametrize("attribute", FORBIDDEN_ATTRIBUTES)
def test_a_forbidden_attribute_is_rejected_and_refused(attribute):
    assert repr(attribute) in rejected(f"import numpy\nx = numpy.{attribute}")
    assert repr(attribute) in rejected(f"x = [1].{attribute}")
    assert repr(attribute) in rejected(f"from numpy import {attribute}")
    if attribute.startswith("__"):
        return  # the view's own (__class__, ...): code cannot name them, the check above
    with pytest.raises(AttributeError, match="not available in the sandbox"):
        getattr(wrap_module(np), attribute)


@pytest.mark.parametrize("name", ALLOWED_NAMES)
def test_the_plain_builtins_are_allowed(name):
    check_code(f"x = {name}")


def test_allowed_modules_and_attributes_pass():
    check_code("import numpy as np\nimport math\nx = np.linalg.norm([3.0, 4.0]) + math.pi\n"
               "y = np.zeros(3).tolist()\nz = '{}'.upper()")
    assert wrap_module(np).linalg.norm([3.0, 4.0]) == 5.0 and wrap_module(math).pi == math.pi


def test_the_import_hook_is_the_restricted_one():
    assert make_builtins(print)["__import__"] is not __import__


@pytest.mark.parametrize("name", ["_x", "__builtins__", "__class__", "__loader__"])
def test_private_names_are_rejected_but_a_lone_underscore_is_not(name):
    assert "may not be used" in rejected(f"y = {name}") and "private" in rejected(f"y = {name}")
    check_code("for _ in range(3):\n    pass")


@pytest.mark.parametrize("attribute", ["f_globals", "gi_frame", "co_code", "tb_next",
                                       "cr_await", "ag_frame", "func_globals"])
def test_frame_and_code_attributes_are_rejected_with_their_reason(attribute):
    assert rejected(f"y = [1].{attribute}") == (
        f"code rejected: line 1: the attribute {attribute!r} is not allowed (attributes of "
        "frames, code objects, tracebacks, generators and compiled functions may not be used)")
