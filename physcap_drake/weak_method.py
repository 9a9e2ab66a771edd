"""Callbacks that Drake keeps in C++ without keeping their Python system alive.

Design notes: docs/design/physcap_drake.md.
"""

from __future__ import annotations

import inspect
import weakref
from collections.abc import Callable


def weak_method(method: Callable) -> Callable:
    """A function calling the bound `method` with its arguments through a weak reference to
    the method's object. Once that object is gone, a call raises RuntimeError naming the
    method. Raises TypeError for anything but a bound method: a lambda or a closure over
    the system would bring back the cycle this avoids (see the design notes)."""
    if not inspect.ismethod(method):
        raise TypeError(f"weak_method needs a bound method (e.g. self._calc), got {method!r}")
    reference = weakref.WeakMethod(method)
    name = method.__qualname__

    def call(*args):
        bound = reference()
        if bound is None:
            raise RuntimeError(f"{name} was called after its system was destroyed")
        return bound(*args)

    call.__qualname__ = call.__name__ = f"weak_method({name})"
    return call
