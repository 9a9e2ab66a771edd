"""Callbacks that Drake keeps in C++ without keeping their Python system alive.

pydrake (Drake 1.58) keeps some of a Python LeafSystem's callbacks in C++:
- the calculation of `DeclareAbstractOutputPort`;
- the `calc` of a cache entry's `ValueProducer`.

When such a callback is a bound method of the system, or a closure over it, the system
refers to itself through C++. Python's garbage collector cannot see that cycle, so the system
lives until the process ends. So does everything reachable from it: its diagram, the plant,
the render engines, the planner, the agent and the episode it runs. That was about 0.1 GB per
find_blue_cube episode (Drake issues #22515 and #23930). The same pydrake frees systems
whose vector output ports and events are bound methods (tests/test_weak_method.py checks
both kinds).

`weak_method(self._calc)` gives Drake a plain function instead. It reaches the method through
a weak reference, so the system lives exactly as long as its diagram (or a caller) holds it.
Every abstract output port and cache entry of the package is declared this way. For the
same reason a system keeps a cache entry's `cache_index()`, never the CacheEntry that
`DeclareCacheEntry` returns: pydrake ties that object to its system in a way the collector
cannot see either. tests/test_weak_method.py reads the source to check both rules.
"""

from __future__ import annotations

import inspect
import weakref
from collections.abc import Callable


def weak_method(method: Callable) -> Callable:
    """A function calling the bound `method` with its arguments through a weak reference to
    the method's object. Once that object is gone, a call raises RuntimeError naming the
    method. Raises TypeError for anything but a bound method: a lambda or a closure over
    the system would bring back the cycle this avoids (see the module docstring)."""
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
