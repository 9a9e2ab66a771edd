"""What sandboxed code may name: modules, builtins, attributes.

One table shared by the static check (`ast_check`, in the parent) and the runtime layer
(`restricted`, in the child), so the two filters never disagree. Both are only filters in
front of the real wall, the child process and its lockdown (see `lockdown`, `seccomp`).

This module must import nothing but the standard library: the child loads it before it has
locked itself down and must not pull in drake or the rest of physcap_drake.
"""

from __future__ import annotations

# Modules generated code may import. numpy's submodules are listed one by one: the others
# (lib, ctypeslib, testing, f2py, distutils, ma, rec, char, ...) reach files, ctypes or
# subprocesses, or are simply not needed to move a robot.
ALLOWED_MODULES: frozenset[str] = frozenset({
    "math",
    "numpy",
    "numpy.fft",
    "numpy.linalg",
    "numpy.polynomial",
    "numpy.random",
})

# Builtin names that are never allowed, in any role (called, assigned, as a parameter or as
# a function name), each with the reason given to the code's author.
_FORBIDDEN_NAME_GROUPS: dict[str, tuple[str, ...]] = {
    "it runs code, reaches objects by name, or touches the interpreter or the system": (
        "__import__", "breakpoint", "compile", "delattr", "eval", "exec", "exit", "getattr",
        "globals", "help", "input", "locals", "memoryview", "open", "quit", "setattr", "vars",
    ),
    "it builds classes or descriptors, a way into the class hierarchy": (
        "classmethod", "object", "property", "staticmethod", "super", "type",
    ),
    "format specifications are not needed; use f-strings instead": ("format",),
}
FORBIDDEN_NAMES: dict[str, str] = {
    name: reason for reason, names in _FORBIDDEN_NAME_GROUPS.items() for name in names
}

PRIVATE_REASON = "names starting with '_' are private or special and may not be used"

# Attribute names that are never allowed, whatever object they are looked up on, each with
# the reason given to the code's author.
_FORBIDDEN_ATTRIBUTE_GROUPS: dict[str, tuple[str, ...]] = {
    "it reads or writes files, maps memory or loads libraries": (
        "DataSource", "dump", "dumps", "fromfile", "fromregex", "genfromtxt", "load",
        "load_library", "loads", "loadtxt", "memmap", "open_memmap", "save", "savetxt", "savez",
        "savez_compressed", "tofile",
    ),
    "it leads to ctypes, compilers, test runners or build machinery": (
        "ctypes", "ctypeslib", "distutils", "f2py", "lib", "show_config", "show_runtime",
        "testing",
    ),
    "format strings can look attributes up by name at run time; use f-strings instead": (
        "format", "format_map",
    ),
    "it exposes the class hierarchy": ("mro",),
    "it is a module other modules keep, a way to the file system and the interpreter": (
        "builtins", "gc", "importlib", "inspect", "io", "marshal", "mmap", "multiprocessing",
        "os", "pathlib", "pickle", "posix", "pty", "resource", "shutil", "signal", "socket",
        "subprocess", "sys", "tempfile", "threading", "types", "warnings",
    ),
    "it runs code or reaches objects by name": (
        "breakpoint", "compile", "delattr", "eval", "exec", "exit", "getattr", "globals",
        "help", "input", "locals", "open", "quit", "setattr", "vars",
    ),
}
FORBIDDEN_ATTRIBUTES: dict[str, str] = {
    name: reason for reason, names in _FORBIDDEN_ATTRIBUTE_GROUPS.items() for name in names
}

# Attribute prefixes of frames, code objects, tracebacks, generators and Cython functions:
# `gen.gi_frame.f_globals` and `np.random.default_rng.func_globals` reach a module's globals
# without a single underscore.
FORBIDDEN_ATTRIBUTE_PREFIXES: tuple[str, ...] = ("ag_", "co_", "cr_", "f_", "func_", "gi_",
                                                 "tb_")

# Exception classes generated code can see (to raise or to catch), besides the robot API's.
EXCEPTION_NAMES: tuple[str, ...] = (
    "ArithmeticError", "AssertionError", "AttributeError", "Exception", "FloatingPointError",
    "IndexError", "KeyError", "LookupError", "MemoryError", "NotImplementedError",
    "OverflowError", "RecursionError", "RuntimeError", "StopIteration", "TypeError",
    "ValueError", "ZeroDivisionError",
)

# The robot API's error classes, rebuilt in the child with the same names and hierarchy as
# physcap_drake.control.errors: SkillRefused and SkillFailed subclass SkillError, which
# subclasses RuntimeError.
SKILL_ERROR_NAMES: tuple[str, ...] = ("SkillError", "SkillRefused", "SkillFailed")

# Plain builtin functions and types generated code may use.
SAFE_BUILTIN_NAMES: tuple[str, ...] = (
    "abs", "all", "any", "bool", "callable", "chr", "dict", "divmod", "enumerate", "filter",
    "float", "frozenset", "int", "isinstance", "issubclass", "iter", "len", "list", "map", "max",
    "min", "next", "ord", "pow", "range", "repr", "reversed", "round", "set", "slice", "sorted",
    "str", "sum", "tuple", "zip",
)


def attribute_problem(name: str) -> str | None:
    """Why the attribute `name` may not be used, or None if it may."""
    if name.startswith("_"):
        return PRIVATE_REASON
    if name in FORBIDDEN_ATTRIBUTES:
        return FORBIDDEN_ATTRIBUTES[name]
    if name.startswith(FORBIDDEN_ATTRIBUTE_PREFIXES):
        return ("attributes of frames, code objects, tracebacks, generators and compiled "
                "functions may not be used")
    return None


def name_problem(name: str) -> str | None:
    """Why the plain name `name` may not be used, or None if it may. A lone `_` (the usual
    throwaway variable) is allowed."""
    if name.startswith("_") and name != "_":
        return PRIVATE_REASON
    if name in FORBIDDEN_NAMES:
        return FORBIDDEN_NAMES[name]
    return None
