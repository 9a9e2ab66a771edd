"""The messages between the sandboxed child and its parent.

A frame is a 4-byte big-endian length followed by that many bytes of ASCII JSON (non-ASCII
text is escaped, so lone surrogates survive too). Never pickle: the parent must not run
anything the child chose, and `json.loads` only builds plain values. NaN and infinities are
written as JSON's common extension tokens (NaN, Infinity, -Infinity), which `json` reads back.

A frame may hold at most `MAX_MESSAGE_BYTES`; a bigger one from the child is a protocol
violation and the parent kills it. The parent's "start" frame alone may hold up to
`MAX_START_BYTES`, enough for any code the static check accepts (100 000 characters, each
at most 12 bytes escaped).

Messages are dicts with a "t" (type) key:

    parent -> child   start   {"code", "api": [names], "limits": {...}, "raw": bool,
                               "require": [isolation layers without which nothing runs]}
                      return  {"value"}
                      raise   {"type": class name, "message"}
    child -> parent   ready   {"isolation": [what the lockdown achieved]}
                      out     {"text": printed text since the last "out"}
                      call    {"name", "args": [...], "kwargs": {...}}
                      done    {"error": null or {"type", "message", "line", "memory"},
                               "truncated": whether output was cut at the limit}

Values on the wire are None, bools, numbers, strings, lists and dicts with string keys.
`to_wire` turns numpy arrays and scalars into these on the way out; `from_wire` (used in the
child only) turns lists of numbers back into numpy float arrays.

Standard library and numpy only: the child loads this before it locks itself down.
"""

from __future__ import annotations

import json
import os
from typing import Any

import numpy as np

MAX_MESSAGE_BYTES = 1 << 20
MAX_START_BYTES = 2 << 20
#: Bounds of what the child reports, kept by the child and checked by the parent: the class
#: name and message of an exception, and the text of one "out" message (characters).
MAX_ERROR_TYPE_CHARS = 100
MAX_ERROR_MESSAGE_CHARS = 2000
MAX_OUT_CHARS = 50_000
# Exit codes of the child for its own failures (not the code's): setup before the code ran
# failed, or the parent went away mid-conversation.
EXIT_SETUP_FAILED = 87
EXIT_PARENT_GONE = 88
_HEADER_BYTES = 4
_MAX_DEPTH = 32
_MAX_INT_BITS = 64


class ProtocolError(Exception):
    """A frame that is too big, truncated, not JSON, or not a message of the protocol."""


def pack(message: dict[str, Any], limit: int = MAX_MESSAGE_BYTES) -> bytes:
    """One frame holding `message`. TypeError if it holds a value JSON cannot carry;
    ProtocolError if it is larger than `limit` bytes."""
    body = json.dumps(message, ensure_ascii=True, allow_nan=True,
                      separators=(",", ":")).encode("ascii")
    if len(body) > limit:
        raise ProtocolError(f"message of {len(body)} bytes exceeds the {limit}-byte limit")
    return len(body).to_bytes(_HEADER_BYTES, "big") + body


def unpack_from(buffer: bytearray) -> dict[str, Any] | None:
    """Take one complete frame off the front of `buffer` and decode it; None if the buffer
    does not hold a complete frame yet. Raises ProtocolError on a bad frame (the announced
    length alone is enough to reject an oversized one, before its bytes arrive)."""
    if len(buffer) < _HEADER_BYTES:
        return None
    size = int.from_bytes(buffer[:_HEADER_BYTES], "big")
    if size > MAX_MESSAGE_BYTES:
        raise ProtocolError(f"frame of {size} bytes announced; the limit is "
                            f"{MAX_MESSAGE_BYTES}")
    end = _HEADER_BYTES + size
    if len(buffer) < end:
        return None
    body = bytes(buffer[_HEADER_BYTES:end])
    del buffer[:end]
    return decode_body(body)


def decode_body(body: bytes) -> dict[str, Any]:
    """Decode a frame's JSON body into a message dict; ProtocolError if it is not one."""
    try:
        message = json.loads(body.decode("ascii"))
    except (UnicodeDecodeError, ValueError, RecursionError) as error:
        raise ProtocolError(f"frame is not ASCII JSON: {error}") from None
    if not isinstance(message, dict) or not isinstance(message.get("t"), str):
        raise ProtocolError("frame is not a message (a JSON object with a string 't')")
    return message


def write_message(fd: int, message: dict[str, Any]) -> None:
    """Write one frame to a blocking file descriptor (the child's side)."""
    data = memoryview(pack(message))
    while data:
        written = os.write(fd, data)
        data = data[written:]


def read_message(fd: int, limit: int = MAX_MESSAGE_BYTES) -> dict[str, Any]:
    """Read one frame of at most `limit` bytes from a blocking file descriptor (the child's
    side). EOFError if the other end closed; ProtocolError on a bad frame."""
    header = _read_exactly(fd, _HEADER_BYTES)
    size = int.from_bytes(header, "big")
    if size > limit:
        raise ProtocolError(f"frame of {size} bytes announced; the limit is {limit}")
    return decode_body(_read_exactly(fd, size))


def _read_exactly(fd: int, size: int) -> bytes:
    chunks = bytearray()
    while len(chunks) < size:
        chunk = os.read(fd, size - len(chunks))
        if not chunk:
            raise EOFError("the other end of the pipe closed")
        chunks += chunk
    return bytes(chunks)


def to_wire(value: Any, _depth: int = 0) -> Any:
    """`value` as plain JSON values: numpy arrays become (nested) lists, numpy scalars
    Python numbers, tuples lists. TypeError for anything else (functions, modules, objects,
    complex numbers, dicts with non-string keys, integers beyond 64 bits, nesting deeper
    than 32)."""
    if _depth > _MAX_DEPTH:
        raise TypeError(f"value is nested more than {_MAX_DEPTH} levels deep")
    if value is None or isinstance(value, (bool, str, float)):
        return value
    if isinstance(value, int):
        if value.bit_length() > _MAX_INT_BITS:
            raise TypeError("integer too large to send (more than 64 bits)")
        return int(value)
    if isinstance(value, np.generic):
        return to_wire(value.item(), _depth + 1)
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "biuf":
            raise TypeError(f"numpy arrays of dtype {value.dtype} cannot be sent")
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [to_wire(item, _depth + 1) for item in value]
    if isinstance(value, dict):
        wired = {}
        for key, item in value.items():
            if not isinstance(key, str):
                raise TypeError(f"dict keys must be strings, not {type(key).__name__}")
            wired[key] = to_wire(item, _depth + 1)
        return wired
    raise TypeError(f"values of type {type(value).__name__} cannot be sent")


def from_wire(value: Any) -> Any:
    """A value off the wire, with every list of numbers (bools excluded) turned into a numpy
    float array; lists of equally shaped arrays become one array of one more dimension (a
    list of three 3-vectors is a 3x3 array). Other lists stay lists, dicts stay dicts."""
    if isinstance(value, dict):
        return {key: from_wire(item) for key, item in value.items()}
    if not isinstance(value, list):
        return value
    items = [from_wire(item) for item in value]
    if not items:
        return items
    if all(isinstance(item, (int, float)) and not isinstance(item, bool) for item in items):
        return np.array(items, dtype=float)
    if all(isinstance(item, np.ndarray) for item in items):
        shape = items[0].shape
        if all(item.shape == shape for item in items):
            return np.stack(items).astype(float)
    return items
