"""SharedBlock: a fixed set of numbers and texts in memory shared with a child process,
written by one side and read by the other without either ever waiting (a sequence lock).

Design notes: docs/design/can.md.
"""

from __future__ import annotations

import dataclasses as dc
import mmap
import os
import time

import numpy as np

#: How often a reader retries a copy that raced with a write before pausing (or giving up).
READ_ATTEMPTS = 20
#: A patient reader's pause between rounds of attempts, s.
RETRY_PAUSE = 50e-6


@dc.dataclass(frozen=True)
class Layout:
    """Names of the numbers (each a slice of the float64 payload) and of the texts (each
    `text_size` bytes of UTF-8) in a block."""

    numbers: dict[str, int]  # name -> how many float64 values
    texts: tuple[str, ...] = ()
    text_size: int = 400

    @property
    def size(self) -> int:
        return sum(self.numbers.values())

    @property
    def bytes(self) -> int:
        return (1 + self.size) * 8 + self.text_size * len(self.texts)

    def slices(self) -> dict[str, slice]:
        out, start = {}, 0
        for name, count in self.numbers.items():
            out[name] = slice(start, start + count)
            start += count
        return out


@dc.dataclass(frozen=True)
class Reading:
    """One consistent copy of a block: numbers (arrays) and texts, by name."""

    numbers: dict[str, np.ndarray]
    texts: dict[str, str]

    def __getitem__(self, name: str):
        return self.texts[name] if name in self.texts else self.numbers[name]


class SharedBlock:
    """A block laid out as `layout`: a new one (`fd=None`; hand `fd` to the child) or the
    child's view of the parent's (`fd` as received)."""

    def __init__(self, layout: Layout, fd: int | None = None):
        self.layout = layout
        self._slices = layout.slices()
        if fd is None:
            fd = os.memfd_create("physcap-shared-block")  # handed over by its number
            os.ftruncate(fd, layout.bytes)
            fresh = True
        else:
            fresh = False
        self.fd = fd
        self._map = mmap.mmap(fd, layout.bytes)
        numbers = (1 + layout.size) * 8
        self._values = np.ndarray((1 + layout.size,), dtype=np.float64, buffer=self._map)
        self._text = np.ndarray((len(layout.texts), layout.text_size), dtype=np.uint8,
                                buffer=self._map, offset=numbers)
        if fresh:
            self._values[:] = np.nan
            self._values[0] = 0.0

    def write(self, numbers: dict | None = None, texts: dict | None = None) -> None:
        """Writes the given numbers and texts (others keep their values)."""
        values = self._values
        values[0] += 1.0  # odd: a write is under way
        for key, value in (numbers or {}).items():
            values[1:][self._slices[key]] = value
        for key, text in (texts or {}).items():
            raw = text.encode("utf-8")[:self.layout.text_size]
            row = self._text[self.layout.texts.index(key)]
            row[:] = 0
            row[:len(raw)] = np.frombuffer(raw, dtype=np.uint8)
        values[0] += 1.0  # even again: done

    def read(self, patience: float = 0.0) -> Reading | None:
        """A consistent copy, or None when nothing was written yet or every attempt raced
        with a write (a writer can be held up in the middle of one). With `patience` (s),
        keeps trying that long, yielding the processor between attempts."""
        deadline = time.monotonic() + patience
        while True:
            for _ in range(READ_ATTEMPTS):
                sequence = self._values[0]
                if sequence == 0.0:
                    return None
                if int(sequence) % 2:
                    continue
                payload = self._values[1:].copy()
                texts = self._text.copy()
                if self._values[0] == sequence:
                    return Reading({k: payload[s] for k, s in self._slices.items()},
                                   {k: bytes(texts[i]).rstrip(b"\0").decode("utf-8", "replace")
                                    for i, k in enumerate(self.layout.texts)})
            if time.monotonic() >= deadline:
                return None
            time.sleep(RETRY_PAUSE)

    def close(self) -> None:
        """Unmaps the memory and closes the descriptor. Safe to call twice."""
        if self._map is None:
            return
        self._values = self._text = None
        self._map.close()
        self._map = None
        os.close(self.fd)
