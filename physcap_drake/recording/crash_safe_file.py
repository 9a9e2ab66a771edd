"""CrashSafeFile: the file an MCAP writer writes into, readable by any MCAP reader at any time.

Design notes: docs/design/recording.md.
"""

from __future__ import annotations

import os
from pathlib import Path

from mcap.data_stream import RecordBuilder
from mcap.records import DataEnd, Footer
from mcap.writer import MCAP0_MAGIC


def _provisional_end() -> bytes:
    """DataEnd (data-section CRC 0: not computed), a Footer whose summary start 0 says "no
    summary section", and the closing magic."""
    builder = RecordBuilder()
    DataEnd(data_section_crc=0).write(builder)
    Footer(summary_start=0, summary_offset_start=0, summary_crc=0).write(builder)
    builder.write(MCAP0_MAGIC)
    return bytes(builder.end())


PROVISIONAL_END = _provisional_end()


class CrashSafeFile:
    """A write-only, forward-only file object for `foxglove.open_mcap` (see the design
    notes). Raises FileExistsError if `path` exists and not `overwrite`."""

    def __init__(self, path: str | Path, *, overwrite: bool = False):
        self.path = Path(path)
        flags = os.O_WRONLY | os.O_CREAT | (os.O_TRUNC if overwrite else os.O_EXCL)
        try:
            self._fd = os.open(self.path, flags, 0o644)
        except FileExistsError:
            raise FileExistsError(f"{self.path} exists already") from None
        self._on_disk = 0  # bytes of the writer's stream written to the file
        self._pending = bytearray()  # bytes written since, not yet on disk
        self._finishing = False
        self.closed = False

    # --- what the writer calls -----------------------------------------------------------

    def write(self, data) -> int:
        if self.closed:
            raise ValueError(f"{self.path} is closed")
        self._pending += data
        return len(data)

    def tell(self) -> int:
        return self._on_disk + len(self._pending)

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        """Only reports the position: the writer never moves backwards (disable_seeking)."""
        target = offset + (self.tell() if whence == os.SEEK_CUR else 0)
        if whence == os.SEEK_END or target != self.tell():
            raise OSError(f"CrashSafeFile writes forward only; asked to seek to {offset} "
                          f"(whence {whence}) at {self.tell()}")
        return target

    def flush(self) -> None:
        """Writes what the writer handed over since the last flush, then the provisional end
        (not once the writer is finishing: its own end follows)."""
        if self.closed:
            return
        data = bytes(self._pending)
        ending = b"" if self._finishing else PROVISIONAL_END
        os.pwrite(self._fd, data + ending, self._on_disk)
        self._on_disk += len(data)
        self._pending.clear()

    # --- what the sink calls -------------------------------------------------------------

    def finishing(self) -> None:
        """The writer is about to write its summary and Footer: no provisional end after it."""
        self._finishing = True

    def close(self) -> None:
        """Writes the rest and cuts the file where the writer's stream ends."""
        if self.closed:
            return
        self._finishing = True
        self.flush()
        os.ftruncate(self._fd, self._on_disk)
        os.close(self._fd)
        self.closed = True
