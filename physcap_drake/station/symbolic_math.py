"""Small helpers for firmware laws written as Drake symbolic expressions (run in C++ by
SymbolicVectorSystem): the same arithmetic as numpy's clip and sign, term for term."""

from __future__ import annotations

from pydrake.symbolic import Expression, if_then_else
from pydrake.symbolic import max as sym_max
from pydrake.symbolic import min as sym_min


def clamp(value, lower, upper) -> Expression:
    """`value` limited to [lower, upper] (numpy.clip: the upper bound wins if they cross)."""
    return sym_min(sym_max(value, lower), upper)


def sign(value) -> Expression:
    """1, -1 or 0 with the sign of `value` (numpy.sign)."""
    return if_then_else(value > 0, 1.0, if_then_else(value < 0, -1.0, 0.0))
