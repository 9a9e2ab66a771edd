"""A stand-in for the `time` module of code that reads the clock: the test sets the time."""

from __future__ import annotations


class FakeTime:
    """`monotonic()` is `now` (s); `time()` is the wall clock at that moment (s)."""

    def __init__(self, now: float = 1000.0):
        self.now = now

    def monotonic(self) -> float:
        return self.now

    def time(self) -> float:
        return self.now + 1.7e9
