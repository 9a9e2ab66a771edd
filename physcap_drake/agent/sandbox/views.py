"""Every attribute generated code reads passes here: module views and the attribute guard.

- `SandboxedModule` stands in for numpy, its allowed submodules and math (read-only).
- `guarded_attribute(obj, name)` is what `obj.name` compiles to in generated code (see
  `rewrite`): the policy's name check, then the lookup; an error from the lookup is raised
  afresh (`fresh_error`: same public class, same message, no attributes, no traceback of
  the lookup), and the value is `mediated`: a module becomes its view or is refused, a
  raw-module object (operator, functools, sys, ...) is refused. Exceptions the code did not
  define show only `args` (mediated too).

Standard library only, plus `policy`.
"""

from __future__ import annotations

import builtins
import operator
from types import ModuleType
from typing import Any

from . import policy

#: Modules whose objects (functions, classes, instances) generated code may never hold:
#: they read attributes by name, reach the interpreter, files or foreign memory.
RAW_MODULES: frozenset[str] = frozenset({
    "_ctypes", "_functools", "_io", "_operator", "_thread", "copyreg", "ctypes",
    "functools", "gc", "importlib", "inspect", "io", "marshal", "operator", "os", "pickle",
    "posix", "subprocess", "sys", "threading", "types", "weakref",
})
#: Builtin exception classes a fresh error may have (the others become RuntimeError).
_FRESH_CLASSES: dict[str, type[BaseException]] = {
    name: getattr(builtins, name) for name in policy.EXCEPTION_NAMES}
#: The only attribute of an exception the code did not define itself.
EXCEPTION_ATTRIBUTES = frozenset({"args"})
SANDBOX_MODULE_NAME = "__sandbox__"


def _refused(what: str, reason: str) -> AttributeError:
    return AttributeError(f"{what} is not available in the sandbox ({reason})")


def safe_message(error: BaseException) -> str:
    """str(error), or a placeholder if its __str__ fails."""
    try:
        return str(error)
    except Exception:  # noqa: BLE001 - a broken __str__ must not break the run
        return f"({type(error).__name__} without a printable message)"


def fresh_error(error: BaseException, extra_classes: dict[str, type[BaseException]]
                | None = None) -> BaseException:
    """A new exception standing for `error`: the nearest class in its hierarchy the code may
    see (else RuntimeError naming it), the same message, nothing else."""
    table = {**_FRESH_CLASSES, **(extra_classes or {})}
    message = safe_message(error)
    for cls in type(error).__mro__:
        if table.get(cls.__name__) is cls:
            return cls(message)
    return RuntimeError(f"{type(error).__name__}: {message}")


def _own_class(obj: Any) -> bool:
    """Whether `obj` is an instance (or class) that generated code defined."""
    cls = obj if isinstance(obj, type) else type(obj)
    return getattr(cls, "__module__", None) == SANDBOX_MODULE_NAME


def home_module(value: Any) -> str:
    """The module an object comes from: its own __module__ for functions and classes, its
    class's for instances."""
    home = getattr(value, "__module__", None) if callable(value) else None
    if not isinstance(home, str):
        home = getattr(type(value), "__module__", None)
    return home if isinstance(home, str) else ""


def mediated(value: Any, where: str) -> Any:
    """What the code receives for `value`, found at `where` (for messages)."""
    if isinstance(value, ModuleType):
        if value.__name__ in policy.ALLOWED_MODULES:
            return wrap_module(value)
        raise _refused(f"module {value.__name__}", f"found at {where}")
    if isinstance(value, dict) and ("__builtins__" in value or "__loader__" in value):
        raise _refused(where, "a module's namespace")
    try:
        home = home_module(value).partition(".")[0]
    except Exception:  # noqa: BLE001 - an object that hides where it comes from is refused
        raise _refused(where, "where it comes from cannot be told") from None
    if home in RAW_MODULES:
        raise _refused(where, f"an object of module {home}")
    if home == "builtins" and callable(value) \
            and getattr(value, "__name__", "") in policy.FORBIDDEN_NAMES:
        raise _refused(where, f"the builtin {value.__name__}")
    return value


def guarded_attribute(obj: Any, name: str) -> Any:
    """`obj.name` as generated code sees it (see the module docstring)."""
    where = f"{_describe(obj)}.{name}"
    reason = policy.attribute_problem(name)
    if reason:
        raise _refused(where, reason)
    if isinstance(obj, BaseException) and not _own_class(obj) \
            and name not in EXCEPTION_ATTRIBUTES:
        raise _refused(where, "an error shows only its args")
    failure = None
    try:
        value = getattr(obj, name)
    except BaseException as error:  # noqa: BLE001 - raised afresh below, outside this block
        failure = fresh_error(error)
    if failure is not None:
        raise failure
    if name == "args" and isinstance(obj, BaseException) and isinstance(value, tuple):
        return tuple(mediated(item, f"{where}[{index}]") for index, item in enumerate(value))
    return mediated(value, where)


_IN_PLACE = {
    "Add": operator.iadd, "Sub": operator.isub, "Mult": operator.imul,
    "MatMult": operator.imatmul, "Div": operator.itruediv, "FloorDiv": operator.ifloordiv,
    "Mod": operator.imod, "Pow": operator.ipow, "LShift": operator.ilshift,
    "RShift": operator.irshift, "BitOr": operator.ior, "BitXor": operator.ixor,
    "BitAnd": operator.iand,
}


def augmented_attribute(obj: Any, name: str, op: str, value: Any) -> None:
    """`obj.name <op>= value` with the read guarded like any other."""
    result = _IN_PLACE[op](guarded_attribute(obj, name), value)
    setattr(obj, name, result)


def _describe(obj: Any) -> str:
    if isinstance(obj, SandboxedModule):
        return object.__getattribute__(obj, "_module").__name__
    if isinstance(obj, type):
        return obj.__name__
    return f"<{type(obj).__name__}>"


class SandboxedModule:
    """A read-only view of an allowed module (numpy, its allowed submodules, math)."""

    __slots__ = ("_module",)

    def __init__(self, module: ModuleType):
        object.__setattr__(self, "_module", module)

    def __getattr__(self, name: str) -> Any:
        module = object.__getattribute__(self, "_module")
        where = f"{module.__name__}.{name}"
        reason = policy.attribute_problem(name)
        if reason:
            raise _refused(where, reason)
        failure = None
        try:
            value = getattr(module, name)
        except (ImportError, OSError):
            # numpy imports some submodules on first access; after the lockdown that fails
            failure = _refused(where, "it would have to be loaded from disk")
        except BaseException as error:  # noqa: BLE001 - raised afresh below
            failure = fresh_error(error)
        if failure is not None:
            raise failure
        return mediated(value, where)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("modules are read-only in the sandbox")

    def __delattr__(self, name: str) -> None:
        raise AttributeError("modules are read-only in the sandbox")

    def __dir__(self) -> list[str]:
        module = object.__getattribute__(self, "_module")
        return [name for name in dir(module) if policy.attribute_problem(name) is None]

    def __repr__(self) -> str:
        return f"<module {object.__getattribute__(self, '_module').__name__!r} (sandboxed)>"


_WRAPPED: dict[str, SandboxedModule] = {}


def wrap_module(module: ModuleType) -> SandboxedModule:
    """The (cached) sandboxed view of `module`."""
    view = _WRAPPED.get(module.__name__)
    if view is None:
        view = _WRAPPED[module.__name__] = SandboxedModule(module)
    return view
