"""Field encodings shared by the PiPER's frames: scaled integers, enumerations, MIT floats.

Every frame is classic CAN with 8 data bytes; multi-byte fields are big-endian. A scaled
field carries round(value / scale) counts; values outside the field's range are clamped
to it, never wrapped. An enumerated field (a mode, a motor number) accepts only its
documented codes: anything else raises ValueError naming the field.
"""

from __future__ import annotations

import math

INT8 = (-(2**7), 2**7 - 1)
UINT8 = (0, 2**8 - 1)
INT16 = (-(2**15), 2**15 - 1)
UINT16 = (0, 2**16 - 1)
INT32 = (-(2**31), 2**31 - 1)

#: rad per count of the 0.001° joint and end-pose angles.
MILLIDEGREE = math.pi / 180_000.0
#: rad per count of the 0.1° joint-limit angles (0x473, 0x474).
DECIDEGREE = math.pi / 1800.0
#: m per count of the 0.001 mm positions (end pose, gripper stroke).
MICROMETRE = 1e-6
#: The "leave unchanged" value of the optional 16-bit settings (0x474, 0x475).
NO_CHANGE = 0x7FFF


class FrameError(ValueError):
    """A frame that cannot be decoded (wrong length, failed checksum)."""


def check(data: bytes, what: str) -> bytes:
    """`data` as bytes, if it has the 8 bytes every PiPER frame has."""
    if len(data) != 8:
        raise FrameError(f"{what}: expected 8 data bytes, got {len(data)}")
    return bytes(data)


def counts(value: float, scale: float, low: int, high: int) -> int:
    """SI value -> integer counts of `scale`, clamped to [low, high] (NaN -> 0)."""
    value = float(value)  # a numpy scalar's arithmetic is several times slower
    if math.isnan(value):
        return 0
    return int(min(max(round(value / scale), low), high))


def optional_counts(value: float | None, scale: float, low: int, high: int) -> int:
    """Like `counts`, with None sent as NO_CHANGE (a count the field never takes otherwise:
    `high` must stay below it)."""
    return NO_CHANGE if value is None else counts(value, scale, low, min(high, NO_CHANGE - 1))


def optional_value(raw: int, scale: float) -> float | None:
    """Counts -> SI value; NO_CHANGE -> None."""
    return None if raw == NO_CHANGE else raw * scale


def clamp_byte(value: int, low: int = 0, high: int = 255) -> int:
    """An integer field of one byte, clamped to [low, high]."""
    return int(min(max(int(value), low), high))


def code(value: int, allowed, field: str) -> int:
    """An enumerated one-byte field: `value` if it is one of `allowed`, else ValueError."""
    value = int(value)
    if value not in allowed:
        shown = ", ".join(f"0x{a:02X}" for a in allowed)
        raise ValueError(f"{field} must be one of {shown}; got 0x{value:02X}")
    return value


def float_to_uint(value: float, low: float, high: float, bits: int) -> int:
    """The MIT frames' fixed-point encoding: (x − low)·(2ⁿ − 1)/(high − low), truncated as
    the vendor SDK does, after clamping x to [low, high] (the SDK does not clamp, so an
    out-of-range value wraps there and changes sign)."""
    value = min(max(float(value), low), high) if not math.isnan(value) else 0.0
    return int((value - low) * ((1 << bits) - 1) / (high - low))


def uint_to_float(raw: int, low: float, high: float, bits: int) -> float:
    """The inverse of `float_to_uint` (to within one count)."""
    return raw * (high - low) / ((1 << bits) - 1) + low
