"""The world generated code runs in, inside the child: its builtins, modules and output.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import builtins
import importlib
import sys
from collections.abc import Callable
from typing import Any

from . import policy, rewrite, views
from .views import SandboxedModule, wrap_module


class SkillError(RuntimeError):
    """A robot skill did not do what was asked (raised by robot API calls)."""


class SkillRefused(SkillError):
    """The robot refused the request before moving (unsafe, unreachable or invalid)."""


class SkillFailed(SkillError):
    """The skill started but did not complete; the arm holds where it stopped."""


SKILL_ERRORS: dict[str, type[Exception]] = {
    "SkillError": SkillError,
    "SkillRefused": SkillRefused,
    "SkillFailed": SkillFailed,
}


class OutputBuffer:
    """Text written by the code, kept up to `max_chars` characters; then one marker line,
    and everything after it is dropped. `take_new()` hands out what arrived since the last
    call. It has the file methods print, numpy and warnings use, so it can stand in for
    sys.stdout and sys.stderr."""

    encoding = "utf-8"
    errors = "replace"

    def __init__(self, max_chars: int):
        self._max_chars = max_chars
        self._kept = 0
        self._pending: list[str] = []
        self._pending_chars = 0
        self.truncated = False

    def write(self, text: str) -> int:
        if not isinstance(text, str):
            raise TypeError(f"write() argument must be str, not {type(text).__name__}")
        if self.truncated:
            return len(text)
        room = self._max_chars - self._kept
        piece = text if len(text) <= room else text[:room]
        if piece:
            self._pending.append(piece)
            self._pending_chars += len(piece)
            self._kept += len(piece)
        if len(text) > room:
            self.truncated = True
            marker = f"\n[output truncated: more than {self._max_chars} characters]\n"
            self._pending.append(marker)
            self._pending_chars += len(marker)
        return len(text)

    @property
    def pending_chars(self) -> int:
        return self._pending_chars

    def take_new(self) -> str:
        text = "".join(self._pending)
        self._pending.clear()
        self._pending_chars = 0
        return text

    def flush(self) -> None:
        """Nothing to do: the child sends pending text itself."""

    def isatty(self) -> bool:
        return False

    def writable(self) -> bool:
        return True


def make_print(output: OutputBuffer, after_write: Callable[[], None]) -> Callable[..., None]:
    """A print that writes to `output` (never to a file) and then calls `after_write`."""

    def print(*values: Any, sep: str | None = " ", end: str | None = "\n",
              file: Any = None, flush: bool = False) -> None:
        if file is not None:
            raise TypeError("print(file=...) is not available in the sandbox")
        sep = " " if sep is None else sep
        end = "\n" if end is None else end
        if not isinstance(sep, str) or not isinstance(end, str):
            raise TypeError("sep and end must be strings")
        output.write(sep.join(str(value) for value in values) + end)
        after_write()

    return print


def restricted_import(name: str, globals: Any = None, locals: Any = None,
                      fromlist: Any = (), level: int = 0) -> SandboxedModule:
    """`__import__` for generated code: only the modules of policy.ALLOWED_MODULES, and
    only as sandboxed views."""
    if level != 0 or name not in policy.ALLOWED_MODULES:
        allowed = ", ".join(sorted(policy.ALLOWED_MODULES))
        raise ImportError(f"import of {name!r} is not allowed in the sandbox "
                          f"(allowed: {allowed})")
    module = sys.modules.get(name) or importlib.import_module(name)
    if fromlist:
        return wrap_module(module)
    return wrap_module(sys.modules[name.partition(".")[0]])


def make_builtins(print_function: Callable[..., None]) -> dict[str, Any]:
    """The `__builtins__` of generated code."""
    table: dict[str, Any] = {name: getattr(builtins, name) for name in policy.SAFE_BUILTIN_NAMES}
    table.update({name: getattr(builtins, name) for name in policy.EXCEPTION_NAMES})
    table.update(SKILL_ERRORS)
    table["print"] = print_function
    table["__import__"] = restricted_import
    # needed by the `class` statement; not reachable by name (it starts with '_')
    table["__build_class__"] = builtins.__build_class__
    table[rewrite.ATTRIBUTE_HELPER] = views.guarded_attribute
    table[rewrite.AUGMENTED_HELPER] = views.augmented_attribute
    return table


def error_from_parent(type_name: str, message: str) -> Exception:
    """The exception to raise in the code for an error the robot API raised in the parent:
    the class of the same name if the code can see one, else RuntimeError naming it."""
    cls = SKILL_ERRORS.get(type_name)
    if cls is None and type_name in policy.EXCEPTION_NAMES:
        cls = getattr(builtins, type_name)
    if cls is None:
        return RuntimeError(f"{type_name}: {message}")
    return cls(message)
