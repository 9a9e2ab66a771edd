"""Values that Drake may share instead of copying: the immutable state of our systems."""

from __future__ import annotations


class Immutable:
    """Mixin for frozen dataclasses kept in a Drake Context (abstract state) or sent on
    abstract ports.

    Drake copies a system's abstract state twice for every unrestricted update (into the
    update's scratch state, and back into the Context), and pydrake copies a Python value with
    `copy.deepcopy`. For a value that holds trajectories or an agent's history, and an event
    every few milliseconds, those copies cost more than the simulation itself. A value that is
    never changed in place (an event replaces it with a new one, e.g. `dataclasses.replace`)
    can be shared by every copy: its deep copy is itself. Only mix this into frozen
    dataclasses whose fields are themselves never mutated (tuples, numbers, strings, frozen
    dataclasses; numpy arrays and Drake trajectories that nothing writes to).
    """

    __slots__ = ()

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self
